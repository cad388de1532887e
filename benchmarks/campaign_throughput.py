"""Campaign throughput: missions per hour per preset, Dask scaling from 1 to 2 workers with an Amdahl model
for N workers, and the peak memory of a worker, with the memory bound enforced.

Run: ``python benchmarks/campaign_throughput.py [--missions 2] [--duration-s 15] [--scaling-missions 4]
[--memory-limit-mib 2048] [--presets groundtruth,falanga2017,...]`` (prints JSON; a few minutes at the
defaults on two cores). Every figure is from real campaigns (``alight.campaign.run_campaign``) into a
temporary directory:

- ``presets.<name>``: a fixed campaign of ``--missions`` missions of the preset (``_BASE``,
  ``--duration-s`` simulated seconds, a platform driving past the take-off point) on the local
  engine with 2 workers. ``missions_per_hour`` is end to end (start-up, warm-up, recording, summary
  included: what a user sees for a campaign this short); ``missions_per_hour_steady`` is
  ``3600 * workers / mean mission wall time``, the rate a long campaign approaches. ``mission_wall_s``,
  ``simulated_s`` (means) and ``compute_ms_per_simulated_s`` say where it goes.
- ``dask``: a groundtruth campaign of ``--scaling-missions`` missions on the embedded Dask cluster with 1
  then 2 workers (T1, T2); ``efficiency_2 = T1 / (2 T2)``. The serial part S is measured as the same
  campaign's time with instant missions (cluster start, warm-up, submission, recording, summary:
  everything but flying), and the model is Amdahl's, ``T(N) = S + (T1 - S) / N``: ``model`` gives T(N)
  and the efficiency ``T1 / (N T(N))`` for N = 2, 4, 8, 16, 32, and ``model_T2_error`` how far the model
  is from the measured T2. ``fit`` is the two-point fit (S = 2 T2 - T1) for comparison.
- ``memory``: each sandbox's resident-memory high-water mark (``getrusage``; the sandbox flies, the
  worker process that owns it holds little), max over the campaign per preset, and the bound: every
  campaign runs with ``memory_limit_mib``; a sandbox over it after a mission is replaced
  (``sandboxes_replaced`` counts the processes that flew missions beyond one per worker).

Before measuring, the presets are warmed up once in a separate process so numba's cache is full: the
figures are an installed system's, not a first run's (``cache_warm_up_compile_s`` says what that first
run paid). On a machine shared with other work the times are upper bounds; ``load_average`` is recorded
at the start and the end.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from alight.campaign import campaign_from_dict, run_campaign
from alight.campaign.engines import fly_mission, max_rss_mib

PRESETS = ("groundtruth", "falanga2017", "zamanakos_sdu", "kim_kaist")
MODULE = Path(__file__).stem


def measured(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """The campaign's own mission (``fly_mission``) plus the sandbox's pid and memory high-water mark."""
    result = fly_mission(scenario, out_dir)
    result["sandbox_pid"] = os.getpid()
    result["sandbox_max_rss_mib"] = max_rss_mib()
    return result


def instant(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """No flight: what a campaign costs besides flying."""
    return {
        "outcome": "landed",
        "success": True,
        "sandbox_pid": os.getpid(),
        "sandbox_max_rss_mib": max_rss_mib(),
    }


# The missions flown: a platform that drives toward the take-off point, under the camera within a few
# seconds, so a 15 s mission takes off, detects, tracks and approaches. (This was the warm-up flight's
# scenario until the warm-up started the platform out of view to fly the search too; the benchmark keeps
# its missions, so its figures stay comparable.)
_BASE: dict[str, Any] = {
    "platform": {"path": "straight", "speed_mps": 1.0, "start_xy": [6.0, 2.0], "heading_rad": 3.14},
}


def _campaign(name: str, preset: str, n: int, duration_s: float) -> Any:
    base = {**_BASE, "duration_s": duration_s}
    return campaign_from_dict(
        {
            "name": name,
            "base": base,
            "presets": [preset],
            "seeds_per_condition": n,
            "seed": 7,
            "timeout_s": 900.0,
        }
    )


def _run(campaign: Any, out: Path, fn: str, **kw: Any) -> dict[str, Any]:
    t0 = time.perf_counter()
    result = run_campaign(campaign, out, mission_fn=f"{MODULE}:{fn}", report=False, warmup=True, **kw)
    wall = time.perf_counter() - t0
    results = [json.loads(p.read_text()) for p in sorted(out.glob("missions/*/result.json"))]
    flown = [r for r in results if r.get("outcome") != "error"]
    pids = {r["sandbox_pid"] for r in flown}
    return {
        "wall_s": wall,
        "missions": result.n_run,
        "errors": result.n_errors,
        "results": flown,
        "sandboxes": len(pids),
        "peak_rss_mib": max((r["sandbox_max_rss_mib"] for r in flown), default=None),
    }


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--presets", default=",".join(PRESETS))
    ap.add_argument("--missions", type=int, default=2, help="missions per preset campaign")
    ap.add_argument("--duration-s", type=float, default=15.0, help="simulated seconds per mission")
    ap.add_argument("--scaling-missions", type=int, default=4, help="missions of the Dask scaling campaign")
    ap.add_argument("--memory-limit-mib", type=float, default=2048.0)
    args = ap.parse_args()
    presets = [p for p in args.presets.split(",") if p]
    workers = 2
    out: dict[str, Any] = {"load_average_start": _load(), "cpu_count": os.cpu_count(), "workers": workers}

    # numba's cache filled once, in its own process (it is the first run's cost, not a campaign's)
    code = (
        "import json, sys; from alight.compile.warmup import warm_up; r = warm_up(sys.argv[1].split(',')); "
        "print(json.dumps({'wall_s': r.wall_s, 'compile_s': r.compile_s}))"
    )
    warm = subprocess.run(
        [sys.executable, "-c", code, ",".join(presets)], capture_output=True, text=True, check=True
    )
    out["cache_warm_up_compile_s"] = json.loads(warm.stdout.strip().splitlines()[-1])["compile_s"]

    limit = args.memory_limit_mib
    with tempfile.TemporaryDirectory(prefix="alight-throughput-") as tmp:
        root = Path(tmp)
        per_preset: dict[str, Any] = {}
        for preset in presets:
            camp = _campaign(f"tp-{preset}", preset, args.missions, args.duration_s)
            r = _run(camp, root / preset, "measured", workers=workers, memory_limit_mib=limit)
            walls = [x["wall_time_s"] for x in r["results"]]
            sims = [x["simulated_time_s"] for x in r["results"]]
            per_preset[preset] = {
                "missions": r["missions"],
                "errors": r["errors"],
                "campaign_wall_s": round(r["wall_s"], 2),
                "missions_per_hour": round(3600.0 * r["missions"] / r["wall_s"], 1),
                "missions_per_hour_steady": round(3600.0 * workers / statistics.mean(walls), 1)
                if walls
                else None,
                "mission_wall_s": round(statistics.mean(walls), 3) if walls else None,
                "simulated_s": round(statistics.mean(sims), 2) if sims else None,
                "compute_ms_per_simulated_s": round(1e3 * sum(walls) / sum(sims), 1) if sims else None,
                "peak_rss_mib": r["peak_rss_mib"],
                "sandboxes_replaced": max(0, r["sandboxes"] - workers),
            }
        out["presets"] = per_preset

        n = args.scaling_missions
        camp = _campaign("tp-scaling", "groundtruth", n, args.duration_s)
        t = {}
        for w in (1, 2):
            r = _run(camp, root / f"dask{w}", "measured", engine="dask", workers=w, memory_limit_mib=limit)
            t[w] = r["wall_s"]
            out.setdefault("memory", {})[f"dask_{w}_workers_peak_rss_mib"] = r["peak_rss_mib"]
        s = _run(camp, root / "serial", "instant", engine="dask", workers=2, memory_limit_mib=limit)["wall_s"]
        t1, t2 = t[1], t[2]
        model = {
            str(k): {"T_s": round(s + (t1 - s) / k, 2), "efficiency": round(t1 / (k * (s + (t1 - s) / k)), 3)}
            for k in (2, 4, 8, 16, 32)
        }
        s_fit = 2 * t2 - t1
        out["dask"] = {
            "missions": n,
            "T1_s": round(t1, 2),
            "T2_s": round(t2, 2),
            "efficiency_2": round(t1 / (2 * t2), 3),
            "serial_s_measured": round(s, 2),
            "serial_fraction": round(s / t1, 3),
            "model": model,
            "model_T2_error_s": round(model["2"]["T_s"] - t2, 2),
            "fit": {"serial_s": round(s_fit, 2), "parallel_s": round(t1 - s_fit, 2)},
        }
    out["memory"] |= {
        "limit_mib": limit,
        "peak_rss_mib_by_preset": {p: v["peak_rss_mib"] for p, v in per_preset.items()},
    }
    out["load_average_end"] = _load()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
