"""What a campaign's views of its failures cost: the same campaign of mostly failing missions flown with
``views_per_cell: all`` (every failure's figures, report.html and replay.gif drawn from its one flight)
and with the default (the first few failures of the cell flown again after the sweep to draw them).

Run: ``python benchmarks/campaign_views.py [--missions 60] [--speed-mps 2.75] [--workers 2]`` (prints
JSON; about 6 min at the defaults on two cores). The missions are falanga2017 on a straight line at
``--speed-mps`` for 30 s, the speed at which ``examples/campaigns/thousand_falanga2017.yaml`` times out
most. For each setting: the campaign's wall time, the CPU time of the campaign and its worker processes
(``os.times`` of this process's children), the size of the output directory, the outcomes, and whether
every results.csv column but the clocks agrees between the two runs (it must: the views change no
flight). The numba cache is warmed first in a separate process, so neither run pays for compiling.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

from alight.campaign import campaign_from_dict, run_campaign
from alight.campaign.results import read_rows
from alight.campaign.spec import VIEWS_PER_CELL
from alight.campaign.store import BLOCK_TIME_COLUMNS

CLOCK_COLUMNS = {"wall_time_s", "mission_dir", *BLOCK_TIME_COLUMNS}
"""Columns that are clocks (or the mission's directory name): they may differ between two runs."""


def _campaign(name: str, missions: int, speed: float, views: int | str) -> dict[str, Any]:
    return {
        "name": name,
        "base": {"platform": {"path": "straight", "speed_mps": speed}, "perception": {"rate_hz": 20.0}},
        "duration_s": 30.0,
        "presets": ["falanga2017"],
        "seeds_per_condition": missions,
        "seed": 1000,
        "timeout_s": 300.0,
        "views_per_cell": views,
    }


def _size_mb(root: Path) -> float:
    return sum(p.stat().st_size for p in root.rglob("*") if p.is_file()) / 1e6


def _rows(out: Path) -> dict[str, dict[str, str]]:
    return {r["mission_id"]: r for r in read_rows(out / "results.csv")}  # the one results.csv reader


def _run(root: Path, missions: int, speed: float, views: int | str, workers: int) -> dict[str, Any]:
    out = root / f"views_{views}"
    before = os.times()
    t0 = time.perf_counter()
    result = run_campaign(
        campaign_from_dict(_campaign(f"views_{views}", missions, speed, views)), out, workers=workers
    )
    wall = time.perf_counter() - t0
    after = os.times()
    cpu = sum(
        getattr(after, k) - getattr(before, k) for k in ("user", "system", "children_user", "children_system")
    )
    rows = _rows(out)
    return {
        "views_per_cell": views,
        "wall_s": round(wall, 1),
        "cpu_s": round(cpu, 1),
        "output_mb": round(_size_mb(out), 1),
        "outcomes": dict(Counter(r["outcome"] for r in rows.values())),
        "views_flown_again": result.n_views,
        "views_problems": result.views_problems,
        "_rows": rows,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=60)
    ap.add_argument("--speed-mps", type=float, default=2.75)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    subprocess.run(
        [sys.executable, "-c", "from alight.compile.warmup import warm_up; warm_up(['falanga2017'])"],
        check=True,
    )
    with tempfile.TemporaryDirectory(prefix="alight-views-bench-") as tmp:
        runs = [
            _run(Path(tmp), args.missions, args.speed_mps, v, args.workers) for v in ("all", VIEWS_PER_CELL)
        ]
    a, b = (r.pop("_rows") for r in runs)
    differ = sorted(
        m for m in a if any(a[m][k] != b.get(m, {}).get(k) for k in a[m] if k not in CLOCK_COLUMNS)
    )
    print(
        json.dumps(
            {
                "missions": args.missions,
                "speed_mps": args.speed_mps,
                "workers": args.workers,
                "runs": runs,
                "wall_ratio": round(runs[1]["wall_s"] / runs[0]["wall_s"], 3),
                "missions_differing_outside_clocks": differ,
                "load_average": os.getloadavg(),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
