"""Where the wall time of a whole ``falanga2017`` mission goes: rendering, detection, PnP and the rest.

Flies the missions of ``bench_vision_missions`` (after the same warm-up) with timers around
``Renderer.render``, ``FalangaTagDetector.detect`` and ``PnpGeolocator.locate``, and prints, per mission:
the real-time factor, the milliseconds per simulated second of each stage and of the rest (physics,
sensors, estimators, planner, controller), and the milliseconds per frame by the size of the tag in the
image (no detection, then the tag's larger pixel extent; rendering is given per frame on average only:
a frame is rendered from its capture-time poses when it reaches the detector, a latency later, and only
when the detector will use it). OpenCV runs on one thread.
The timers cost a few microseconds per call, so the real-time factor here is slightly below
``alight bench``'s.

It also times the anchor clock of the real-time-factor benchmarks before and after (``reference_aruco_ms``;
multiply a figure in ms by ``anchor_aruco_ms / reference_aruco_ms`` for the anchor machine's speed).

``--budget`` adds what issue 3's target (``sim_rtf_falanga2017_at_reference >= 25``) leaves per frame,
and the best real-time factor the present blocks could reach with nothing but their isolated cost: the
flight loop's ms per simulated second (the groundtruth preset flies the same blocks without a camera),
plus 20 frames a second of a render and a detection timed alone on one frame of each kind (search, tag
small, tag filling the view; the preset's sensor noise on, no mission around them to evict caches),
and the OpenCV calls that no renderer or detector of a full 752x480 frame can skip. All at the anchor
machine's speed.

Run: ``python benchmarks/vision_mission_breakdown.py [--seeds 1,2] [--budget]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections import defaultdict
from typing import Any

import cv2
import numpy as np

from alight.airframe import DEFAULT_AIRFRAME
from alight.cameras.pinhole import camera_pose_W
from alight.evaluation.bench import ANCHOR_ARUCO_MS, load_benchmark
from alight.evaluation.runner import run_mission
from alight.mission.presets import build_preset
from alight.perception.falanga_tag import FalangaTagDetector
from alight.perception.geolocation import PnpGeolocator
from alight.scenario import scenario_from_dict
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import rot_z

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


_TARGET_RTF = 25.0
_FRAME_RATE_HZ = 20.0


def _best_ms(fn: Any, repeats: int) -> float:
    """Median over ``repeats`` calls of ``fn`` (ms), after two warm-up calls."""
    fn()
    fn()
    ts = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t0
    return float(np.median(ts) * 1e3)


def _isolated_frames(repeats: int) -> tuple[dict[str, dict[str, float]], dict[str, float]]:
    """Render and detect, each timed alone (ms), on one frame of each kind, with the falanga2017 preset's
    camera, tag, detector and sensor noise; and the OpenCV calls a full frame cannot do without."""
    s = scenario_from_dict({**_SCENARIOS[1], "seed": 1})
    preset = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    renderer = Renderer(
        preset.camera,
        make_ground_texture(s.camera.ground, rng),
        preset.pad,
        RenderOptions(noise_sigma_dn=s.camera.noise_dn),
        rng,
        R_BC=preset.mount.R_BC,
    )
    detector = FalangaTagDetector(preset.pad)
    pad_pose = (np.array([0.0, 0.0, s.platform.pad_height_m]), 0.3)
    deck_z = float(pad_pose[0][2])
    kinds = {  # the vehicle at (x, y, z) in W, level, heading 0.3 rad (the platform's); heights over the deck
        "search, ground only, 12 m": np.array([40.0, 25.0, 12.0]),
        "tag small, 10 m": np.array([0.6, -0.4, deck_z + 10.0]),
        "tag a third of the view, 3 m": np.array([0.2, -0.1, deck_z + 3.0]),
        "tag fills the view, 0.7 m": np.array([0.05, 0.0, deck_z + 0.7]),
    }
    frames: dict[str, dict[str, float]] = {}
    for name, p_WB in kinds.items():
        p_WC, R_WC = camera_pose_W(p_WB, rot_z(0.3), preset.mount)
        img = renderer.render(p_WC, R_WC, pad_pose)
        detector.set_range(float(p_WB[2] - deck_z) if "tag" in name else float(p_WB[2]))
        found = bool(detector.detect(img, 0.0))
        frames[name] = {
            "render_ms": _best_ms(lambda: renderer.render(p_WC, R_WC, pad_pose), repeats),  # noqa: B023
            "detect_ms": _best_ms(lambda: detector.detect(img, 0.0), repeats),  # noqa: B023
            "tag_found": found,
        }
    # the calls no renderer or detector of a whole 752x480 frame can skip: one bilinear resampling of the
    # frame (the deck filling the view), the ground at half resolution brought up to full, and one pass
    # of the detector over the frame at its search resolution (area downscale, a global threshold)
    p_WC, R_WC = camera_pose_W(kinds["tag fills the view, 0.7 m"], rot_z(0.3), preset.mount)
    deck = renderer._deck_maps(p_WC, R_WC, pad_pose[0], pad_pose[1])
    assert deck is not None and deck[2] == renderer.width * renderer.height, "the deck must fill the view"
    H, W = renderer.height, renderer.width
    b = renderer._buf
    mx, my = b.pmx.reshape(H, W), b.pmy.reshape(H, W)
    out = np.empty((H, W), np.uint8)
    level = deck[1].image
    p_WC, R_WC = camera_pose_W(kinds["search, ground only, 12 m"], rot_z(0.3), preset.mount)
    img = renderer.render(p_WC, R_WC, pad_pose)
    half = np.empty((H // 2, W // 2), np.uint8)
    primitives = {
        "full_frame_bilinear_remap_ms": _best_ms(
            lambda: cv2.remap(level, mx, my, cv2.INTER_LINEAR, dst=out, borderMode=cv2.BORDER_REPLICATE),
            repeats,
        ),
        "ground_half_resolution_and_pyrup_ms": _best_ms(
            lambda: renderer._draw_ground(p_WC, R_WC, out), repeats
        ),
        "area_downscale_and_threshold_ms": _best_ms(
            lambda: cv2.threshold(
                cv2.resize(img, (W // 2, H // 2), dst=half, interpolation=cv2.INTER_AREA),
                128,
                255,
                cv2.THRESH_BINARY,
            ),
            repeats,
        ),
    }
    return frames, primitives


def budget(repeats: int = 200) -> dict[str, Any]:
    """What ``sim_rtf_falanga2017_at_reference >= 25`` leaves per frame once the flight loop is paid, and
    the best real-time factor of each kind of frame from isolated stage costs (see the module docstring).
    Times the anchor clock before and after, as the missions do."""
    n_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        clock = load_benchmark("bench_detectors").aruco_reference_ms
        sim = load_benchmark("bench_sim")
        sim._rtf(sim._SCENARIO, 0, False)  # warm-up
        before = clock()
        flight_ms = statistics.median(1e3 / sim._rtf(sim._SCENARIO, seed, False)[0] for seed in (1, 2, 3))
        frames, primitives = _isolated_frames(repeats)
        ref = 0.5 * (before + clock())
    finally:
        cv2.setNumThreads(n_threads)
    to_ref = ANCHOR_ARUCO_MS / ref
    allowed = 1e3 / _TARGET_RTF
    flight_ref = flight_ms * to_ref
    per_frame_left = (allowed - flight_ref) / _FRAME_RATE_HZ
    kinds = {}
    for name, f in frames.items():
        frame_ref = (f["render_ms"] + f["detect_ms"]) * to_ref
        kinds[name] = {
            "render_ms_at_reference": round(f["render_ms"] * to_ref, 3),
            "detect_ms_at_reference": round(f["detect_ms"] * to_ref, 3),
            "tag_found": f["tag_found"],
            "best_rtf_at_reference": round(1e3 / (flight_ref + _FRAME_RATE_HZ * frame_ref), 1),
            "speed_up_needed": round(frame_ref / per_frame_left, 2) if per_frame_left > 0 else None,
        }
    return {
        "reference_aruco_ms": round(ref, 2),
        "target_rtf_at_reference": _TARGET_RTF,
        "ms_per_simulated_s_allowed_at_reference": round(allowed, 1),
        "flight_loop_ms_per_simulated_s_at_reference": round(flight_ref, 2),
        "render_detect_ms_per_frame_left_at_reference": round(per_frame_left, 3),
        "frames": kinds,
        "primitives_ms_at_reference": {k: round(v * to_ref, 3) for k, v in primitives.items()},
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="1,2", help="seed offsets, as in bench_vision_missions")
    ap.add_argument("--budget", action="store_true", help="add the per-frame budget of issue 3's target")
    args = ap.parse_args()
    clock = load_benchmark("bench_detectors").aruco_reference_ms
    before = clock()
    rows = breakdown(tuple(int(x) for x in args.seeds.split(",")))
    ref = 0.5 * (before + clock())
    report: dict[str, Any] = {"reference_aruco_ms": round(ref, 2), "anchor_aruco_ms": ANCHOR_ARUCO_MS}
    report["missions"] = rows
    if args.budget:
        report["budget"] = budget()
    print(json.dumps(report, indent=1))
