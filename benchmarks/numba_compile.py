"""numba compile time: of a mission with an empty cache (a fresh install) and with the cache it left, and of
each preset's warm-up with an empty cache.

Run: ``python benchmarks/numba_compile.py [SCENARIO] [--presets P,...]`` (default scenario
``examples/alight_circle.yaml``, the one the README's first command flies; prints JSON). Each measurement
is a fresh Python process with ``NUMBA_CACHE_DIR`` pointing to a new, empty directory:

- ``cold``: the process flies the scenario once (``run_mission``, as ``alight fly --no-warmup`` does);
  ``warm``: again with the cache the first one left. The README's first command compiles the same
  signatures: its warm-up compiles them all, and the mission after it none.
- ``presets``: for each preset (default all five), a process with its own empty cache flies the preset's
  warm-up (``alight.warmup.warm_up``, what ``alight fly`` and a campaign's sandbox run before any
  mission's clock starts): the cold compile of that preset. ``cold`` compiles in the flight alone
  (``compile_first=False``); ``cold_parallel`` as ``alight fly`` does, the listed kernels first in
  parallel helper processes (``alight.parallel_compile``; ``ahead`` says what they did: their CPU time
  is in ``cpu_s``, not in ``compile_s``, which is this process's own).

``compile_s`` is the CPU time numba spent compiling (``alight.warmup.compile_meter``: outermost compiles
only, cache loads excluded; CPU rather than wall time, so other work on the machine does not inflate it),
``signatures`` the signatures compiled, ``top`` the kernels that dominate, ``cpu_s``/``wall_s`` the
whole child process (imports included). ``mission_wall_s`` is the mission's ``wall_time_s``: it includes
the compile here because this benchmark flies without a warm-up, as a measurement of the compile.
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
from alight.warmup import compile_meter, warm_up
what, arg = sys.argv[1], sys.argv[2]
out = {}
with compile_meter() as m:
    if what == "scenario":
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
print(json.dumps(out))
"""


def _child(what: str, arg: str, cache: str) -> dict[str, Any]:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
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


def main() -> None:
    args = sys.argv[1:]
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
