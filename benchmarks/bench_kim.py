"""Benchmark of paper 003's blocks: the colour filter + contour detector per frame, and the UKF per camera
frame (predict + pixel update).

Run: ``python benchmarks/bench_kim.py`` (prints JSON), or ``pytest benchmarks/bench_kim.py`` for the
pytest-benchmark versions. Frames come from ``alight.sim.render`` in colour: the red target
(``alight.pads.RedTarget``) on its deck over grass, asphalt and concrete with red distractors on the
ground (``DistractorSpec``: 8 discs and rectangles per tile), 3 to 15 m above the pad with up to 0.3 rad of
tilt, through a 640 x 480 pinhole (f = 400 px) and the 752 x 480 default downward camera. One thread
(``cv2.setNumThreads(1)``); each time is the best of the repeats, the median over frames.

Keys (a flat dict for ``alight bench``): ``kim_detect_ms_640x480``, ``kim_detect_ms_752x480`` (the whole
``RedTargetDetector.detect``: Alg. 1 + 2, contours, selection, centroid), ``kim_color_filter_ms_640x480``,
``kim_color_filter_ms_752x480`` (Alg. 2 alone, the compiled one-pass kernel),
``kim_color_filter_opencv_ms_640x480`` and ``_752x480`` (the same Alg. 2 as OpenCV's whole-image operations,
:func:`color_filter_opencv`, its peer; every frame checks that both give the same mask),
``kim_detect_gate_shape_ms_752x480`` (with the
``gate+shape`` mitigation), ``kim_detection_rate`` and ``kim_centroid_error_px_median`` (paper mode,
against the projected target centre, frames where the target is the biggest red blob),
``kim_ukf_step_us`` (``KimUkf.update_pixel``: compiled predict + update with eq. 24's roots, 15 sigma
points), ``kim_ukf_step_python_us`` (the same through the generic ``ukf_predict``/``ukf_update``),
``kim_ukf_world_update_us`` (``KimUkf.update`` with a world measurement) and
``kim_flat_earth_locate_us``.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.cameras.omni import OmniCamera
from alight.estimation.kim_ukf import KimUkf, KimUkfConfig, rotation_zyx
from alight.pads import RedTarget
from alight.perception.color_filter import (
    RedTargetDetector,
    RedTargetDetectorConfig,
    alg1_table,
    binary_image_of_color,
    color_filter,
    temp_table,
)
from alight.perception.flat_earth import FlatEarthGeolocator
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import DistractorSpec, make_ground_texture
from alight.types import Observation, PlatformMeasurement


def color_filter_opencv(image_bgr: np.ndarray, tables: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Alg. 2 with OpenCV's whole-image operations (split, Alg. 1 three times, the 0.6 test, three
    saturating subtractions): alight's implementation until the one-pass kernel, kept as its peer."""
    T1, T2 = tables
    B, G, R = cv2.split(image_bgr)
    out = cv2.subtract(binary_image_of_color(R, G, B, T1), binary_image_of_color(G, B, R, T1))
    cv2.subtract(out, binary_image_of_color(B, R, G, T1), dst=out)
    cv2.subtract(out, cv2.compare(G, cv2.LUT(R, T2), cv2.CMP_GT), dst=out)
    return out


MOUNT = CameraMount.downward()
# the fisheye of testdata/real/fisheye_ocamcalib/calib_results_0.txt
LENS = OmniCamera(
    width=1600,
    height=1600,
    ss=np.array([-4.714441e02, 0.0, 7.356108e-04, -3.773045e-07, 5.800006e-10]),
    xc=794.308657,
    yc=798.175741,
    c=1.000305,
    d=-0.000277,
    e=-0.000925,
    rho_max=800.0,
)


def cameras() -> dict[str, PinholeCamera]:
    return {
        "640x480": PinholeCamera(640, 480, np.array([[400.0, 0, 319.5], [0, 400.0, 239.5], [0, 0, 1]])),
        "752x480": PinholeCamera.default_downward(),
    }


def render_frames(cam: PinholeCamera, n_per_ground: int, seed: int = 0) -> list[dict[str, Any]]:
    """Colour frames with the target in view: dicts with ``image`` and the projected target centre ``px``."""
    target = RedTarget.default()
    rng = np.random.default_rng(seed)
    frames: list[dict[str, Any]] = []
    for g, ground in enumerate(("grass", "asphalt", "concrete")):
        tex = make_ground_texture(
            ground, np.random.default_rng(seed + g), size_px=512, color=True, distractors=DistractorSpec()
        )
        r = Renderer(cam, tex, target, RenderOptions(color=True), np.random.default_rng(seed + 10 + g))
        made = 0
        while made < n_per_ground:
            z = rng.uniform(3.0, 15.0)
            eta = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-3.0, 3.0)])
            R_WB = rotation_zyx(eta)
            p_WB = np.array([rng.uniform(-0.3, 0.3) * z, rng.uniform(-0.2, 0.2) * z, z + 0.5])
            p_WP = np.array([0.0, 0.0, 0.5])
            p_WC, R_WC = camera_pose_W(p_WB, R_WB, MOUNT)
            px = cam.project((R_WC.T @ (p_WP - p_WC))[None])[0]
            m = 40.0
            if not (np.isfinite(px).all() and m < px[0] < cam.width - m and m < px[1] < cam.height - m):
                continue
            frames.append({"image": r.render(p_WC, R_WC, (p_WP, rng.uniform(-math.pi, math.pi))), "px": px})
            made += 1
    return frames


def _best(fn: Callable[[], object], repeats: int, inner: int = 1) -> float:
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        best = min(best, (time.perf_counter() - t0) / inner)
    return best


def _ukf_setup(use_compiled: bool = True) -> tuple[KimUkf, Callable[[], bool]]:
    """A KimUkf on the fisheye following a target; the returned step advances 50 ms and updates."""
    f = KimUkf(KimUkfConfig(pixel_std=1.0), camera=LENS, mount=MOUNT)
    f.use_compiled = use_compiled and f.use_compiled
    rng = np.random.default_rng(0)

    class Ego:
        p_WB = np.array([0.0, 0.0, 8.0])
        v_WB = np.array([0.5, 0.0, 0.0])
        R_WB = rotation_zyx(np.array([0.05, -0.03, 0.2]))

    ego = Ego()
    R_WC = ego.R_WB @ MOUNT.R_BC
    state = {"t": 0.0}

    def step() -> bool:
        t = state["t"]
        ego.p_WB = np.array([0.5 * t, 0.0, 8.0])
        pT = np.array([1.0 + 1.5 * t, 0.3 * t, 0.0])
        px = LENS.project_exact((R_WC.T @ (pT - ego.p_WB))[None])[0] + rng.normal(0, 1.0, 2)
        state["t"] = t + 0.05
        return f.update_pixel(t, px, ego)

    for _ in range(20):
        step()
    return f, step


def bench_kim(quick: bool = False, repeats: int | None = None) -> dict[str, float]:
    """Timings (see the module docstring for the keys). ``quick``: 2 frames per ground instead of 10."""
    n_per_ground = 2 if quick else 10
    repeats = repeats if repeats is not None else (2 if quick else 5)
    n_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    out: dict[str, float] = {}
    try:
        plain = RedTargetDetector()
        mitigated = RedTargetDetector(RedTargetDetectorConfig(mitigation="gate+shape", max_fill=0.9))
        tables = (alg1_table(0.8, 20.0), temp_table(0.6))
        found, errors = 0, []
        n_frames = 0
        for name, cam in cameras().items():
            frames = render_frames(cam, n_per_ground)
            n_frames += len(frames)
            det_ms, cf_ms, cv_ms, mit_ms = [], [], [], []
            for fr in frames:
                img = fr["image"]
                det_ms.append(1e3 * _best(lambda img=img: plain.detect(img, 0.0), repeats))
                cf_ms.append(1e3 * _best(lambda img=img: color_filter(img, tables=tables), repeats))
                cv_ms.append(1e3 * _best(lambda img=img: color_filter_opencv(img, tables), repeats))
                if not np.array_equal(color_filter(img, tables=tables), color_filter_opencv(img, tables)):
                    raise AssertionError(f"bench_kim: the two colour filters disagree on a {name} frame")
                mitigated.set_prediction(fr["px"], 60.0)
                mit_ms.append(1e3 * _best(lambda img=img: mitigated.detect(img, 0.0), repeats))
                obs = plain.detect(img, 0.0)
                if obs:
                    found += 1
                    errors.append(float(np.hypot(*(obs[0].pixels[0] - fr["px"]))))
            out[f"kim_detect_ms_{name}"] = statistics.median(det_ms)
            out[f"kim_color_filter_ms_{name}"] = statistics.median(cf_ms)
            out[f"kim_color_filter_opencv_ms_{name}"] = statistics.median(cv_ms)
            if name == "752x480":
                out["kim_detect_gate_shape_ms_752x480"] = statistics.median(mit_ms)
        out["kim_detection_rate"] = found / n_frames
        near = [e for e in errors if e < 20.0]  # frames where a distractor was bigger are not centroid errors
        out["kim_centroid_error_px_median"] = statistics.median(near) if near else math.nan
    finally:
        cv2.setNumThreads(n_threads)
    inner = 50 if quick else 200
    _, step = _ukf_setup(True)
    out["kim_ukf_step_us"] = 1e6 * _best(step, repeats, inner)
    _, step_py = _ukf_setup(False)
    out["kim_ukf_step_python_us"] = 1e6 * _best(step_py, repeats, inner)
    f = KimUkf()
    clock = {"t": 0.0}

    def world() -> bool:
        clock["t"] += 0.05
        t = clock["t"]
        m = PlatformMeasurement(t=t, p_WP=np.array([1.5 * t, 0.0, 0.5]), cov_p_WP=np.eye(3) * 0.01)
        return f.update(m)

    out["kim_ukf_world_update_us"] = 1e6 * _best(world, repeats, inner)
    geo = FlatEarthGeolocator(LENS, MOUNT)
    obs = Observation(t=0.0, kind="blob", quality=1.0, pixels=np.array([[900.0, 700.0]]))
    p_WB, R_WB = np.array([0.0, 0.0, 8.0]), np.eye(3)
    out["kim_flat_earth_locate_us"] = 1e6 * _best(lambda: geo.locate(obs, p_WB, R_WB), repeats, inner)
    return out


# ---- pytest-benchmark ------------------------------------------------------------------------------


def test_bench_kim_detect_752x480(benchmark) -> None:  # type: ignore[no-untyped-def]
    cv2.setNumThreads(1)
    img = render_frames(cameras()["752x480"], 1)[0]["image"]
    det = RedTargetDetector()
    assert benchmark(det.detect, img, 0.0)


def test_bench_kim_detect_640x480(benchmark) -> None:  # type: ignore[no-untyped-def]
    cv2.setNumThreads(1)
    img = render_frames(cameras()["640x480"], 1)[0]["image"]
    det = RedTargetDetector()
    assert benchmark(det.detect, img, 0.0)


def test_bench_kim_ukf_step(benchmark) -> None:  # type: ignore[no-untyped-def]
    _, step = _ukf_setup(True)
    assert benchmark(step)


if __name__ == "__main__":  # pragma: no cover
    print(json.dumps(bench_kim(), indent=2))
