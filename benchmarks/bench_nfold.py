"""Benchmark of the n-fold marker detector (paper 004 Sec. IV-A) on rendered 752 x 480 frames: the fast
detector (:class:`alight.perception.nfold.NFoldDetector`: separable kernel, coarse to fine) against the
plain method (two full-frame ``cv2.filter2D``, :func:`alight.perception.nfold.nfold_detect_filter2d`), per
kernel size, plus the adaptive search and the whole SDU landing-marker detector (n-fold + OpenCV ArUco).

Run: ``python benchmarks/bench_nfold.py`` (prints JSON), ``alight bench --only nfold``, or
``pytest benchmarks/bench_nfold.py`` (pytest-benchmark). Frames: the SDU pad (plain 4-fold marker) over
grass, asphalt and concrete from 1.5 to 13 m with up to 0.3 rad of tilt, the n-fold disc fully in view and
at least 30 px wide. One thread (``cv2.setNumThreads(1)``); each timing is the best of a few repeats per
frame (the frame's own cost), then the median over frames; the two variants are interleaved frame by
frame so that a busy machine slows both alike.

Keys (a flat dict for ``alight bench``): ``nfold_frames``; per kernel size k in 13, 21, 31, 41:
``nfold_fast_ms_k{k}``, ``nfold_filter2d_ms_k{k}``, ``nfold_speedup_k{k}``; ``nfold_same_peak_fraction``
(fast and plain peaks within 0.5 px, over frames and sizes); ``nfold_adaptive_ms_per_frame`` and
``nfold_adaptive_ms_p90`` (the adaptive search, as ``detect`` runs it), ``nfold_adaptive_mean_sizes_tried``;
``nfold_no_marker_ms`` (a frame of ground only: every size is tried, the worst case);
``nfold_detection_rate`` (within 3 px of the projected tip), ``nfold_tip_error_median_px``;
``sdu_marker_ms_per_frame`` (n-fold + ArUco + fusion).

Measured (2-core AMD EPYC VM shared with other jobs, load ~6, OpenCV 5.0, one thread, 30 frames): plain
method 18-24 ms per kernel size (k = 13, 21, 31, 41), fast detector 1.9-2.4 ms, speed-up 8.5-10.5x, the
same peak on 120/120 frame-size pairs; adaptive search 3.0 ms median (p90 8 ms, 2 sizes tried on
average), 18 ms on a frame without a marker (all 8 sizes, 6 coarse passes thanks to shared plans);
detection rate 1.0, median tip error 0.025 px; the whole SDU detector 24 ms (OpenCV's ArUco dominates).
"""

from __future__ import annotations

import json
import math
import time
from typing import Any

import cv2
import numpy as np

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.pads.sdu_pad import SduPad
from alight.perception.nfold import NFoldConfig, NFoldDetector, nfold_detect_filter2d
from alight.perception.sdu_marker import SduMarkerDetector
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import rot_z

KERNEL_SIZES = (13, 21, 31, 41)


def _R_WB(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return rot_z(yaw) @ Ry @ Rx


def render_frames(n_per_ground: int = 10, seed: int = 0) -> list[dict[str, Any]]:
    """Frames with the n-fold disc fully in view and at least 30 px wide: dicts with ``image`` (uint8
    752 x 480) and the true tip pixel ``tip``; plus one frame of ground only (``tip`` None) at the end."""
    cam = PinholeCamera.default_downward()
    mount = CameraMount.downward()
    pad = SduPad.default()
    rng = np.random.default_rng(seed)
    ang = np.linspace(0.0, 2 * np.pi, 16, endpoint=False)
    rim = np.c_[pad.nfold_radius_m * np.cos(ang), pad.nfold_radius_m * np.sin(ang), np.zeros(16)]
    frames: list[dict[str, Any]] = []
    r = None
    for g, ground in enumerate(("grass", "asphalt", "concrete")):
        tex = make_ground_texture(ground, np.random.default_rng(seed + g), size_px=512)
        r = Renderer(cam, tex, pad, RenderOptions(), np.random.default_rng(seed + 10 + g))
        made = 0
        while made < n_per_ground:
            z = rng.uniform(1.5, 13.0)
            R_WB = _R_WB(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-math.pi, math.pi))
            p_WB = np.array([rng.uniform(-0.4, 0.4) * z, rng.uniform(-0.3, 0.3) * z, z + 0.5])
            p_WP, yaw = np.array([0.0, 0.0, 0.5]), rng.uniform(-math.pi, math.pi)
            p_WC, R_WC = camera_pose_W(p_WB, R_WB, mount)
            R_CP, p_CP = R_WC.T @ rot_z(yaw), R_WC.T @ (p_WP - p_WC)
            rp = cam.project((R_CP @ rim.T).T + p_CP)
            if not (np.isfinite(rp).all() and (rp > 2).all() and (rp[:, 0] < cam.width - 3).all()):
                continue
            if not (rp[:, 1] < cam.height - 3).all() or np.linalg.norm(rp[:8] - rp[8:], axis=1).min() < 30:
                continue
            img = r.render(p_WC, R_WC, (p_WP, yaw))
            frames.append({"image": img, "tip": cam.project(p_CP[None, :])[0]})
            made += 1
    assert r is not None
    p_WC, R_WC = camera_pose_W(np.array([40.0, 0.0, 6.0]), _R_WB(0.0, 0.0, 0.3), mount)
    frames.append({"image": r.render(p_WC, R_WC, (np.array([0.0, 0.0, 0.5]), 0.0)), "tip": None})
    return frames


def _best(fn: Any, repeats: int) -> float:
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def bench_nfold(
    quick: bool = False, n_per_ground: int | None = None, repeats: int | None = None
) -> dict[str, float]:
    """Timings and rates, a flat dict (see the module docstring for the keys). ``quick``: 2 frames per
    ground and 2 repeats instead of 10 and 3."""
    if n_per_ground is None:
        n_per_ground = 2 if quick else 10
    if repeats is None:
        repeats = 2 if quick else 3
    n_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        frames = render_frames(n_per_ground)
        marked = [f for f in frames if f["tip"] is not None]
        empty = [f for f in frames if f["tip"] is None]
        pad = SduPad.default()
        det = NFoldDetector(NFoldConfig(order=pad.nfold_order, oriented=pad.nfold_oriented))
        sdu = SduMarkerDetector(pad)
        for f in marked[:2]:  # warm up (numba cache load, OpenCV allocations)
            det.detect_result(f["image"])
            sdu.detect(f["image"], 0.0)
        out: dict[str, float] = {"nfold_frames": len(marked)}
        same = total = 0
        for k in KERNEL_SIZES:
            t_fast, t_ref = [], []
            for f in marked:
                img = f["image"]
                bf = br = math.inf
                for _ in range(repeats):
                    t0 = time.perf_counter()
                    a = det.detect_at(img, k)
                    t1 = time.perf_counter()
                    b = nfold_detect_filter2d(img, pad.nfold_order, k)
                    t2 = time.perf_counter()
                    bf, br = min(bf, t1 - t0), min(br, t2 - t1)
                t_fast.append(bf * 1e3)
                t_ref.append(br * 1e3)
                total += 1
                same += a is not None and b is not None and abs(a.x - b.x) < 0.5 and abs(a.y - b.y) < 0.5
            out[f"nfold_fast_ms_k{k}"] = float(np.median(t_fast))
            out[f"nfold_filter2d_ms_k{k}"] = float(np.median(t_ref))
            out[f"nfold_speedup_k{k}"] = float(np.median(t_ref) / np.median(t_fast))
        out["nfold_same_peak_fraction"] = same / total
        t_ad, sizes, errs, t_sdu = [], [], [], []
        for f in marked:
            img = f["image"]
            t_ad.append(_best(lambda img=img: det.detect_result(img), repeats))
            t_sdu.append(_best(lambda img=img: sdu.detect(img, 0.0), repeats))
            res = det.detect_result(img)
            sizes.append(len(res.kernel_sizes_tried) if res is not None else len(det.config.kernel_sizes))
            errs.append(math.inf if res is None else math.hypot(res.x - f["tip"][0], res.y - f["tip"][1]))
        errs_a = np.array(errs)
        out["nfold_adaptive_ms_per_frame"] = float(np.median(t_ad))
        out["nfold_adaptive_ms_p90"] = float(np.percentile(t_ad, 90))
        out["nfold_adaptive_mean_sizes_tried"] = float(np.mean(sizes))
        out["nfold_no_marker_ms"] = float(
            np.median([_best(lambda f=f: det.detect_result(f["image"]), repeats) for f in empty])
        )
        out["nfold_detection_rate"] = float(np.mean(errs_a < 3.0))
        out["nfold_tip_error_median_px"] = float(np.median(errs_a))
        out["sdu_marker_ms_per_frame"] = float(np.median(t_sdu))
        return out
    finally:
        cv2.setNumThreads(n_threads)


# ---------------------------------------------------------------------------------- pytest-benchmark

_FRAMES: list[dict[str, Any]] = []


def _frame() -> np.ndarray:
    if not _FRAMES:
        _FRAMES.extend(render_frames(1))
    return _FRAMES[0]["image"]  # type: ignore[no-any-return]


def test_bench_nfold_fast_k21(benchmark) -> None:  # type: ignore[no-untyped-def]
    img, det = _frame(), NFoldDetector(NFoldConfig(order=4))
    det.detect_at(img, 21)
    res = benchmark(det.detect_at, img, 21)
    assert res is not None


def test_bench_nfold_filter2d_k21(benchmark) -> None:  # type: ignore[no-untyped-def]
    img = _frame()
    res = benchmark(nfold_detect_filter2d, img, 4, 21)
    assert res is not None


def test_bench_nfold_adaptive(benchmark) -> None:  # type: ignore[no-untyped-def]
    img, det = _frame(), NFoldDetector(NFoldConfig(order=4))
    det.detect_result(img)
    res = benchmark(det.detect_result, img)
    assert res is not None


if __name__ == "__main__":  # pragma: no cover
    print(json.dumps(bench_nfold(), indent=1))
