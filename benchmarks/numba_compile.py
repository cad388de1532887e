"""numba compile time: of a mission with an empty cache (a fresh install) and with the cache it left, and of
each preset's warm-up with an empty cache.

Run: ``python benchmarks/numba_compile.py [SCENARIO] [--presets P,...]`` (default scenario
``examples/alight_circle.yaml``, the one the README's first command flies; prints JSON), or
``python benchmarks/numba_compile.py --functions PRESET [--top N] [--opt 3,0]`` for where one preset's
compile goes (below). Each measurement is a fresh Python process with ``NUMBA_CACHE_DIR`` pointing to a
new, empty directory:

- ``cold``: the process flies the scenario once (``run_mission``, as ``alight fly --no-warmup`` does);
  ``warm``: again with the cache the first one left. The README's first command compiles the same
  signatures: its warm-up compiles them all, and the mission after it none.
- ``presets``: for each preset (default all five), a process with its own empty cache flies the preset's
  warm-up (``alight.compile.warmup.warm_up``, what ``alight fly`` and a campaign's sandbox run before any
  mission's clock starts): the cold compile of that preset. ``cold`` compiles in the flight alone
  (``compile_first=False``); ``cold_parallel`` as ``alight fly`` does, the listed kernels first in
  parallel helper processes (``alight.compile.parallel``; ``ahead`` says what they did: their CPU time
  is in ``cpu_s``, not in ``compile_s``, which is this process's own).

``compile_s`` is the CPU time numba spent compiling (``alight.compile.meter.compile_meter``: outermost
compiles only, cache loads excluded; CPU rather than wall time, so other work on the machine does not
inflate it), ``signatures`` the signatures compiled, ``top`` the kernels that dominate, ``cpu_s``/``wall_s``
the whole child process (imports included). ``mission_wall_s`` is the mission's ``wall_time_s``: it includes
the compile here because this benchmark flies without a warm-up, as a measurement of the compile.

``--functions PRESET``: the process compiles the preset's listed kernels (the list
``alight.compile.parallel`` keeps) and reports every numba function compiled, callees and numba's own
overloads (``np.empty``'s) included, by the CPU time of its own compiles with its callees' nested
compiles taken out (``exclusive_s``; the meter's ``by_function``), with ``inclusive_s`` and
``signatures``; ``functions`` says how many there were. With ``--opt``, the same compile runs again at
each LLVM optimisation level given (numba's ``NUMBA_OPT``, default 3), each in its own process:
``by_opt`` says how much of the compile is LLVM's optimiser rather than numba's typing and lowering.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

_CHILD = """
import json, sys, time
from alight.compile.warmup import compile_meter, warm_up
what, arg = sys.argv[1], sys.argv[2]
out = {}
with compile_meter() as m:
    if what == "functions":
        from alight.compile.parallel import _dispatcher, parse_signature, read_manifest
        kernels = [k for k in read_manifest() if arg in k.presets]
        for k in kernels:
            _dispatcher(k).compile(parse_signature(k.signature))
        out = {"kernels": len(kernels)}
    elif what == "scenario":
        from alight.scenario import load_scenario
        from alight.evaluation.runner import run_mission
        r = run_mission(load_scenario(arg), record=True).result
        out = {"mission_wall_s": round(r["wall_time_s"], 2), "outcome": r["outcome"],
               "touchdown_error_m": r["touchdown_error_m"]}
    else:
        rep = warm_up([arg], compile_first=what == "warmup_parallel")
        out = {"warmup_wall_s": round(rep.wall_s, 2)}
        if rep.ahead is not None:
            a = rep.ahead
            out["ahead"] = {"helpers": a.helpers, "signatures": a.kernels, "wall_s": round(a.wall_s, 2),
                            "cpu_s": round(a.cpu_s, 2), "failed": a.failed, "note": a.note}
top = sorted(m.by_kernel.items(), key=lambda kv: -kv[1])[:10]
out.update({"compile_s": round(m.compile_s, 2), "signatures": m.n_signatures,
            "top": {k: round(v, 2) for k, v in top}})
if what == "functions":
    out["functions"] = len(m.by_function)
    out["by_function"] = [
        {"function": name, "exclusive_s": round(f.exclusive_s, 2), "inclusive_s": round(f.inclusive_s, 2),
         "signatures": f.signatures}
        for name, f in sorted(m.by_function.items(), key=lambda kv: -kv[1].exclusive_s)
    ]
print(json.dumps(out))
"""


def _child(what: str, arg: str, cache: str, opt: str | None = None) -> dict[str, Any]:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    if opt is not None:
        env["NUMBA_OPT"] = opt
    t0, c0 = time.perf_counter(), os.times()
    run = subprocess.run(
        [sys.executable, "-c", _CHILD, what, arg], env=env, capture_output=True, text=True, check=True
    )
    c1 = os.times()
    out: dict[str, Any] = json.loads(run.stdout.strip().splitlines()[-1])
    out["cpu_s"] = round(c1.children_user - c0.children_user + c1.children_system - c0.children_system, 2)
    out["wall_s"] = round(time.perf_counter() - t0, 2)
    out["load_avg_1min"] = round(os.getloadavg()[0], 2)
    return out


def functions(preset: str, top: int, opts: list[str]) -> dict[str, Any]:
    """Where ``preset``'s compile goes, function by function (``--functions``)."""
    from alight.compile.parallel import read_manifest

    if not any(preset in k.presets for k in read_manifest()):
        raise SystemExit(f"numba_compile: no listed kernel for preset {preset!r}")
    with tempfile.TemporaryDirectory(prefix="alight-numba-cache-") as cache:
        out = _child("functions", preset, cache)
    out = {"preset": preset, **out, "by_function": out["by_function"][:top]}
    if opts:
        out["by_opt"] = {}
        for level in opts:
            with tempfile.TemporaryDirectory(prefix="alight-numba-cache-") as cache:
                r = _child("functions", preset, cache, opt=level)
            out["by_opt"][level] = {"compile_s": r["compile_s"], "signatures": r["signatures"]}
    return out


def main() -> None:
    args = sys.argv[1:]
    if args[:1] == ["--functions"]:
        flags = dict(zip(args[2::2], args[3::2], strict=False))
        if len(args) < 2 or len(args) % 2 or set(flags) - {"--top", "--opt"}:
            raise SystemExit(
                "usage: python benchmarks/numba_compile.py --functions PRESET [--top N] [--opt 3,0]"
            )
        opts = [o for o in flags.get("--opt", "").split(",") if o]
        print(json.dumps(functions(args[1], int(flags.get("--top", "25")), opts), indent=1))
        return
    presets = ["alight", "groundtruth", "falanga2017", "kim_kaist", "zamanakos_sdu"]
    if "--presets" in args:
        i = args.index("--presets")
        presets = [p for p in args[i + 1].split(",") if p]
        del args[i : i + 2]
    scenario = args[0] if args else str(Path(__file__).parents[1] / "examples" / "alight_circle.yaml")
    out: dict[str, Any] = {"scenario": scenario}
    with tempfile.TemporaryDirectory(prefix="alight-numba-cache-") as cache:
        for label in ("cold", "warm"):
            out[label] = _child("scenario", scenario, cache)
    out["presets"] = {}
    for preset in presets:
        out["presets"][preset] = {}
        for label, what in (("cold", "warmup"), ("cold_parallel", "warmup_parallel")):
            with tempfile.TemporaryDirectory(prefix="alight-numba-cache-") as cache:
                out["presets"][preset][label] = _child(what, preset, cache)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
