"""Strong wind: hold error and landings of the ground-truth flight core (docs/wind.md's tables).

Run: ``python benchmarks/wind_table.py OUT.jsonl AIRFRAME TURBULENCE SPEEDS SEEDS VARIANTS`` e.g.
``python benchmarks/wind_table.py runs/wind.jsonl matrice100 moderate 8,12 1,2,3,4,5 base,int2,l1``
(then ``python benchmarks/wind_table.py --summary runs/wind.jsonl`` prints the markdown table), and
``python benchmarks/wind_table.py --trim`` prints the tilt each airframe needs to hold a steady wind: the
controller (integral 2.0, the airframe's tilt limit) and the fused rate loop + dynamics hold the origin for
25 s in ``SteadyWind`` on the airframe's drag area.

Every mission: preset ``groundtruth``, a 2 m/s circle, 90 s, wind along +x of W at the given mean speed,
``steady`` when TURBULENCE is ``none``, else ``dryden`` with that intensity. Variants: ``base`` (the
preset as it is), ``int2`` (``controller.integral_gain: 2.0``), ``l1`` (``controller.l1_adaptive:
true``), ``int2+l1`` (both), and ``tilt60``, ``tilt60+int2``, ``tilt60+l1`` (the controller's tilt
limit raised to 60 deg by patching ``HighLevelGains.from_bandwidth``, the limit has no scenario key).
One JSON line per mission: outcome, whether it left take-off, the hold error (horizontal distance
between the vehicle and its reference, RMS and max over t > 3 s: take-off, exploration and tracking
alike) and the touchdown error.
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
    "int2+l1": (None, {"integral_gain": 2.0, "l1_adaptive": True}),
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


def trim(
    airframe: str, speed: float, tilt_deg: float | None = None, seconds: float = 25.0
) -> dict[str, float]:
    """Hold the origin in a steady wind of ``speed`` along +x with the tilt limit ``tilt_deg`` (None: the
    airframe's); the final tilt, drift and thrust."""
    from alight.airframes import load_airframe
    from alight.control import HighLevelController, HighLevelGains, low_level, pack_low_level_params
    from alight.sim.quadrotor import IX_W, initial_state, pack_params, step
    from alight.sim.wind import SteadyWind
    from alight.types import EgoState, Reference, quat_to_rotmat

    af = load_airframe(airframe)
    limit = None if tilt_deg is None else math.radians(tilt_deg)
    gains = HighLevelGains.from_bandwidth(3.0, ki=(2.0, 2.0, 2.0), integral_limit=6.0, max_tilt=limit)
    ctl = HighLevelController(af, gains)
    ll, sp = pack_low_level_params(af), pack_params(af)
    wind = SteadyWind([speed, 0.0, 0.0], area_m2=af.body_drag_area_m2)
    x = initial_state(np.zeros(3), 0.0, af.weight_N / 4.0)
    z = np.zeros(3)
    for i in range(int(seconds * 100)):
        t = i * 0.01
        ego = EgoState(t=t, p_WB=x[0:3], v_WB=x[3:6], q_WB=x[6:10], w_WB_B=x[10:13])
        cmd = ctl.command(ego, Reference(t=t, p=z, v=z, a=z, j=z, yaw=0.0))
        f_W, v_air = wind.force_W(t, x[0:3], x[3:6]), wind.air_velocity_W(t)
        for _ in range(10):
            u = low_level(cmd.thrust_N, np.array(cmd.w_WB_B_cmd), x[IX_W : IX_W + 3], ll)
            x = step(x, u, f_W, v_air, sp, 0.001)
    tilt = math.degrees(math.acos(quat_to_rotmat(x[6:10])[2, 2]))
    return {
        "tilt_deg": tilt,
        "drift_mps": float(x[3]),
        "thrust_N": float(np.sum(x[13:17])),
        "offset_m": float(x[0]),
    }


def main(argv: list[str]) -> None:
    if argv[0] == "--trim":
        cases = [("f450", v, None) for v in (6, 7, 8, 10, 12, 14)] + [("f450", v, 60.0) for v in (12, 14)]
        cases += [("matrice100", v, None) for v in (12, 14, 18)]
        for airframe, speed, tilt in cases:
            row = trim(airframe, float(speed), tilt)
            print(json.dumps({"airframe": airframe, "wind_mps": speed, "tilt_limit_deg": tilt, **row}))
        return
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
