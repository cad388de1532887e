"""numba compile time of a mission: with an empty cache (a fresh install) and with the cache it left.

Run: ``python benchmarks/numba_compile.py [SCENARIO]`` (default ``examples/circle.yaml``, the README's
first command; prints JSON). Each measurement is a fresh Python process flying the scenario once
(``run_mission``, as ``alight fly`` does) with ``NUMBA_CACHE_DIR`` pointing to a new, empty directory
(``cold``), then again with the same directory (``warm``). ``compile_s`` is the CPU time numba spent
compiling (``alight.warmup.compile_meter``: outermost compiles only, cache loads excluded; CPU rather than
wall time, so other work on the machine does not inflate it), ``signatures`` the signatures compiled,
``top`` the kernels that dominate, ``mission_wall_s`` the mission's ``wall_time_s`` (it includes the
compile here: ``alight fly`` has no warm-up; a campaign's sandboxes do).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

_CHILD = """
import json, sys, time
from alight.warmup import compile_meter
from alight.scenario import load_scenario
from alight.evaluation.runner import run_mission
with compile_meter() as m:
    r = run_mission(load_scenario(sys.argv[1]), record=True).result
top = sorted(m.by_kernel.items(), key=lambda kv: -kv[1])[:10]
print(json.dumps({"compile_s": round(m.compile_s, 2), "signatures": m.n_signatures,
                  "mission_wall_s": round(r["wall_time_s"], 2), "outcome": r["outcome"],
                  "top": {k: round(v, 2) for k, v in top}}))
"""


def main() -> None:
    scenario = (
        sys.argv[1] if len(sys.argv) > 1 else str(Path(__file__).parents[1] / "examples" / "circle.yaml")
    )
    out = {"scenario": scenario}
    with tempfile.TemporaryDirectory(prefix="alight-numba-cache-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        for label in ("cold", "warm"):
            run = subprocess.run(
                [sys.executable, "-c", _CHILD, scenario], env=env, capture_output=True, text=True, check=True
            )
            out[label] = json.loads(run.stdout.strip().splitlines()[-1])
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
