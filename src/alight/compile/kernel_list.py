"""The kernel list, ``kernels.json``: written by flying each preset's warm-up on an empty numba cache and
recording the kernel signatures it calls from Python (:func:`alight.compile.meter.python_calls`).

``python -m alight.compile.kernel_list --write [PRESET ...]`` rewrites it (every preset by default);
``tests/test_parallel_compile.py`` checks that it is what the warm-up flights call. The top of
:mod:`alight.compile`: it flies the warm-up (:mod:`~alight.compile.warmup`) and writes the list that
:mod:`~alight.compile.parallel` reads.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from alight.compile.meter import python_calls
from alight.compile.parallel import MANIFEST, Kernel
from alight.compile.warmup import warm_up


def _record_preset(preset: str) -> list[tuple[str, str, str, float]]:
    """(In a process with an empty cache) fly ``preset``'s warm-up and return its outermost kernels."""
    with python_calls() as calls:
        warm_up([preset], compile_first=False)
    return calls


def write_manifest(presets: Sequence[str], path: Path = MANIFEST) -> list[Kernel]:
    """Fly each preset's warm-up in a fresh process on an empty numba cache and write the list."""
    found: dict[tuple[str, str, str], Kernel] = {}
    for preset in presets:
        with tempfile.TemporaryDirectory(prefix="alight-manifest-") as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            out = subprocess.run(
                [sys.executable, "-m", "alight.compile.kernel_list", "--record", preset],
                env=env, capture_output=True, text=True, check=True,
            )  # fmt: skip
        for module, qualname, sig, cpu_s in json.loads(out.stdout.strip().splitlines()[-1]):
            key = (module, qualname, sig)
            old = found.get(key)
            presets_of = (*old.presets, preset) if old else (preset,)
            found[key] = Kernel(module, qualname, sig, presets_of, max(cpu_s, old.compile_s if old else 0.0))
    kernels = sorted(found.values(), key=lambda k: (k.module, k.qualname, k.signature))
    data = {
        "about": "Outermost numba kernels of each preset's warm-up flight; written by python -m "
        "alight.compile.kernel_list --write, checked by tests/test_parallel_compile.py.",
        "kernels": [
            {**k.__dict__, "presets": list(k.presets), "compile_s": round(k.compile_s, 2)} for k in kernels
        ],
    }
    path.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return kernels


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args[:1] == ["--record"] and len(args) == 2:
        print(json.dumps(_record_preset(args[1])))
        return 0
    if args[:1] == ["--write"]:
        from alight.mission.presets import PRESETS

        kernels = write_manifest(args[1:] or sorted(PRESETS))
        print(f"{MANIFEST}: {len(kernels)} kernel signatures")
        return 0
    print("usage: python -m alight.compile.kernel_list --write [PRESET ...]", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
