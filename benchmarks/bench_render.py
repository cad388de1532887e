"""Benchmark of the camera renderer (``alight.sim.render``): milliseconds per 752 x 480 frame.

Run: ``python benchmarks/bench_render.py`` (prints JSON). The target is <= 1.5 ms per frame on one core
with the noise off; OpenCV is limited to one thread while it runs.
"""

from __future__ import annotations

import json
import time

import cv2
import numpy as np

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.pads import FalangaTag
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import quat_to_rotmat, rot_z


def _poses() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    mount = CameraMount.downward()
    tilt = quat_to_rotmat(np.array([0.0, np.sin(0.6), 0.0, np.cos(0.6)]))  # 1.2 rad pitch
    cases = {
        "nadir_10m_pad_small": (np.array([0.5, 0.3, 10.0]), rot_z(0.3)),
        "nadir_3m_pad_quarter": (np.array([0.2, -0.1, 3.0]), rot_z(0.3)),
        "nadir_1.6m_pad_fills": (np.array([0.0, 0.0, 1.6]), rot_z(0.3)),
        "tilted_to_horizon": (np.array([6.0, 0.0, 3.0]), tilt),
    }
    return {k: camera_pose_W(p, R, mount) for k, (p, R) in cases.items()}


def bench_render(repeats: int = 300) -> dict[str, float]:
    """Median and best time per frame (ms) for a few representative poses, the mean of the medians,
    and the frame rate it implies. Single-threaded OpenCV, noise off."""
    n_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        cam = PinholeCamera.default_downward()
        ground = make_ground_texture("grass", np.random.default_rng(0))
        r = Renderer(cam, ground, FalangaTag.default(1.5), RenderOptions(noise_sigma_dn=0.0), None)
        platform = (np.array([0.0, 0.0, 1.0]), 0.2)
        out: dict[str, float] = {}
        medians = []
        for name, (p_WC, R_WC) in _poses().items():
            for _ in range(5):  # warm up (numba, caches)
                r.render(p_WC, R_WC, platform)
            ts = np.empty(repeats)
            for i in range(repeats):
                t0 = time.perf_counter()
                r.render(p_WC, R_WC, platform)
                ts[i] = time.perf_counter() - t0
            out[f"{name}_median_ms"] = float(np.median(ts) * 1e3)
            out[f"{name}_best_ms"] = float(ts.min() * 1e3)
            medians.append(out[f"{name}_median_ms"])
        out["mean_of_medians_ms"] = float(np.mean(medians))
        out["frames_per_s"] = 1e3 / out["mean_of_medians_ms"]
        return out
    finally:
        cv2.setNumThreads(n_threads)


if __name__ == "__main__":
    print(json.dumps(bench_render(), indent=1))
