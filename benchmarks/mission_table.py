"""The closed-loop acceptance table of the ``groundtruth`` preset (issue 2): paper 000's conditions,
N seeds each, with per-condition success, touchdown-error quantiles and times.

    python benchmarks/mission_table.py [--seeds 20] [--workers 2] [--preset groundtruth]

Not a unit test (it takes a few minutes); the numbers go into the issue notes. CI flies a few seeded
missions per condition instead (tests/integration/test_missions.py).
"""

from __future__ import annotations

import argparse
import json
import statistics
from concurrent.futures import ProcessPoolExecutor

from alight.evaluation.runner import run_mission
from alight.scenario import scenario_from_dict

CONDITIONS = {
    "straight 1.2 m/s": {"path": "straight", "speed_mps": 1.2},
    "circle 2.0 m/s": {"path": "circle", "speed_mps": 2.0},
    "figure-8 4.2 m/s": {"path": "figure8", "speed_mps": 4.2},
}


def _fly(args: tuple[str, str, dict, int]) -> dict:
    name, preset, platform, seed = args
    r = run_mission(
        scenario_from_dict({"preset": preset, "seed": seed, "platform": platform}), record=False
    ).result
    return {
        "condition": name,
        **{
            k: r[k]
            for k in (
                "seed",
                "outcome",
                "touchdown_error_m",
                "touchdown_rel_vertical_speed_mps",
                "touchdown_rel_horizontal_speed_mps",
                "time_first_detection_s",
                "time_landing_start_s",
                "time_to_land_s",
                "go_arounds",
                "wall_time_s",
                "simulated_time_s",
            )
        },
    }


def _q(values: list[float], q: float) -> float:
    return (
        statistics.quantiles(values, n=100, method="inclusive")[int(q) - 1] if len(values) > 1 else values[0]
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--preset", default="groundtruth")
    ap.add_argument("--jsonl", default=None, help="also write one JSON line per mission here")
    args = ap.parse_args()
    jobs = [
        (name, args.preset, platform, seed)
        for name, platform in CONDITIONS.items()
        for seed in range(args.first_seed, args.first_seed + args.seeds)
    ]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(_fly, jobs))
    if args.jsonl:
        with open(args.jsonl, "w") as f:
            for r in rows:
                f.write(json.dumps(r) + "\n")
    print(
        "| condition | landed | touchdown error median / p90 / max (m) | rel. vertical speed max (m/s) "
        "| first detection median (s) | touchdown median (s) | failures |"
    )
    print("|---|---|---|---|---|---|---|")
    for name in CONDITIONS:
        rs = [r for r in rows if r["condition"] == name]
        ok = [r for r in rs if r["outcome"] == "landed"]
        err = [r["touchdown_error_m"] for r in ok]
        vz = [r["touchdown_rel_vertical_speed_mps"] for r in ok]
        det = [r["time_first_detection_s"] for r in rs if r["time_first_detection_s"] is not None]
        land = [r["time_to_land_s"] for r in ok]
        fails = ", ".join(f"seed {r['seed']}: {r['outcome']}" for r in rs if r["outcome"] != "landed") or "-"
        err_txt = f"{statistics.median(err):.3f} / {_q(err, 90):.3f} / {max(err):.3f}" if err else "-"
        vz_txt = f"{max(vz):.2f}" if vz else "-"
        det_txt = f"{statistics.median(det):.1f}" if det else "-"
        land_txt = f"{statistics.median(land):.1f}" if land else "-"
        print(f"| {name} | {len(ok)}/{len(rs)} | {err_txt} | {vz_txt} | {det_txt} | {land_txt} | {fails} |")
    sim = sum(r["simulated_time_s"] for r in rows)
    wall = sum(r["wall_time_s"] for r in rows)
    print(
        f"\n{len(rows)} missions, {sim:.0f} s simulated in {wall:.0f} s of mission wall time "
        f"(sum over workers): {sim / wall:.1f}x real time per core"
    )


if __name__ == "__main__":
    main()
