"""Probe for issue 18 item 2: would a homography warp render the deck cheaper than per-pixel rays + remap?

For an undistorted pinhole camera a plane maps to the image by a homography, so the deck texture could be
drawn with one ``cv2.warpPerspective`` (and its hit mask with a second, nearest-neighbour warp of a
constant image) instead of ``Renderer``'s numba kernel over the deck's bounding box (a ray per pixel,
float32, fastmath) and ``cv2.remap``. This script times both on the same frames of an undistorted
752x480 camera (the default falanga2017 camera has k1 = -0.08, k2 = 0.01: the homography does not apply
to it, nor to kim_kaist's omnidirectional camera) and compares the pixels where both paths hit the deck.

Run: ``python benchmarks/deck_homography_probe.py [--repeats 50]``.
"""

# ruff: noqa: B023  (each closure below is timed and called only within the loop iteration defining it)
from __future__ import annotations

import argparse
import json
import math
import os
import time

import cv2
import numpy as np

from alight.cameras.pinhole import PinholeCamera
from alight.pads import FalangaTag
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture


def _poses(n: int, rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray, float]]:
    out = []
    for _ in range(n):
        h = float(rng.uniform(0.8, 8.0))
        tilt = float(rng.uniform(0.0, 0.35))
        az = float(rng.uniform(-math.pi, math.pi))
        # looking down (OpenCV camera: z forward), tilted by `tilt` about an axis at azimuth `az`
        R0 = np.diag([1.0, -1.0, -1.0])
        axis = np.array([math.cos(az), math.sin(az), 0.0]) * tilt
        Rt, _ = cv2.Rodrigues(axis)
        R_WC = Rt @ R0
        p = np.array([*rng.uniform(-0.3, 0.3, 2) * h, h + 0.5])
        out.append((p, R_WC, float(rng.uniform(-math.pi, math.pi))))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=50)
    ap.add_argument("--frames", type=int, default=40)
    a = ap.parse_args()
    cv2.setNumThreads(1)
    f = 400.0
    cam = PinholeCamera(752, 480, np.array([[f, 0, 375.5], [0, f, 239.5], [0, 0, 1.0]]), np.zeros(5))
    rng = np.random.default_rng(1)
    r = Renderer(cam, make_ground_texture("grass", rng), FalangaTag(), RenderOptions(noise_sigma_dn=0.0), rng)
    Kinv = np.linalg.inv(cam.K)
    p_WP = np.array([0.0, 0.0, 0.5])
    t_remap, t_warp, diffs, mask_xor, px = [], [], [], 0, 0
    for p_WC, R_WC, yaw in _poses(a.frames, rng):
        deck = r._deck_maps(p_WC, R_WC, p_WP, yaw)
        if deck is None:
            continue
        (v0, v1, u0, u1), lev, _ = deck
        nr, nc = v1 - v0, u1 - u0
        # the same M the renderer builds, as a pixel -> texel homography over the ROI
        c, s = math.cos(yaw), math.sin(yaw)
        R_WPm = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        p_PC, R_PC = R_WPm.T @ (p_WC - p_WP), R_WPm.T @ R_WC
        h_p = float(p_WC[2] - p_WP[2])
        N = np.array([[-h_p, 0.0, p_PC[0]], [0.0, -h_p, p_PC[1]], [0.0, 0.0, 1.0]])
        Hroi = lev.H @ N @ R_PC @ Kinv @ np.array([[1.0, 0, u0], [0, 1.0, v0], [0, 0, 1.0]])
        ones = np.full(lev.image.shape[:2], 255, np.uint8)

        def remap_path() -> tuple[np.ndarray, np.ndarray]:
            d = r._deck_maps(p_WC, R_WC, p_WP, yaw)
            assert d is not None
            b = r._buf
            out = cv2.remap(
                lev.image,
                b.pmx[: nr * nc].reshape(nr, nc),
                b.pmy[: nr * nc].reshape(nr, nc),
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_REPLICATE,
            )
            return out, b.mask[: nr * nc].reshape(nr, nc).copy()

        def warp_path() -> tuple[np.ndarray, np.ndarray]:
            fl = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
            out = cv2.warpPerspective(lev.image, Hroi, (nc, nr), flags=fl, borderMode=cv2.BORDER_REPLICATE)
            m = cv2.warpPerspective(
                ones,
                Hroi,
                (nc, nr),
                flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=0,
            )
            return out, m

        for fn, acc in ((remap_path, t_remap), (warp_path, t_warp)):
            fn()
            t0 = time.perf_counter()
            for _ in range(a.repeats):
                fn()
            acc.append(1e3 * (time.perf_counter() - t0) / a.repeats)
        (ia, ma), (ib, mb) = remap_path(), warp_path()
        both = (ma > 0) & (mb > 0)
        diffs.append(np.abs(ia.astype(np.int16) - ib.astype(np.int16))[both])
        mask_xor += int(np.count_nonzero((ma > 0) != (mb > 0)))
        px += int(np.count_nonzero(ma > 0))
    # the ground, at half resolution (nearest texel, wrapped tile), on views whose every ray hits the
    # ground within the haze range (no sky, no haze): the only case a plain warp covers
    from alight.sim.render import _ground_maps

    g_remap, g_warp, g_diff, g_px = [], [], 0, 0
    H2, W2 = r._half_shape
    b = r._buf
    for p_WC, R_WC, _ in _poses(a.frames, rng):
        h = float(p_WC[2])
        dz = min(float(R_WC[2, 2]), -0.05)
        foot = min(h / -dz, 300.0) * 2.0 * r._pixel_angle / math.sqrt(-dz)
        lev = r._level(r._glevels, foot)
        n = lev.image.shape[1] - 1
        tile_m = r._glevels[0].texel_m * (r._glevels[0].image.shape[0] - 7)
        px_, py_ = math.fmod(float(p_WC[0]), tile_m), math.fmod(float(p_WC[1]), tile_m)
        N = np.array([[-h, 0.0, px_], [0.0, -h, py_], [0.0, 0.0, 1.0]])
        M = lev.H @ N @ R_WC
        Hh = M @ Kinv @ np.diag([2.0, 2.0, 1.0])
        tile = np.ascontiguousarray(lev.image[:n, :n])
        M32 = M.astype(np.float32).ravel()
        min_den = np.float32(h / 300.0)

        def ground_remap() -> np.ndarray:
            _ground_maps(r._hx, r._hy, r._hz, M32, min_den, n, b.gmx, b.gmy)
            return cv2.remap(
                lev.image,
                b.gmx.reshape(H2, W2),
                b.gmy.reshape(H2, W2),
                cv2.INTER_NEAREST,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=0,
            )

        def ground_warp() -> np.ndarray:
            return cv2.warpPerspective(
                tile, Hh, (W2, H2), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_WRAP
            )

        for fn, acc in ((ground_remap, g_remap), (ground_warp, g_warp)):
            fn()
            t0 = time.perf_counter()
            for _ in range(a.repeats):
                fn()
            acc.append(1e3 * (time.perf_counter() - t0) / a.repeats)
        ga, gb = ground_remap(), ground_warp()
        g_diff += int(np.count_nonzero(ga != gb))
        g_px += ga.size
    d = np.concatenate(diffs)
    print(
        json.dumps(
            {
                "frames": len(t_remap),
                "deck_remap_ms_median": round(float(np.median(t_remap)), 3),
                "deck_warp_ms_median": round(float(np.median(t_warp)), 3),
                "ratio_warp_over_remap": round(float(np.median(np.array(t_warp) / np.array(t_remap))), 3),
                "abs_diff_mean_dn": round(float(d.mean()), 4),
                "abs_diff_max_dn": int(d.max()),
                "pixels_differing_fraction": round(float(np.mean(d > 0)), 5),
                "mask_disagreement_fraction": round(mask_xor / max(px, 1), 5),
                "ground_half_remap_ms_median": round(float(np.median(g_remap)), 3),
                "ground_half_warp_ms_median": round(float(np.median(g_warp)), 3),
                "ground_ratio_warp_over_remap": round(
                    float(np.median(np.array(g_warp) / np.array(g_remap))), 3
                ),
                "ground_pixels_differing_fraction": round(g_diff / max(g_px, 1), 5),
                "load1": os.getloadavg()[0],
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
