"""Where numba's compile time goes, function by function: the kernels a preset's warm-up calls (the list
``alight.parallel_compile`` keeps), compiled in one fresh process on an empty cache.

Run: ``python benchmarks/numba_compile_functions.py [--preset alight] [--top 25] [--opt 3,0]`` (prints
JSON). For each numba function compiled (the listed kernels and every callee they pull in, numba's own
overloads such as ``np.empty`` included): ``exclusive_s``, the CPU time of its own compiles with the
nested compiles of its callees taken out, ``inclusive_s`` and ``signatures``. ``total_s`` is the whole
compile's CPU time, ``functions`` and ``signatures`` how many there were.

With ``--opt``, the same compile runs once per LLVM optimisation level (numba's ``NUMBA_OPT``, default 3)
in its own process, and ``by_opt`` gives each total: how much of the compile is LLVM's optimiser rather
than numba's typing and lowering.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from typing import Any


def _profile(preset: str, top: int) -> dict[str, Any]:
    """In this process (its cache empty): compile ``preset``'s listed kernels and account per function."""
    from numba.core import event

    from alight.parallel_compile import _dispatcher, parse_signature, read_manifest

    stack: list[list[float]] = []
    exclusive: Counter[str] = Counter()
    inclusive: Counter[str] = Counter()
    signatures: Counter[str] = Counter()

    class _Listener(event.Listener):
        def on_start(self, ev: Any) -> None:
            stack.append([time.process_time(), 0.0])

        def on_end(self, ev: Any) -> None:
            t0, nested = stack.pop()
            dt = time.process_time() - t0
            fn = ev.data["dispatcher"].py_func
            name = f"{fn.__module__}.{fn.__qualname__}"
            exclusive[name] += dt - nested
            inclusive[name] += dt
            signatures[name] += 1
            if stack:
                stack[-1][1] += dt

    kernels = [k for k in read_manifest() if preset in k.presets]
    if not kernels:
        raise SystemExit(f"numba_compile_functions: no listed kernel for preset {preset!r}")
    listener = _Listener()
    event.register("numba:compile", listener)  # type: ignore[no-untyped-call]
    c0 = time.process_time()
    for k in kernels:
        _dispatcher(k).compile(parse_signature(k.signature))
    total = time.process_time() - c0
    event.unregister("numba:compile", listener)  # type: ignore[no-untyped-call]
    return {
        "preset": preset,
        "kernels": len(kernels),
        "total_s": round(total, 2),
        "functions": len(exclusive),
        "signatures": sum(signatures.values()),
        "top": [
            {
                "function": name,
                "exclusive_s": round(v, 2),
                "inclusive_s": round(inclusive[name], 2),
                "signatures": signatures[name],
            }
            for name, v in exclusive.most_common(top)
        ],
    }


def _child(preset: str, top: int, opt: str | None) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="alight-numba-cache-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        if opt is not None:
            env["NUMBA_OPT"] = opt
        run = subprocess.run(
            [sys.executable, __file__, "--child", preset, str(top)],
            env=env, capture_output=True, text=True, check=True,
        )  # fmt: skip
    result: dict[str, Any] = json.loads(run.stdout.strip().splitlines()[-1])
    return result


def main(argv: list[str]) -> None:
    if argv[:1] == ["--child"]:
        print(json.dumps(_profile(argv[1], int(argv[2]))))
        return
    opts = dict(zip(argv[::2], argv[1::2], strict=False))
    unknown = set(opts) - {"--preset", "--top", "--opt"}
    if unknown or len(argv) % 2:
        raise SystemExit(
            "usage: python benchmarks/numba_compile_functions.py [--preset P] [--top N] [--opt 3,0]"
        )
    preset, top = opts.get("--preset", "alight"), int(opts.get("--top", "25"))
    out = _child(preset, top, None)
    if "--opt" in opts:
        out["by_opt"] = {}
        for level in opts["--opt"].split(","):
            r = _child(preset, 0, level)
            out["by_opt"][level] = {"total_s": r["total_s"], "signatures": r["signatures"]}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
