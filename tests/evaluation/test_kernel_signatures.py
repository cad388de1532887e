"""A kernel that calls another compiles it once: not a second time for a literal int (issue 18, item 3:
every signature costs compile time on a fresh install, ~0.1-0.4 s of CPU each for these)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[2]

# numba types a caller's `n = 0` as Literal[int](0) until the loop that increments it unifies it to
# int64, and compiles the callee for both unless the caller starts from np.int64(0).
_CHILD = """
import json
import numpy as np
from alight.numerics import runs
from alight.perception.falanga_close import _dark_runs
from alight.perception.falanga_tag import _threshold_runs
from alight.sim import sensors

img = np.random.default_rng(0).integers(0, 256, (48, 64)).astype(np.uint8)
_threshold_runs(img, 2, 0.1, 8.0, True)
_dark_runs(img, 8.0, 0.5)
q = np.array([0.0, 0.0, 0.0, 1.0])
sensors._true_range(np.array([0.0, 0.0, 2.0]), q, np.zeros(3), np.zeros(3), 0.0, 1.0)
kernels = {"link_run": runs.link_run, "run_roots": runs.run_roots, "find_root": runs.find_root,
           "_body_axis": sensors._body_axis}
print(json.dumps({name: [str(s) for s in k.signatures] for name, k in kernels.items()}))
"""


def test_callees_compile_once_not_again_for_a_literal_int(tmp_path: Path) -> None:
    # A fresh process with an empty cache: a cached caller loads without compiling its callees, and other
    # tests call these kernels directly.
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    run = subprocess.run(
        [sys.executable, "-c", _CHILD], capture_output=True, text=True, check=True, cwd=ROOT, env=env
    )
    signatures = json.loads(run.stdout.strip().splitlines()[-1])
    for name, sigs in signatures.items():
        assert len(sigs) == 1, f"{name} compiled for {len(sigs)} signatures: {sigs}"
