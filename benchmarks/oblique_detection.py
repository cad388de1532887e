"""How often the SDU landing marker is found when the camera looks at the ground obliquely.

A vehicle holding its position in a strong side wind leans into it, and its body-fixed downward camera
then sees the pad smaller and foreshortened. This renders frames from a height (default 12 m, the
exploration altitude) with the camera tilted by 0-40 deg about a random horizontal axis, the pad placed
within 3 m of where the optical axis meets the deck and wholly in view, on grass, asphalt and concrete
in turn, and runs paper 004's detector through ``QosDetector`` at several (image scale, kernel cap)
settings. A frame counts as found when the reported tip is within a quarter of the pad's side in pixels
of the projected pad centre (what the search needs: a fix to start tracking from).

    python benchmarks/oblique_detection.py [--height 12] [--frames 40] [--seed 1]

It backs ``EXPLORE_SETTING`` and ``OBLIQUE_SEARCH_SETTING`` in ``alight.energy.qos``.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.energy.qos import QosSetting
from alight.pads.sdu_pad import SduPad
from alight.perception.qos_detector import QosDetector
from alight.perception.sdu_marker import SduMarkerDetector
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import rot_z

DECK_Z = 0.5
SETTINGS = ((0.5, 21), (0.75, 21), (0.75, 29), (1.0, 21), (1.0, 41))
TILTS_DEG = (0, 15, 25, 30, 35, 40)


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def detection_rates(height_m: float, n_frames: int, seed: int) -> dict[int, dict[tuple[float, int], float]]:
    """Fraction of frames found, per tilt (deg) and per (image scale, kernel cap)."""
    rng = np.random.default_rng(seed)
    cam, mount, pad = PinholeCamera.default_downward(), CameraMount.downward(), SduPad.default()
    opts = RenderOptions(noise_sigma_dn=2.0)
    renderers = [
        Renderer(cam, make_ground_texture(g, rng, size_px=512), pad, opts, rng)
        for g in ("grass", "asphalt", "concrete")
    ]
    inner = SduMarkerDetector(pad, camera=cam)
    dets = {s: QosDetector(inner, QosSetting(30.0, s[0], s[1]), throttle=False) for s in SETTINGS}
    corners_P = np.vstack([np.zeros(3), pad.quad_corners_P()])
    out: dict[int, dict[tuple[float, int], float]] = {}
    for tilt_deg in TILTS_DEG:
        hits = dict.fromkeys(SETTINGS, 0)
        n = 0
        while n < n_frames:
            heading = rng.uniform(-math.pi, math.pi)
            axis = np.array([math.cos(heading), math.sin(heading), 0.0])
            R_WB = _axis_angle(axis, math.radians(tilt_deg)) @ rot_z(rng.uniform(-math.pi, math.pi))
            p_WC, R_WC = camera_pose_W(np.array([0.0, 0.0, height_m + DECK_Z]), R_WB, mount)
            z_C = R_WC[:, 2]
            hit = p_WC + (-(p_WC[2] - DECK_Z) / z_C[2]) * z_C
            p_WP = np.array([hit[0] + rng.uniform(-3, 3), hit[1] + rng.uniform(-3, 3), DECK_Z])
            yaw_P = rng.uniform(-math.pi, math.pi)
            pts_C = (R_WC.T @ ((rot_z(yaw_P) @ corners_P.T).T + p_WP - p_WC).T).T
            px = cam.project(pts_C)
            inside = np.isfinite(px).all() and (px[:, 0] > 2).all() and (px[:, 1] > 2).all()
            if not (inside and (px[:, 0] < cam.width - 3).all() and (px[:, 1] < cam.height - 3).all()):
                continue
            image = renderers[n % len(renderers)].render(p_WC, R_WC, (p_WP, yaw_P))
            n += 1
            side_px = float(cam.K[0, 0]) * pad.size_m / float(pts_C[0, 2])
            for s, det in dets.items():
                obs = det.detect(image, float(n))
                if obs and float(np.hypot(*(obs[0].pixels[0] - px[0]))) <= 0.25 * side_px:
                    hits[s] += 1
        out[tilt_deg] = {s: hits[s] / n for s in SETTINGS}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--height", type=float, default=12.0, help="camera height above the deck (m)")
    ap.add_argument("--frames", type=int, default=40, help="frames per tilt")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rates = detection_rates(a.height, a.frames, a.seed)
    print(f"found / frames, {a.frames} frames per tilt, {a.height:g} m; columns: image scale / kernel cap")
    print("| tilt | " + " | ".join(f"{s} / {k}" for s, k in SETTINGS) + " |")
    print("|---" * (len(SETTINGS) + 1) + "|")
    for tilt, row in rates.items():
        print(f"| {tilt} deg | " + " | ".join(f"{row[s]:.2f}" for s in SETTINGS) + " |")


if __name__ == "__main__":
    main()
