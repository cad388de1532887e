"""Where the wall time of a whole ``falanga2017`` mission goes: rendering, detection, PnP and the rest.

Flies the missions of ``bench_vision_missions`` (after the same warm-up) with timers around
``Renderer.render``, ``FalangaTagDetector.detect`` and ``PnpGeolocator.locate``, and prints, per mission:
the real-time factor, the milliseconds per simulated second of each stage and of the rest (physics,
sensors, estimators, planner, controller), and the milliseconds per frame by the size of the tag in the
image (no detection, then the tag's larger pixel extent; each frame is rendered at its capture time and
detected a latency later, so rendering is given per frame on average only). OpenCV runs on one thread.
The timers cost a few microseconds per call, so the real-time factor here is slightly below
``alight bench``'s.

It also times the anchor clock of the real-time-factor benchmarks before and after (``reference_aruco_ms``;
multiply a figure in ms by ``anchor_aruco_ms / reference_aruco_ms`` for the anchor machine's speed).

Run: ``python benchmarks/vision_mission_breakdown.py [--seeds 1,2]``.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from typing import Any

import cv2
import numpy as np

from alight.evaluation.bench import ANCHOR_ARUCO_MS, load_benchmark
from alight.evaluation.runner import run_mission
from alight.perception.falanga_tag import FalangaTagDetector
from alight.perception.geolocation import PnpGeolocator
from alight.scenario import scenario_from_dict
from alight.sim.render import Renderer

# the missions of ``alight bench``'s vision group, so the two measure the same thing
_SCENARIOS = load_benchmark("bench_vision_missions")._SCENARIOS
_SIZE_BINS_PX = (0.0, 120.0, 240.0, 400.0, np.inf)


class _Timers:
    """Wraps the three stages' methods with timers for the duration of a ``with`` block."""

    def __init__(self) -> None:
        self.ms: dict[str, float] = defaultdict(float)
        self.frames: list[tuple[float, float]] = []  # (tag extent px, 0 for none; detect ms)

    def __enter__(self) -> _Timers:
        self._saved = (Renderer.render, FalangaTagDetector.detect, PnpGeolocator.locate)
        render, detect, locate = self._saved
        timers = self

        def timed_render(obj: Any, *a: Any, **k: Any) -> Any:
            t0 = time.perf_counter()
            out = render(obj, *a, **k)
            timers.ms["render"] += (time.perf_counter() - t0) * 1e3
            return out

        def timed_detect(obj: Any, image: Any, t: float) -> Any:
            t0 = time.perf_counter()
            out = detect(obj, image, t)
            dt = (time.perf_counter() - t0) * 1e3
            timers.ms["detect"] += dt
            size = float(np.ptp(out[0].pixels, axis=0).max()) if out else 0.0
            timers.frames.append((size, dt))
            return out

        def timed_locate(obj: Any, *a: Any, **k: Any) -> Any:
            t0 = time.perf_counter()
            out = locate(obj, *a, **k)
            timers.ms["pnp"] += (time.perf_counter() - t0) * 1e3
            return out

        Renderer.render = timed_render  # type: ignore[method-assign]
        FalangaTagDetector.detect = timed_detect  # type: ignore[method-assign]
        PnpGeolocator.locate = timed_locate  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: object) -> None:
        Renderer.render, FalangaTagDetector.detect, PnpGeolocator.locate = self._saved  # type: ignore[method-assign]


def _mean_ms(ms: np.ndarray, mask: np.ndarray) -> dict[str, Any]:
    return {"frames": int(mask.sum()), "detect_ms": round(float(ms[mask].mean()), 3) if mask.any() else None}


def breakdown(seed_offsets: tuple[int, ...] = (1, 2)) -> list[dict[str, Any]]:
    n_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    rows = []
    try:
        run_mission(scenario_from_dict({**_SCENARIOS[0], "seed": 0}), record=False)  # warm-up
        for s in seed_offsets:
            for k, sc in enumerate(_SCENARIOS):
                seed = 100 * k + s
                with _Timers() as tm:
                    t0 = time.perf_counter()
                    res = run_mission(scenario_from_dict({**sc, "seed": seed}), record=False).result
                    wall_ms = (time.perf_counter() - t0) * 1e3
                sim_s = float(res["simulated_time_s"])
                per_s = {key: round(v / sim_s, 2) for key, v in tm.ms.items()}
                per_s["rest"] = round((wall_ms - sum(tm.ms.values())) / sim_s, 2)
                sizes = np.array([f[0] for f in tm.frames])
                det_ms = np.array([f[1] for f in tm.frames])
                by_size = {}
                for lo, hi in zip(_SIZE_BINS_PX[:-1], _SIZE_BINS_PX[1:], strict=True):
                    m = (sizes > lo) & (sizes <= hi) if lo > 0 else (sizes > 0) & (sizes <= hi)
                    by_size[f"tag {lo:.0f}-{hi:.0f} px"] = _mean_ms(det_ms, m)
                by_size["no tag"] = _mean_ms(det_ms, sizes == 0)
                rows.append(
                    {
                        "path": sc["platform"]["path"],
                        "seed": seed,
                        "outcome": res["outcome"],
                        "simulated_s": round(sim_s, 2),
                        "rtf": round(sim_s * 1e3 / wall_ms, 1),
                        "frames": len(tm.frames),
                        "ms_per_simulated_s": per_s,
                        "render_ms_per_frame": round(tm.ms["render"] / max(len(tm.frames), 1), 3),
                        "detect_by_tag_size": by_size,
                    }
                )
    finally:
        cv2.setNumThreads(n_threads)
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="1,2", help="seed offsets, as in bench_vision_missions")
    args = ap.parse_args()
    clock = load_benchmark("bench_detectors").aruco_reference_ms
    before = clock()
    rows = breakdown(tuple(int(x) for x in args.seeds.split(",")))
    ref = 0.5 * (before + clock())
    print(
        json.dumps(
            {"reference_aruco_ms": round(ref, 2), "anchor_aruco_ms": ANCHOR_ARUCO_MS, "missions": rows},
            indent=1,
        )
    )
