"""Strong wind: hold error and landings of the ground-truth flight core (docs/wind.md's tables).

Run: ``python benchmarks/wind_table.py OUT.jsonl AIRFRAME TURBULENCE SPEEDS SEEDS VARIANTS`` e.g.
``python benchmarks/wind_table.py runs/wind.jsonl matrice100 moderate 8,12 1,2,3,4,5 base,int2,l1``
(then ``python benchmarks/wind_table.py --summary runs/wind.jsonl`` prints the markdown table).

Every mission: preset ``groundtruth``, a 2 m/s circle, 90 s, wind along +x of W at the given mean speed,
``steady`` when TURBULENCE is ``none``, else ``dryden`` with that intensity. Variants: ``base`` (the
preset as it is), ``int2`` (``controller.integral_gain: 2.0``), ``l1`` (``controller.l1_adaptive:
true``), and ``tilt60``, ``tilt60+int2``, ``tilt60+l1`` (the controller's tilt limit raised to 60 deg
by patching ``HighLevelGains.from_bandwidth``, the limit has no scenario key). One JSON line per
mission: outcome, whether it left take-off, the hold error (horizontal distance between the vehicle
and its reference, RMS and max over t > 3 s: take-off, exploration and tracking alike) and the
touchdown error.
"""

from __future__ import annotations

import collections
import json
import math
import sys

import numpy as np

from alight.control import high_level
from alight.evaluation.runner import run_mission
from alight.scenario import scenario_from_dict

VARIANTS: dict[str, tuple[float | None, dict[str, object]]] = {
    "base": (None, {}),
    "int2": (None, {"integral_gain": 2.0}),
    "l1": (None, {"l1_adaptive": True}),
    "tilt60": (60.0, {}),
    "tilt60+int2": (60.0, {"integral_gain": 2.0}),
    "tilt60+l1": (60.0, {"l1_adaptive": True}),
}

_TILT: dict[str, float | None] = {"deg": None}
_from_bandwidth = high_level.HighLevelGains.from_bandwidth.__func__  # type: ignore[attr-defined]


def _patched(cls, omega_n, zeta=1.0, **kw):  # type: ignore[no-untyped-def]
    if _TILT["deg"] is not None:
        kw.setdefault("max_tilt", math.radians(_TILT["deg"]))
    return _from_bandwidth(cls, omega_n, zeta, **kw)


high_level.HighLevelGains.from_bandwidth = classmethod(_patched)  # type: ignore[method-assign,assignment]


def fly(variant: str, speed: float, seed: int, airframe: str, turbulence: str) -> dict[str, object]:
    tilt, controller = VARIANTS[variant]
    _TILT["deg"] = tilt
    wind: dict[str, object] = {"model": "steady", "velocity_mps": [speed, 0.0, 0.0]}
    if turbulence != "none":
        wind = {"model": "dryden", "velocity_mps": [speed, 0.0, 0.0], "turbulence": turbulence}
    scenario = {
        "preset": "groundtruth",
        "seed": seed,
        "duration_s": 90.0,
        "airframe": airframe,
        "platform": {"path": "circle", "speed_mps": 2.0},
        "wind": wind,
        "controller": controller,
    }
    run = run_mission(scenario_from_dict(scenario))
    log = run.log
    if log is None:
        raise RuntimeError("run_mission returned no log")
    err = np.linalg.norm((log["p_WB"] - log["p_ref"])[:, :2], axis=1)
    keep = (log["t"] > 3.0) & np.isfinite(err)
    modes = {m for _, m, _ in run.mode_history}
    return {
        "turb": turbulence,
        "variant": variant,
        "v": speed,
        "seed": seed,
        "airframe": airframe,
        "outcome": run.result["outcome"],
        "contact_reason": run.result["contact_reason"],
        "left_takeoff": bool(modes & {"explore", "track"}),
        "hold_rms_m": float(np.sqrt(np.mean(err[keep] ** 2))),
        "hold_max_m": float(np.max(err[keep])),
        "td_err": run.result["touchdown_error_m"],
    }


def summary(path: str) -> None:
    rows = [json.loads(line) for line in open(path, encoding="utf-8")]
    groups: dict[tuple[str, str, float, str], list[dict[str, object]]] = collections.defaultdict(list)
    for r in rows:
        groups[(r["turb"], r["airframe"], r["v"], r["variant"])].append(r)
    head = [
        "turbulence",
        "airframe",
        "W (m/s)",
        "controller",
        "left take-off",
        "landed",
        "hold rms (m)",
        "hold max (m)",
    ]
    print("| " + " | ".join(head) + " |")
    print("|---|---|---|---|---|---|---|---|")
    for key in sorted(groups):
        rs = groups[key]
        n = len(rs)
        left = sum(bool(r["left_takeoff"]) for r in rs)
        landed = sum(r["outcome"] == "landed" for r in rs)
        rms = np.median([float(r["hold_rms_m"]) for r in rs])  # type: ignore[arg-type]
        mx = np.median([float(r["hold_max_m"]) for r in rs])  # type: ignore[arg-type]
        cells = [
            key[0],
            key[1],
            f"{key[2]:g}",
            key[3],
            f"{left}/{n}",
            f"{landed}/{n}",
            f"{rms:.2f}",
            f"{mx:.2f}",
        ]
        print("| " + " | ".join(cells) + " |")


def main(argv: list[str]) -> None:
    if argv[0] == "--summary":
        summary(argv[1])
        return
    out, airframe, turbulence, speeds, seeds, variants = argv
    for seed in (int(s) for s in seeds.split(",")):
        for speed in (float(v) for v in speeds.split(",")):
            for variant in variants.split(","):
                rec = fly(variant, speed, seed, airframe, turbulence)
                with open(out, "a", encoding="utf-8") as f:
                    f.write(json.dumps(rec) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
