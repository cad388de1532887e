"""Detector of the cross-and-ring landing tag of paper 000 (Falanga et al. 2017, Sec. II-B, Alg. 1).

Alg. 1 of the paper, step by step, and how each step is done here (numbers measured on the rendered
752x480 frames of ``benchmarks/bench_detectors.py``):

1. ``binary image <- black and white(camera image)``. An adaptive threshold on a box-downscaled copy
   (integer factor so that the long side is <= ``search_max_side_px``; 752x480 -> 376x240): a pixel is
   white when it is brighter than the mean of its neighbourhood (a window of ~15 % of the short side)
   plus an offset of 20 % of the image's brightness range (2nd to 98th percentile, so the offset scales
   with the exposure), and brighter than the median of the image plus that offset (a floor, capped below
   the 98th percentile for a pad that fills the view).
   *Why adaptive and not Otsu*: one global threshold moves with everything in the view (a bright patch
   of ground, the sky, the vehicle's shadow), while a local comparison only asks "is the pad brighter than
   what surrounds it", which survives exposure and gain changes, vignetting and shadows larger than the
   window (a pad entirely in a shadow of gain 0.65, or a shadow inside the pad, are in the tests).
   *Why ``mean + offset`` and not ``mean - offset``*: uniform regions (plain asphalt, the middle of a
   large white square) then turn black instead of becoming large white blobs; the pad's border stays
   white because the darker ground around it pulls the local mean down, and only the *outer* outline of
   the white region is used. *Why the floor*: bright ground beside a dark platform deck is brighter than
   *its* neighbourhood too, and would join the pad's outline. *Known limit*: a hard shadow edge across
   the pad's border cuts the white outline, so the quad (and Alg. 1) fails on such frames.
   The local means come from 4x4-tile sums and a prefix-sum box over the tile grid, fused in one numba
   kernel with the run extraction and labelling (step 2): ~0.1-0.3 ms.
2. ``polygons <- detect polygons(binary image)``. White runs are labelled into 8-connected components
   (union-find on runs) with their bounding boxes. A textured ground gives thousands of specks, and
   tracing each with ``cv2.findContours`` would cost ~4 us of Python apiece, so components are scored
   first (numba, from their row extents): *solidity* (area / convex-hull area) and *quadness* (largest
   quadrangle on the hull / hull area: ~1 for a quad, 2/pi for an ellipse). Components that look like
   clean quadrangles go on with the corners of that largest inscribed quadrangle; the others, a pad with a
   speck of ground clinging to it for instance, are traced (``cv2.findContours``) and fitted with
   ``cv2.approxPolyDP`` (2 %, then the lines of the 4 longest sides of that polygon, then 3.5 %).
3. ``landing tag <- largest quadrangle(polygons)``. Convex 4-gons with no degenerate side or angle that
   do not touch the image border, clean ones first, largest first. The corners are refined at full
   resolution: along every side, the pad-to-ground step is searched on the normal at up to 16 places
   (sub-pixel), a line is fitted to each side (total least squares, one outlier-rejection pass) and
   adjacent lines are intersected. A quad is accepted as *the tag* only if the image sampled through the
   homography of the quad at ~150 points of known colour (black ring/cross, white backdrop, each at least
   3 % of the side from any edge) correlates with the tag's pattern (Pearson r >= ``min_pattern_corr``);
   otherwise the next quad is tried (up to ``max_candidates``). This check keeps the white squares that
   are not the tag (paper sheets, AprilTag borders, ChArUco squares: r <= 0.45 on the real photos) out.
4. ``circle <- detect circle in(landing tag)``. 2D-3D correspondences on a circle under perspective come
   from the homography, not from an ellipse fit: a homography maps lines to lines, so the image of the
   pad's radial line at angle theta is the line through the images of two points of that radial line,
   and the ring edge found on that image line *is* the image of the model point at theta. (An ellipse fit
   has no such point-to-point match: the centre of the imaged ellipse is not the image of the circle's
   centre, and its parametric angle is not theta.) So for ``n_ring_rays`` angles the outer edge (black to
   white going outward) and the inner edge (white to black) are searched on those lines at full
   resolution, a homography is fitted to the ring points by RANSAC, and the search is repeated once, narrower,
   from that homography. The circle is detected when at least ``min_ring_fraction`` of the 2 n rays are
   RANSAC inliers (the paper's "entirely visible", relaxed to "mostly": with 20 % of the ring hidden the
   ring's 50 points still give a better pose than the cross's 12).
5. ``cross <- detect cross in(landing tag)``. The 4 inner and 8 outer corners of the cross predicted by the
   quad's homography and refined by ``cv2.cornerSubPix``; RANSAC homography over the 12; detected when the
   4 inner corners and at least 8 in all are inliers.
6. Else the 4 refined corners of the quad.
7. *Our extension, not in the paper*: when no quad is accepted, the cross alone
   (:mod:`alight.perception.falanga_close`, kinds ``cross`` and ``cross_close``), because the white square
   leaves the downward camera's view below ~1.5 m above the pad and Alg. 1 would go blind for the last
   part of the landing. Off with ``close_range=False``.

RANSAC (step 4, 5) is :func:`alight.numerics.homography.ransac_homography` (numba): 4-point minimal
samples from a fixed-seed xorshift generator (a detection stays a pure function of the image), adaptive
iteration count for 99.5 % confidence, then a least-squares refit (normalised DLT) on the inliers.

The result is one :class:`alight.types.Observation` (kind ``circle``, ``cross`` or ``quad``) with the image
points, their points in P (z = 0) for PnP, and a quality in [0, 1]: the pattern correlation times the
inlier fraction of the chosen feature. The tag is symmetric under rotations by 90 deg, so the pad's yaw
is only defined modulo pi/2; the quad's corners are labelled so that the (+x, +y) corner is the one
nearest the image's top-left, which is the right label for a camera with the image top toward the pad's
front (+x). The paper reports 12 ms per 752x480 frame on an Odroid XU4 (Table I); this runs in under 1 ms
on one desktop core (``benchmarks/bench_detectors.py``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

from alight.numerics.histogram import histogram_quantile
from alight.numerics.homography import apply_homography, homography_4pt, ransac_homography
from alight.numerics.image import bilinear
from alight.numerics.runs import link_run, run_roots
from alight.pads.falanga_tag import FalangaTag
from alight.perception.falanga_close import CloseRangeCrossDetector
from alight.perception.image_input import as_gray_u8, check_time
from alight.types import FloatArray, Image, Observation, U8Array

STAGES = ("threshold", "contours", "quad", "inner", "ransac")
"""Keys of the stage-time table of :meth:`FalangaTagDetector.detect_timed` (plus ``total``)."""


@dataclass(frozen=True, kw_only=True)
class FalangaDetectorConfig:
    """Parameters of :class:`FalangaTagDetector` (pixel values are full-resolution pixels unless named
    otherwise, grey levels are 8-bit)."""

    search_max_side_px: int = 400
    """The quad search runs on the image box-downscaled by the smallest integer factor that brings its
    long side to at most this (752x480 -> 376x240)."""
    threshold_window_frac: float = 0.15
    """Side of the adaptive-threshold window as a fraction of the downscaled image's short side."""
    threshold_offset_frac: float = 0.2
    """A pixel is white when brighter than its neighbourhood mean plus this fraction of the image's
    brightness range (2nd to 98th percentile of the downscaled image), so that the threshold scales
    with the exposure."""
    threshold_offset_min: float = 4.0
    """Least offset (grey levels), for nearly uniform images."""
    threshold_floor: bool = True
    """Also require white pixels to be brighter than the image's median plus the offset (capped at the
    98th percentile minus the offset)."""
    min_quad_side_px: float = 24.0
    """Shortest side of a candidate quad (px); the pattern is not resolvable below ~24 px."""
    max_candidates: int = 6
    """How many of the largest quads are checked against the tag's pattern, largest first."""
    max_traced: int = 16
    """How many of the largest convex components are traced and fitted with a quad at most."""
    min_solidity: float = 0.7
    """Least solidity of a component's row extents for it to be traced (see ``_solidity``)."""
    min_quadness: float = 0.72
    """Least quadness of a component's hull for it to be traced (~1 for a quad, 0.64 for an ellipse;
    a speck of ground clinging to the pad lowers it)."""
    min_pattern_corr: float = 0.7
    """Least correlation between the image inside the quad and the tag's pattern."""
    n_ring_rays: int = 32
    """Rays per ring edge (outer and inner), so up to 2 n correspondences for a circle."""
    min_ring_fraction: float = 0.8
    """Fraction of the 2 n ring rays that must be RANSAC inliers for the circle to count as visible."""
    ransac_threshold_px: float = 1.5
    """RANSAC inlier threshold (px); grown to 1 % of the quad's diagonal for large quads (lens distortion
    bends a large quad away from a single homography)."""
    min_edge_step: float = 6.0
    """Least brightness step across an edge (grey levels) for an edge search to count."""
    min_feature_px: float = 2.5
    """The ring (cross) is searched only when its width (bar width) is at least this in the image (px)."""
    close_range: bool = True
    """When no tag quad is found, look for the cross alone (:mod:`alight.perception.falanga_close`, our
    extension of Alg. 1 for the last ~1.5 m of a landing, where the white square no longer fits in the
    view). False gives the paper's Alg. 1 only."""
    close_range_max_range_m: float = 5.0
    """The close-range stage is skipped while the range finder reads more than this (m), when the
    pipeline passes the reading (:meth:`FalangaTagDetector.set_range`): the stage is for a camera below
    ~1.6 m above the pad, and 5 m leaves room for a deck up to 2.5 m high beside the beam and a 30 deg
    tilt. It would cost ~0.4 ms on every frame of a search at 12 m. Without a reading (none passed,
    or an invalid one) the stage runs whenever Alg. 1 finds no quad."""

    def __post_init__(self) -> None:
        checks = {
            "search_max_side_px": self.search_max_side_px >= 32,
            "threshold_window_frac": 0.0 < self.threshold_window_frac <= 1.0,
            "threshold_offset_frac": 0.0 <= self.threshold_offset_frac < 1.0,
            "threshold_offset_min": math.isfinite(self.threshold_offset_min)
            and self.threshold_offset_min >= 0,
            "min_quad_side_px": self.min_quad_side_px >= 8,
            "max_candidates": self.max_candidates >= 1,
            "max_traced": self.max_traced >= 1,
            "min_solidity": 0.0 <= self.min_solidity <= 1.0,
            "min_quadness": 0.0 <= self.min_quadness <= 1.0,
            "min_pattern_corr": -1.0 <= self.min_pattern_corr <= 1.0,
            "n_ring_rays": self.n_ring_rays >= 8,
            "min_ring_fraction": 0.0 < self.min_ring_fraction <= 1.0,
            "ransac_threshold_px": self.ransac_threshold_px > 0,
            "min_edge_step": self.min_edge_step >= 0,
            "min_feature_px": self.min_feature_px > 0,
            "close_range_max_range_m": self.close_range_max_range_m > 0,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"invalid FalangaDetectorConfig values: {bad}")


# --------------------------------------------------------------------------------------------------
# numba kernels: threshold + components
# --------------------------------------------------------------------------------------------------

_TILE = 4
"""Side of the tiles (downscaled pixels) whose means make the adaptive threshold's local mean. A module
constant, so that numba compiles the tile arithmetic to shifts."""


@numba.njit(cache=True)
def _threshold_runs(img, radius_tiles, offset_frac, offset_min, use_floor):  # pragma: no cover - numba
    """Adaptive threshold and 8-connected labelling of the white runs.

    White: ``img > mean(window) + offset``, the window being (2 radius_tiles + 1)^2 tiles of
    ``_TILE x _TILE`` pixels around the pixel's tile (clipped at the image border), and ``offset =
    max(offset_min, offset_frac (p98 - p2))`` from the image's 2nd and 98th brightness percentiles. Returns
    ``(n_runs, row, x0, x1, root, bx0, bx1, by0, by1)``: run k spans columns x0[k]..x1[k] of row[k];
    ``root[k]`` is the run that represents k's component, where the bounding box arrays are valid.

    One kernel: the tile sums, the brightness percentiles, the tile threshold ``T`` and the labelling of the
    runs against it work on the same frame, per camera frame on the detector's hot path; the union-find
    is already apart (``link_run``, ``run_roots``). ``T`` is the seam if it is ever split; it is kept whole so
    as not to add a compiled kernel (compile/kernels.json, the warm-up) for no speed or clarity gain.
    """
    h, w = img.shape
    th = (h + _TILE - 1) // _TILE
    tw = (w + _TILE - 1) // _TILE
    tw_full = w // _TILE
    P = np.zeros((th + 1, tw + 1), np.float64)
    Cn = np.zeros((th + 1, tw + 1), np.float64)
    rowsum = np.zeros(tw, np.int64)
    hist = np.zeros(256, np.int64)
    for ti in range(th):
        rowsum[:] = 0
        for i in range(ti * _TILE, min(h, ti * _TILE + _TILE)):
            r = img[i]
            if (i & 3) == 0:  # a 4x4 subsample is plenty for three percentiles
                for j in range(0, w, 4):
                    hist[r[j]] += 1
            for tj in range(tw_full):
                j = tj * _TILE
                rowsum[tj] += np.int64(r[j]) + r[j + 1] + r[j + 2] + r[j + 3]
            for j in range(tw_full * _TILE, w):
                rowsum[tw - 1] += r[j]
        for tj in range(tw):
            c = min(_TILE, h - ti * _TILE) * min(_TILE, w - tj * _TILE)
            P[ti + 1, tj + 1] = rowsum[tj] + P[ti, tj + 1] + P[ti + 1, tj] - P[ti, tj]
            Cn[ti + 1, tj + 1] = c + Cn[ti, tj + 1] + Cn[ti + 1, tj] - Cn[ti, tj]
    total = hist.sum()
    p2 = histogram_quantile(hist, total, 0.02)
    p50 = histogram_quantile(hist, total, 0.5)
    p98 = histogram_quantile(hist, total, 0.98)
    offset = max(offset_min, offset_frac * (p98 - p2))
    # a floor under the local threshold: brighter than the median scene by the offset (capped below the
    # brightest pixels, for a pad that fills most of the view); it keeps bright ground beside a dark
    # deck, which is brighter than *its* neighbourhood, from joining the pad
    floor_t = min(p50 + offset, p98 - offset) if use_floor else -1.0
    T = np.empty((th, tw), np.int32)
    for ti in range(th):
        a0 = max(0, ti - radius_tiles)
        a1 = min(th, ti + radius_tiles + 1)
        for tj in range(tw):
            b0 = max(0, tj - radius_tiles)
            b1 = min(tw, tj + radius_tiles + 1)
            s = P[a1, b1] - P[a0, b1] - P[a1, b0] + P[a0, b0]
            c = Cn[a1, b1] - Cn[a0, b1] - Cn[a1, b0] + Cn[a0, b0]
            T[ti, tj] = int(np.floor(max(s / c + offset, floor_t)))  # integer pixels: v > x <=> v > floor(x)
    thr = np.empty(w, np.int32)
    w8 = (w + 1 + 7) // 8 * 8
    wb = np.zeros(w8 + 1, np.uint8)
    dwb = np.zeros(w8, np.uint8)
    dwb64 = dwb.view(np.uint64)
    trans = np.empty(w + 2, np.int32)
    cap = h * ((w + 1) // 2) + 1
    row = np.empty(cap, np.int32)
    x0 = np.empty(cap, np.int32)
    x1 = np.empty(cap, np.int32)
    parent = np.empty(cap, np.int32)
    # int64 zeros, not literal ones: typed as Literal[int](0) before the loop unifies them, they would
    # make numba compile link_run and run_roots once more for that literal type
    n = np.int64(0)
    prev_start = np.int64(0)
    prev_end = np.int64(0)
    for i in range(h):
        if (i % _TILE) == 0:
            trow = T[i // _TILE]
            for j in range(w):
                thr[j] = trow[j // _TILE]
        # run extraction: white flags with a 0 sentinel on either side, their changes, and the positions
        # of the changes read 8 at a time (a noisy threshold boundary defeats branch prediction)
        r = img[i]
        cur_start = n
        for j in range(w):
            wb[j + 1] = 1 if r[j] > thr[j] else 0
        for j in range(w + 1):
            dwb[j] = wb[j] ^ wb[j + 1]
        cnt = 0
        for q in range(dwb64.shape[0]):  # skip 8 unchanged pixels at a time
            if dwb64[q] != 0:
                for j in range(8 * q, 8 * q + 8):
                    if dwb[j]:
                        trans[cnt] = j
                        cnt += 1
        for t in range(0, cnt, 2):
            row[n] = i
            x0[n] = trans[t]
            x1[n] = trans[t + 1] - 1
            parent[n] = n
            n += 1
        # union with the runs of the previous row that touch this one (8-connectivity)
        p = prev_start
        for k in range(cur_start, n):
            p = link_run(parent, x0, x1, k, p, prev_end)
        prev_start = cur_start
        prev_end = n
    root = run_roots(parent, n)
    bx0 = np.empty(n, np.int32)
    bx1 = np.empty(n, np.int32)
    by0 = np.empty(n, np.int32)
    by1 = np.empty(n, np.int32)
    for k in range(n):
        r0 = root[k]
        if r0 == k:
            bx0[k] = x0[k]
            bx1[k] = x1[k]
            by0[k] = row[k]
            by1[k] = row[k]
        else:
            if x0[k] < bx0[r0]:
                bx0[r0] = x0[k]
            if x1[k] > bx1[r0]:
                bx1[r0] = x1[k]
            by1[r0] = row[k]  # runs come in row order
    return n, row[:n].copy(), x0[:n].copy(), x1[:n].copy(), root, bx0, bx1, by0, by1


@numba.njit(cache=True)
def _solidity(row, x0, x1, root, cands, by0, by1):  # pragma: no cover - numba
    """Shape scores of candidate components (root run indices), from their row extents (leftmost and
    rightmost pixel of each row), which are the same for a filled quadrangle and for the hollow band the
    threshold leaves along the border of a large one:

    - solidity: the area between the extents over the area of their convex hull (a convex shape ~1, the
      ragged blobs of a textured ground less; 0 for a component with an empty row);
    - hull area (px^2);
    - quadness: the largest quadrangle on the hull's vertices over the hull's area (~1 for a quadrangle,
      2/pi for an ellipse);
    - that quadrangle's corners, shape (nc, 4, 2), (x, y) in pixels.

    One kernel: per candidate, the row extents, their monotone-chain hull (in buffers reused across
    candidates), its area and the largest quadrangle (``_max_quad``, apart) are one loop; the hull is the seam
    if it is ever split, kept inline so as not to add a compiled kernel (compile/kernels.json, the warm-up) on
    the detector's per-frame path.
    """
    nc = cands.shape[0]
    slot = np.full(row.shape[0], -1, np.int32)
    off = np.zeros(nc + 1, np.int64)
    for c in range(nc):
        slot[cands[c]] = c
        off[c + 1] = off[c] + by1[cands[c]] - by0[cands[c]] + 1
    L = np.full(off[nc], 1 << 30, np.int32)
    R = np.full(off[nc], -1, np.int32)
    for k in range(row.shape[0]):
        c = slot[root[k]]
        if c >= 0:
            idx = off[c] + row[k] - by0[cands[c]]
            if x0[k] < L[idx]:
                L[idx] = x0[k]
            if x1[k] > R[idx]:
                R[idx] = x1[k]
    sol = np.zeros(nc)
    hull_area = np.zeros(nc)
    quadness = np.zeros(nc)
    corners = np.zeros((nc, 4, 2))
    hx = np.empty(0)
    hy = np.empty(0)
    for c in range(nc):
        m = off[c + 1] - off[c]
        span = 0.0
        gap = False
        for t in range(m):
            if R[off[c] + t] < 0:
                gap = True
                break
            span += R[off[c] + t] - L[off[c] + t] + 1
        if gap:
            continue
        # the points (y, L) and (y, R) come sorted by (y, x): Andrew's monotone chain with y as the
        # primary coordinate; each row's extent is widened by half a pixel on either side
        npt = 2 * m
        if hx.shape[0] < 2 * npt + 2:
            hx = np.empty(2 * npt + 2)
            hy = np.empty(2 * npt + 2)
        k = 0
        for ii in range(npt):
            t = ii // 2
            py = float(by0[cands[c]] + t)
            px = L[off[c] + t] - 0.5 if ii % 2 == 0 else R[off[c] + t] + 0.5
            while (
                k >= 2
                and (hy[k - 1] - hy[k - 2]) * (px - hx[k - 2]) - (hx[k - 1] - hx[k - 2]) * (py - hy[k - 2])
                <= 0
            ):
                k -= 1
            hx[k] = px
            hy[k] = py
            k += 1
        lo = k + 1
        for ii in range(npt - 2, -1, -1):
            t = ii // 2
            py = float(by0[cands[c]] + t)
            px = L[off[c] + t] - 0.5 if ii % 2 == 0 else R[off[c] + t] + 0.5
            while (
                k >= lo
                and (hy[k - 1] - hy[k - 2]) * (px - hx[k - 2]) - (hx[k - 1] - hx[k - 2]) * (py - hy[k - 2])
                <= 0
            ):
                k -= 1
            hx[k] = px
            hy[k] = py
            k += 1
        a = 0.0
        for i in range(k - 1):
            a += hx[i] * hy[i + 1] - hx[i + 1] * hy[i]
        a = abs(a) * 0.5
        # the hull through row centres misses half a row at the top and bottom
        a_full = a + 0.5 * (R[off[c]] - L[off[c]] + 1) + 0.5 * (R[off[c] + m - 1] - L[off[c] + m - 1] + 1)
        hull_area[c] = a_full
        if a_full > 0:
            sol[c] = span / a_full
        if a > 0 and k - 1 >= 4:
            qa, qc = _max_quad(hx[: k - 1], hy[: k - 1])
            quadness[c] = qa / a
            for r in range(4):  # by element: numba compiles a slice assignment's error message (~1 s)
                corners[c, r, 0] = qc[r, 0]
                corners[c, r, 1] = qc[r, 1]
    return sol, hull_area, quadness, corners


@numba.njit(cache=True)
def _tri2(x, y, i, j, k):  # pragma: no cover - numba
    return abs((x[j] - x[i]) * (y[k] - y[i]) - (y[j] - y[i]) * (x[k] - x[i]))


@numba.njit(cache=True)
def _max_quad(x_in, y_in):  # pragma: no cover - numba
    """The largest quadrangle with its corners on the vertices of a convex polygon (vertices in order):
    for each diagonal (i, k) the farthest vertex on either side, with pointers that only move forward,
    O(h^2). Polygons with more than 48 vertices are decimated first (the area is then a slight
    underestimate). Returns (area, corners (4, 2) in polygon order)."""
    h0 = x_in.shape[0]
    step = (h0 + 47) // 48
    h = (h0 + step - 1) // step
    x = np.empty(2 * h)
    y = np.empty(2 * h)
    for t in range(h):
        x[t] = x_in[t * step]
        y[t] = y_in[t * step]
        x[t + h] = x[t]
        y[t + h] = y[t]
    best = 0.0
    bi = bj = bk = bq = 0
    for i in range(h):
        j = i + 1
        q = i + 3
        for k in range(i + 2, i + h - 1):
            if j >= k:
                j = k - 1
            while j + 1 < k and _tri2(x, y, i, j + 1, k) >= _tri2(x, y, i, j, k):
                j += 1
            if q <= k:
                q = k + 1
            while q + 1 < i + h and _tri2(x, y, k, q + 1, i) >= _tri2(x, y, k, q, i):
                q += 1
            a = _tri2(x, y, i, j, k) + _tri2(x, y, k, q, i)
            if a > best:
                best = a
                bi, bj, bk, bq = i, j, k, q
    corners = np.empty((4, 2))
    for r, v in enumerate((bi, bj, bk, bq)):
        corners[r, 0] = x[v]
        corners[r, 1] = y[v]
    return 0.5 * best, corners


@numba.njit(cache=True)
def _paint(row, x0, x1, root, r, oy, ox, hh, ww):  # pragma: no cover - numba
    """Mask (hh, ww) of the component ``r``, offset by (oy, ox)."""
    m = np.zeros((hh, ww), np.uint8)
    for k in range(row.shape[0]):
        if root[k] == r:
            i = row[k] - oy
            for j in range(x0[k] - ox, x1[k] - ox + 1):
                m[i, j] = 255
    return m


# --------------------------------------------------------------------------------------------------
# numba kernels: sampling, edges, homographies
# --------------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _edge1(img, x, y, dx, dy, L, pol, min_step):  # pragma: no cover - numba
    """Strongest step edge of polarity ``pol`` (+1: brightness increasing along (dx, dy), -1 decreasing)
    on the segment ``(x, y) + s (dx, dy)``, ``|s| <= L`` (px).

    The profile is sampled every 0.5 px (bilinear); its derivative over +-1 px, weighted by a prior on
    the offset from ``(x, y)``, is maximised, refined to sub-pixel by a parabola through the
    peak, and accepted when the brightness changes by at least ``min_step`` across +-1.5 px of it.
    Returns (ok, ex, ey).
    """
    h, w = img.shape
    ns = int(4.0 * L) + 1
    nt = ns + 6  # 1.5 px more on either side for the derivative and the step check
    sx = x - (L + 1.5) * dx
    sy = y - (L + 1.5) * dy
    ex = sx + (nt - 1) * 0.5 * dx
    ey = sy + (nt - 1) * 0.5 * dy
    if not (
        min(sx, ex) >= 0
        and min(sy, ey) >= 0
        and max(sx, ex) <= w - 1
        and max(sy, ey) <= h - 1
        and w > 1
        and h > 1
    ):
        return False, np.nan, np.nan
    prof = np.empty(nt)
    for i in range(nt):
        prof[i] = bilinear(img, sx + i * 0.5 * dx, sy + i * 0.5 * dy)
    # the derivative weighted by a prior on the offset (1 - (s / 1.5 L)^2, 0.56 at the ends), so that a
    # stronger edge near the end of the range (the ring just inside the pad's border) loses to the one
    # predicted
    best_w = 0.0
    bi = -1
    inv_w2 = 1.0 / (1.5 * L) ** 2
    for i in range(3, 3 + ns):
        d = pol * (prof[i + 2] - prof[i - 2]) * 0.5
        off_s = (i - 3) * 0.5 - L
        dw = d * (1.0 - off_s * off_s * inv_w2)
        if dw > best_w:
            best_w = dw
            bi = i
    if bi < 0:
        return False, np.nan, np.nan
    # the prior only chooses the edge: climb to the local maximum of the unweighted derivative before
    # the sub-pixel fit, or the slope of the weight would bias the position toward (x, y)
    while bi > 3 and pol * (prof[bi + 1] - prof[bi - 3]) > pol * (prof[bi + 2] - prof[bi - 2]):
        bi -= 1
    while bi < 2 + ns and pol * (prof[bi + 3] - prof[bi - 1]) > pol * (prof[bi + 2] - prof[bi - 2]):
        bi += 1
    if bi <= 3 or bi >= 2 + ns:
        return False, np.nan, np.nan
    best = pol * (prof[bi + 2] - prof[bi - 2]) * 0.5
    if pol * (prof[bi + 3] - prof[bi - 3]) < min_step:
        return False, np.nan, np.nan
    dm = pol * (prof[bi + 1] - prof[bi - 3]) * 0.5
    dp = pol * (prof[bi + 3] - prof[bi - 1]) * 0.5
    den = dm - 2.0 * best + dp
    off = 0.0
    if den < 0:
        off = min(0.5, max(-0.5, 0.5 * (dm - dp) / den))
    s = (bi + off) * 0.5
    return True, sx + s * dx, sy + s * dy


@numba.njit(cache=True)
def _median_small(a, n):  # pragma: no cover - numba
    """Median of ``a[:n]`` (n >= 1) as ``np.median`` gives it (the middle value, or the mean of the two
    middle ones), by insertion sort of a copy: n is at most 16 here, and numba's ``np.median`` (a
    quickselect) takes ~0.8 s to compile against ~0.1 s for this."""
    s = np.empty(n)
    for k in range(n):
        v = a[k]
        i = k
        while i > 0 and v < s[i - 1]:
            s[i] = s[i - 1]
            i -= 1
        s[i] = v
    h = n >> 1
    if n & 1 == 0:
        return (s[h - 1] + s[h]) / 2
    return s[h]


@numba.njit(cache=True)
def _fit_line(px, py, n):  # pragma: no cover - numba
    """Total-least-squares line through the first n points, refitted once without the points farther
    than max(0.75 px, 2.5 robust sigmas). Returns (ok, cx, cy, dx, dy)."""
    keep = np.ones(n, np.bool_)
    cx = cy = dx = dy = 0.0
    for it in range(2):
        m = 0
        cx = 0.0
        cy = 0.0
        for k in range(n):
            if keep[k]:
                cx += px[k]
                cy += py[k]
                m += 1
        if m < 3:
            return False, 0.0, 0.0, 0.0, 0.0
        cx /= m
        cy /= m
        sxx = syy = sxy = 0.0
        for k in range(n):
            if keep[k]:
                ax = px[k] - cx
                ay = py[k] - cy
                sxx += ax * ax
                syy += ay * ay
                sxy += ax * ay
        ang = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
        dx = np.cos(ang)
        dy = np.sin(ang)
        if it == 1:
            break
        res = np.empty(n)
        for k in range(n):
            res[k] = abs(-(px[k] - cx) * dy + (py[k] - cy) * dx)
        lim = max(0.75, 2.5 * 1.4826 * _median_small(res, n))
        for k in range(n):
            keep[k] = res[k] <= lim
    return True, cx, cy, dx, dy


@numba.njit(cache=True)
def _refine_quad(img, q, half, min_step):  # pragma: no cover - numba
    """Corners (4, 2) refined at full resolution: along each side, the white-pad-to-ground step is
    searched on the outward normal at up to 16 places, a line is fitted per side and adjacent lines are
    intersected (a side without enough edge points keeps its coarse line). Returns (corners, number of
    sides fitted); the input corners when a corner would move by more than 2 half."""
    out = q.copy()
    cxm = 0.25 * (q[0, 0] + q[1, 0] + q[2, 0] + q[3, 0])
    cym = 0.25 * (q[0, 1] + q[1, 1] + q[2, 1] + q[3, 1])
    lines = np.zeros((4, 4))
    px = np.empty(16)
    py = np.empty(16)
    n_ok = 0
    for k in range(4):
        ax, ay = q[k, 0], q[k, 1]
        bx, by = q[(k + 1) % 4, 0], q[(k + 1) % 4, 1]
        length = np.hypot(bx - ax, by - ay)
        if length < 1e-9:
            return out, 0
        dx = (bx - ax) / length
        dy = (by - ay) / length
        nx, ny = -dy, dx
        if nx * (0.5 * (ax + bx) - cxm) + ny * (0.5 * (ay + by) - cym) < 0:
            nx, ny = -nx, -ny
        m = int(min(16.0, max(4.0, length / 4.0)))
        cnt = np.int64(0)  # not a literal 0, which would make numba compile _fit_line for it too
        for i in range(m):
            s = 0.12 + 0.76 * i / (m - 1)
            ok, ex, ey = _edge1(img, ax + s * (bx - ax), ay + s * (by - ay), nx, ny, half, -1.0, min_step)
            if ok:
                px[cnt] = ex
                py[cnt] = ey
                cnt += 1
        ok = cnt >= max(3, m // 2)
        if ok:
            ok, lcx, lcy, ldx, ldy = _fit_line(px, py, cnt)
        if ok:
            lines[k, 0] = lcx
            lines[k, 1] = lcy
            lines[k, 2] = ldx
            lines[k, 3] = ldy
            n_ok += 1
        else:  # keep the coarse side
            lines[k, 0] = ax
            lines[k, 1] = ay
            lines[k, 2] = dx
            lines[k, 3] = dy
    if n_ok == 0:
        return out, 0
    for k in range(4):
        a = lines[(k + 3) % 4]
        b = lines[k]
        det = -a[2] * b[3] + b[2] * a[3]
        if abs(det) < 1e-3:
            return q.copy(), 0
        rx = b[0] - a[0]
        ry = b[1] - a[1]
        s = (-rx * b[3] + b[2] * ry) / det
        cx = a[0] + s * a[2]
        cy = a[1] + s * a[3]
        if np.hypot(cx - q[k, 0], cy - q[k, 1]) > 2.0 * half:
            return q.copy(), 0
        out[k, 0] = cx
        out[k, 1] = cy
    return out, n_ok


@numba.njit(cache=True)
def _pattern_corr(img, H, pat_xy, label):  # pragma: no cover - numba
    """Pearson correlation between the image sampled at the pattern points mapped by H and their labels
    (1 white, 0 black), the white-minus-black mean difference, and the fraction of points inside the
    image. (corr, contrast, frac_in)."""
    h, w = img.shape
    n = pat_xy.shape[0]
    p = apply_homography(H, pat_xy)
    sv = sl = svv = sll = svl = 0.0
    sw = sb = 0.0
    nw = nb = 0
    m = 0
    for k in range(n):
        x, y = p[k, 0], p[k, 1]
        if not (x >= 0 and y >= 0 and x <= w - 1 and y <= h - 1):
            continue
        v = bilinear(img, x, y)
        lab = label[k]
        sv += v
        sl += lab
        svv += v * v
        sll += lab * lab
        svl += v * lab
        m += 1
        if lab > 0.5:
            sw += v
            nw += 1
        else:
            sb += v
            nb += 1
    if m < 3 or nw == 0 or nb == 0:
        return 0.0, 0.0, m / max(n, 1)
    cov = svl / m - (sv / m) * (sl / m)
    var_v = svv / m - (sv / m) ** 2
    var_l = sll / m - (sl / m) ** 2
    if var_v <= 1e-9 or var_l <= 1e-12:
        return 0.0, 0.0, m / n
    return cov / np.sqrt(var_v * var_l), sw / nw - sb / nb, m / n


@numba.njit(cache=True)
def _ring_edges(img, H, ring_xy, ring_out, ring_in, pol, half, min_step):  # pragma: no cover
    """Ring edge points: for each model point, the step of polarity ``pol`` searched along the image of
    the pad's radial line through it (the line through the images of the points just inside and just
    outside the edge). Returns (points (N, 2), ok (N,))."""
    n = ring_xy.shape[0]
    c = apply_homography(H, ring_xy)
    a = apply_homography(H, ring_out)
    b = apply_homography(H, ring_in)
    pts = np.full((n, 2), np.nan)
    ok = np.zeros(n, np.bool_)
    for k in range(n):
        dx = a[k, 0] - b[k, 0]
        dy = a[k, 1] - b[k, 1]
        nrm = np.hypot(dx, dy)
        if not (nrm > 1e-9) or not np.isfinite(c[k, 0]):
            continue
        good, ex, ey = _edge1(img, c[k, 0], c[k, 1], dx / nrm, dy / nrm, half, pol[k], min_step)
        if good:
            ok[k] = True
            pts[k, 0] = ex
            pts[k, 1] = ey
    return pts, ok


@numba.njit(cache=True)
def _ransac_subset(src, dst, ok, thr, max_iters, n_need):  # pragma: no cover
    """RANSAC homography over the pairs with ``ok``; (good, H, inlier mask over all pairs, inlier
    count). ``good`` needs at least ``n_need`` valid pairs and as many inliers."""
    n = src.shape[0]
    sel = np.flatnonzero(ok)
    mask = np.zeros(n, np.bool_)
    if sel.shape[0] < max(4.0, n_need):
        return False, np.eye(3), mask, 0
    s2 = np.empty((sel.shape[0], 2))
    d2 = np.empty((sel.shape[0], 2))
    for k in range(sel.shape[0]):
        s2[k, 0] = src[sel[k], 0]
        s2[k, 1] = src[sel[k], 1]
        d2[k, 0] = dst[sel[k], 0]
        d2[k, 1] = dst[sel[k], 1]
    good, H, m = ransac_homography(s2, d2, thr, max_iters)
    cnt = 0
    for k in range(sel.shape[0]):
        if m[k]:
            mask[sel[k]] = True
            cnt += 1
    return good and cnt >= n_need, H, mask, cnt


@numba.njit(cache=True)
def _quad_stage(img, q_small, f, quad_xy, half, min_step):  # pragma: no cover
    """A candidate quad (downscaled pixels) to full resolution, labelled like the model (negative
    shoelace area in (u, v), the (+x, +y) corner first = the one nearest the image's top-left), refined
    (:func:`_refine_quad`), and its homography from the pad plane. Returns (ok, corners (4, 2), sides
    fitted, H0, mean side (px), diagonal (px))."""
    q = np.empty((4, 2))
    for k in range(4):
        q[k, 0] = (q_small[k, 0] + 0.5) * f - 0.5
        q[k, 1] = (q_small[k, 1] + 0.5) * f - 0.5
    area2 = 0.0
    for k in range(4):
        area2 += q[k, 0] * q[(k + 1) % 4, 1] - q[(k + 1) % 4, 0] * q[k, 1]
    order = np.array([0, 1, 2, 3]) if area2 < 0 else np.array([3, 2, 1, 0])
    k0 = 0
    best = np.inf
    for k in range(4):
        v = q[order[k], 0] + q[order[k], 1]
        if v < best:
            best = v
            k0 = k
    qo = np.empty((4, 2))
    for k in range(4):
        qo[k, 0] = q[order[(k0 + k) % 4], 0]
        qo[k, 1] = q[order[(k0 + k) % 4], 1]
    q_ref, n_sides = _refine_quad(img, qo, half, min_step)
    # int64 indices, not literals: homography_4pt then compiles once, for RANSAC's int64 indices too
    ok, H0 = homography_4pt(quad_xy, q_ref, np.int64(0), np.int64(1), np.int64(2), np.int64(3))
    side = 0.0
    for k in range(4):
        side += np.hypot(q_ref[(k + 1) % 4, 0] - q_ref[k, 0], q_ref[(k + 1) % 4, 1] - q_ref[k, 1])
    diag = np.hypot(q_ref[2, 0] - q_ref[0, 0], q_ref[2, 1] - q_ref[0, 1])
    return ok, q_ref, n_sides, H0, 0.25 * side, diag


@numba.njit(cache=True)
def _quad_shape_ok(q):  # pragma: no cover - numba
    """No side shorter than a fifth of the longest and every corner angle in [32, 148] deg."""
    smin = np.inf
    smax = 0.0
    for k in range(4):
        s = np.hypot(q[(k + 1) % 4, 0] - q[k, 0], q[(k + 1) % 4, 1] - q[k, 1])
        smin = min(smin, s)
        smax = max(smax, s)
    if smin < 0.2 * smax or smin <= 0:
        return False
    for k in range(4):
        ax = q[(k + 3) % 4, 0] - q[k, 0]
        ay = q[(k + 3) % 4, 1] - q[k, 1]
        bx = q[(k + 1) % 4, 0] - q[k, 0]
        by = q[(k + 1) % 4, 1] - q[k, 1]
        c = (ax * bx + ay * by) / (np.hypot(ax, ay) * np.hypot(bx, by))
        if abs(c) > 0.85:
            return False
    return True


# --------------------------------------------------------------------------------------------------
# the detector
# --------------------------------------------------------------------------------------------------


def _pattern_samples(tag: FalangaTag) -> tuple[FloatArray, FloatArray]:
    """Points of known colour on the tag (N, 2) in P (m) and their labels (1 white, 0 black): a 12x12 grid
    over the square, the ring's mid circle and the cross's centre lines, keeping only points at least 3 %
    of the side from every edge (so that a slightly wrong homography does not flip a label)."""
    s = tag.size_m
    g = (np.arange(12) + 0.5) / 12 * s - s / 2
    gx, gy = np.meshgrid(g, g, indexing="ij")
    r_mid = tag.ring_outer_radius_m - tag.ring_width_m / 2
    a = 2 * np.pi * (np.arange(24) + 0.5) / 24
    t = np.linspace(-0.8, 0.8, 9) * tag.cross_arm_half_length_m
    p = np.concatenate(
        [
            np.stack([gx.ravel(), gy.ravel()], axis=1),
            np.stack([r_mid * np.cos(a), r_mid * np.sin(a)], axis=1),
            np.stack([t, np.zeros_like(t)], axis=1),
            np.stack([np.zeros_like(t), t], axis=1),
        ]
    )
    x: FloatArray = p[:, 0]
    y: FloatArray = p[:, 1]
    sd_ring = np.abs(np.hypot(x, y) - r_mid) - tag.ring_width_m / 2
    L, h = tag.cross_arm_half_length_m, tag.cross_bar_width_m / 2

    def sd_box(hx: float, hy: float) -> FloatArray:
        dx = np.abs(x) - hx
        dy = np.abs(y) - hy
        return np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)) + np.minimum(np.maximum(dx, dy), 0)

    sd_black = np.minimum(sd_ring, np.minimum(sd_box(L, h), sd_box(h, L)))
    sd_square = np.maximum(np.abs(x), np.abs(y)) - s / 2
    margin = min(0.03 * s, 0.45 * tag.ring_width_m)
    keep = (np.abs(sd_black) >= margin) & (sd_square <= -margin)
    label = (sd_black > 0).astype(np.float64)
    return np.ascontiguousarray(p[keep]), np.ascontiguousarray(label[keep])


class FalangaTagDetector:
    """Paper 000's tag detector (Alg. 1). ``detect(image, t)`` is a pure function of the image.

    Parameters
    ----------
    tag:
        The tag's geometry (``alight.pads.FalangaTag``); its lengths fix the metric points for PnP.
        Default: ``FalangaTag.default()`` (1.5 m).
    config:
        Thresholds and sizes (:class:`FalangaDetectorConfig`); the defaults suit 752x480 grey frames.
    """

    def __init__(self, tag: FalangaTag | None = None, config: FalangaDetectorConfig | None = None) -> None:
        self.tag = FalangaTag.default() if tag is None else tag
        self.config = FalangaDetectorConfig() if config is None else config
        t = self.tag
        self._quad_P = np.ascontiguousarray(t.quad_corners_P(), dtype=np.float64)
        self._quad_xy = np.ascontiguousarray(self._quad_P[:, :2])
        self._pat_xy, self._pat_label = _pattern_samples(t)
        n = self.config.n_ring_rays
        # half a step off the cross's axes, so no ray runs along a bar's edge at the inner ring
        ang = 2 * np.pi * (np.arange(n) + 0.5) / n
        unit = np.stack([np.cos(ang), np.sin(ang)], axis=1)
        r_out, r_in = t.ring_outer_radius_m, t.ring_inner_radius_m
        self._ring_xy = np.ascontiguousarray(np.concatenate([r_out * unit, r_in * unit]))
        self._ring_P = np.concatenate([self._ring_xy, np.zeros((2 * n, 1))], axis=1)
        radial = np.concatenate([unit, unit])
        eps = 0.25 * t.ring_width_m
        self._ring_out = np.ascontiguousarray(self._ring_xy + eps * radial)
        self._ring_in = np.ascontiguousarray(self._ring_xy - eps * radial)
        # polarity along the outward radial direction: outer edge black -> white, inner white -> black
        self._ring_pol = np.concatenate([np.ones(n), -np.ones(n)])
        self._cross_P = np.concatenate([t.cross_inner_corners_P(), t.cross_outer_corners_P()]).astype(
            np.float64
        )
        self._cross_xy = np.ascontiguousarray(self._cross_P[:, :2])
        # The cross branch (a quad whose circle is not found: blur, a view at speed) is rare, and a
        # warm-up flight may not take it. Its one kernel call from Python is made here once, so that a
        # warm-up compiles it (or loads it from the cache) and no mission compiles it mid-flight.
        apply_homography(np.eye(3), self._cross_xy)
        # our close-range extension, run only when Alg. 1 finds no quad (see falanga_close.py)
        self._close = CloseRangeCrossDetector(t) if self.config.close_range else None
        self._range_m: float | None = None

    # ------------------------------------------------------------------------------------ public API

    def detect(self, image: Image, t: float) -> list[Observation]:
        """Observations of the tag in ``image`` (grey or BGR uint8 of any size) captured at ``t`` (s): at
        most one; ``[]`` when there is no tag or the image is unusable (empty, tiny, not an image);
        :class:`alight.errors.ImageError` for a non-finite ``t`` or an oversized image
        (:mod:`alight.perception.image_input`)."""
        t = check_time(t)
        return self._run(image, t, None) or self._run_close(image, t)

    def set_range(self, range_m: float | None) -> None:
        """The range finder's reading (m, to the surface below), or None when there is no valid one; the
        close-range stage is skipped above ``config.close_range_max_range_m`` (the Pipeline passes it
        before every image)."""
        ok = range_m is not None and math.isfinite(range_m) and range_m >= 0
        self._range_m = float(range_m) if ok else None  # type: ignore[arg-type]

    def detect_timed(self, image: Image, t: float) -> tuple[list[Observation], dict[str, float]]:
        """As :meth:`detect`, plus the wall time of each stage (ms) keyed by :data:`STAGES` and ``total``:
        ``threshold`` (grey conversion, downscale, adaptive threshold and run labelling), ``contours``
        (component shape scores, contour tracing and polygon fits), ``quad`` (corner refinement), ``inner``
        (pattern check, ring edges, cross corners) and ``ransac`` (the RANSAC homographies). The close-range
        stage (when no quad was found) counts in ``total`` only: ``total`` minus the sum of the stages."""
        t = check_time(t)
        times = dict.fromkeys(STAGES, 0.0)
        t0 = time.perf_counter()
        obs = self._run(image, t, times) or self._run_close(image, t)
        times["total"] = (time.perf_counter() - t0) * 1e3
        return obs, times

    # ------------------------------------------------------------------------------------ pipeline

    def _run(self, image: Image, t: float, times: dict[str, float] | None) -> list[Observation]:
        cfg = self.config
        clock = time.perf_counter
        tic = clock()
        gray = as_gray_u8(image)
        if gray is None or min(gray.shape) < 16:
            return []
        H, W = gray.shape
        f = max(1, math.ceil(max(H, W) / cfg.search_max_side_px))
        ws, hs = W // f, H // f
        if min(hs, ws) < 8:
            return []
        small = (
            gray if f == 1 else cv2.resize(gray[: hs * f, : ws * f], (ws, hs), interpolation=cv2.INTER_AREA)
        )
        radius_tiles = max(1, int(round(cfg.threshold_window_frac * min(hs, ws) / _TILE / 2)))
        n, row, x0, x1, root, bx0, bx1, by0, by1 = _threshold_runs(
            small,
            radius_tiles,
            float(cfg.threshold_offset_frac),
            float(cfg.threshold_offset_min),
            cfg.threshold_floor,
        )
        tic = _lap(times, "threshold", tic)
        if n == 0:
            return []
        # components big enough, not touching the border, with convex row extents; largest hull first
        min_side_s = cfg.min_quad_side_px / f
        idx = np.flatnonzero(root == np.arange(n, dtype=np.int32))
        bx0_, bx1_, by0_, by1_ = bx0[idx], bx1[idx], by0[idx], by1[idx]
        big = (bx1_ - bx0_ + 1 >= min_side_s) & (by1_ - by0_ + 1 >= min_side_s)
        big &= (bx0_ > 0) & (by0_ > 0) & (bx1_ < ws - 1) & (by1_ < hs - 1)
        idx = np.ascontiguousarray(idx[big], dtype=np.int32)
        if idx.size == 0:
            _lap(times, "contours", tic)
            return []
        sol, hull, quadness, corners = _solidity(row, x0, x1, root, idx, by0, by1)
        keep = np.flatnonzero((sol >= cfg.min_solidity) & (quadness >= cfg.min_quadness))
        # clean quadrangles first, largest first; then the ones a speck of ground may have spoiled
        clean = (sol[keep] >= 0.85) & (quadness[keep] >= 0.85)
        order = keep[np.lexsort((-hull[keep], ~clean))][: cfg.max_traced]
        tic = _lap(times, "contours", tic)
        tried = 0
        for c in order:
            if sol[c] >= 0.85 and quadness[c] >= 0.85:
                # a clean quadrangle: the largest quad on its hull is close enough for the refinement,
                # no need to trace its contour
                q: FloatArray | None = corners[c] if _quad_shape_ok(corners[c]) else None
            else:
                r = int(idx[c])
                q = _component_quad(row, x0, x1, root, r, int(by0[r]), int(bx0[r]), int(by1[r]), int(bx1[r]))
            tic = _lap(times, "contours", tic)
            if q is None:
                continue
            tried += 1
            obs = self._verify(gray, q, f, t, times)
            tic = time.perf_counter()
            if obs is not None:
                return [obs]
            if tried >= cfg.max_candidates:
                break
        return []

    def _run_close(self, image: Image, t: float) -> list[Observation]:
        """The close-range stage (our extension of Alg. 1, :mod:`alight.perception.falanga_close`): the cross
        alone, for frames where :meth:`_run` found no quad."""
        if self._close is None:
            return []
        if self._range_m is not None and self._range_m > self.config.close_range_max_range_m:
            return []
        gray = as_gray_u8(image)
        obs = None if gray is None or min(gray.shape) < 16 else self._close.detect(gray, t)
        return [] if obs is None else [obs]

    def _verify(
        self, gray: U8Array, q_small: FloatArray, f: int, t: float, times: dict[str, float] | None
    ) -> Observation | None:
        """Refine a candidate quad, check it against the tag's pattern and find the circle, else the
        cross, else keep the quad (Alg. 1, lines 5-13)."""
        cfg = self.config
        tic = time.perf_counter()
        ok, q_ref, n_sides, H0, side_px, diag_px = _quad_stage(
            gray, q_small, f, self._quad_xy, 2.0 * f + 2.0, float(cfg.min_edge_step)
        )
        tic = _lap(times, "quad", tic)
        if not ok:
            return None
        corr, contrast, frac_in = _pattern_corr(gray, H0, self._pat_xy, self._pat_label)
        if not (corr >= cfg.min_pattern_corr and frac_in >= 0.95):
            _lap(times, "inner", tic)
            return None
        min_step = max(cfg.min_edge_step, 0.3 * contrast)
        q_pattern = min(1.0, corr)
        thr = max(cfg.ransac_threshold_px, 0.01 * diag_px)
        tag = self.tag
        # --- circle (Alg. 1 line 7)
        ring_px = tag.ring_width_m / tag.size_m * side_px
        if ring_px >= cfg.min_feature_px:
            res = self._detect_ring(gray, H0, ring_px, min_step, thr, times)
            if res is not None:
                px, pts_P, frac = res
                _lap(times, "inner", tic)
                return Observation(t=t, kind="circle", quality=q_pattern * frac, pixels=px, points_P=pts_P)
        # --- cross (line 10)
        bar_px = tag.cross_bar_width_m / tag.size_m * side_px
        if bar_px >= 2 * cfg.min_feature_px:
            res = self._detect_cross(gray, H0, bar_px, thr, times)
            if res is not None:
                px, pts_P, frac = res
                _lap(times, "inner", tic)
                return Observation(t=t, kind="cross", quality=q_pattern * frac, pixels=px, points_P=pts_P)
        # --- the quad itself (line 13)
        _lap(times, "inner", tic)
        return Observation(
            t=t, kind="quad", quality=q_pattern * (0.5 + 0.125 * n_sides), pixels=q_ref, points_P=self._quad_P
        )

    def _detect_ring(
        self,
        gray: U8Array,
        H0: FloatArray,
        ring_px: float,
        min_step: float,
        thr: float,
        times: dict[str, float] | None,
    ) -> tuple[FloatArray, FloatArray, float] | None:
        """Ring correspondences: two passes of edge search + RANSAC, the second from the first's
        homography with a narrower search. None unless ``min_ring_fraction`` of the rays are inliers."""
        n_need = self.config.min_ring_fraction * self._ring_xy.shape[0]
        H = H0
        half = min(20.0, max(1.5, 0.6 * ring_px))
        mask = pts = None
        for _ in range(2):
            pts, ok = _ring_edges(
                gray, H, self._ring_xy, self._ring_out, self._ring_in, self._ring_pol, half, min_step
            )
            tic = time.perf_counter()
            good, H, mask, n_in = _ransac_subset(self._ring_xy, pts, ok, thr, 200, n_need)
            _lap(times, "ransac", tic, negate="inner")
            if not good:
                return None
            half = min(6.0, max(1.0, 0.3 * ring_px)) + thr
        if mask is None or pts is None:
            return None
        return pts[mask], self._ring_P[mask], float(n_in) / self._ring_xy.shape[0]

    def _detect_cross(
        self, gray: U8Array, H0: FloatArray, bar_px: float, thr: float, times: dict[str, float] | None
    ) -> tuple[FloatArray, FloatArray, float] | None:
        """Cross corners: ``cv2.cornerSubPix`` from the quad's prediction, then RANSAC over the 12."""
        pred = apply_homography(H0, self._cross_xy)
        h, w = gray.shape
        win = int(np.clip(0.4 * bar_px, 2, 12))
        inside = (pred[:, 0] >= win) & (pred[:, 1] >= win) & (pred[:, 0] < w - win) & (pred[:, 1] < h - win)
        if not inside[:4].all():
            return None
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 20, 0.01)
        c = pred.astype(np.float32).reshape(-1, 1, 2)
        c = cv2.cornerSubPix(gray, c, (win, win), (-1, -1), crit).reshape(-1, 2).astype(np.float64)
        ok = inside & (np.linalg.norm(c - pred, axis=1) <= 0.7 * win)
        if not ok[:4].all() or ok.sum() < 8:
            return None
        tic = time.perf_counter()
        # n_need as a float, as the ring's call passes it: one compiled signature for both
        good, _, mask, _ = _ransac_subset(self._cross_xy, c, ok, thr, 200, 8.0)
        _lap(times, "ransac", tic, negate="inner")
        if not good or not mask[:4].all():
            return None
        return c[mask], self._cross_P[mask], float(mask.sum()) / mask.size


def _lap(times: dict[str, float] | None, key: str, tic: float, negate: str | None = None) -> float:
    """Add the time since ``tic`` to ``times[key]`` (ms), and subtract it from ``times[negate]`` (for a
    stage nested in another); returns the current clock."""
    toc = time.perf_counter()
    if times is not None:
        dt = (toc - tic) * 1e3
        times[key] += dt
        if negate is not None:
            times[negate] -= dt
    return toc


def _signed_area(q: FloatArray) -> float:
    """Shoelace area of a polygon (N, 2) in (u, v) pixel coordinates."""
    a = 0.0
    n = q.shape[0]
    for k in range(n):
        x0, y0 = q[k]
        x1, y1 = q[(k + 1) % n]
        a += float(x0 * y1 - x1 * y0)
    return 0.5 * a


def _approx_quad(c: NDArray[np.int32], eps_frac: float, offset: tuple[int, int]) -> FloatArray | None:
    """Corners (4, 2) of a contour's ``approxPolyDP`` at ``eps_frac`` of its perimeter when that is a
    convex quadrangle whose area is close to the contour's (within 4 % plus the ~2/side that pixel
    steps make on a small shape), else None."""
    approx = cv2.approxPolyDP(c, eps_frac * cv2.arcLength(c, True), True)
    if len(approx) != 4 or not cv2.isContourConvex(approx):
        return None
    q = approx.reshape(4, 2).astype(np.float64) + offset
    area = abs(_signed_area(q))
    if area <= 0 or abs(1.0 - float(cv2.contourArea(c)) / area) > 0.04 + 2.0 / math.sqrt(area):
        return None
    return q


def _longest_sides_quad(c: NDArray[np.int32], offset: tuple[int, int]) -> FloatArray | None:
    """Corners (4, 2) where the lines of the 4 longest sides of a fine (2 %) polygon of the contour meet,
    when those sides make at least 60 % of its perimeter: a speck of ground that clings to one corner of
    the pad adds short sides, and the pad's own four sides stay the longest."""
    approx = cv2.approxPolyDP(c, 0.02 * cv2.arcLength(c, True), True).reshape(-1, 2).astype(np.float64)
    m = approx.shape[0]
    if m < 5 or m > 12:
        return None
    e = approx[(np.arange(m) + 1) % m] - approx
    length = np.hypot(e[:, 0], e[:, 1])
    top = np.sort(np.argsort(-length, kind="stable")[:4])
    if length[top].sum() < 0.6 * length.sum():
        return None
    q = np.empty((4, 2))
    for k in range(4):
        i, j = top[k - 1], top[k]
        a0, da = approx[i], e[i]
        b0, db = approx[j], e[j]
        det = -da[0] * db[1] + db[0] * da[1]
        if abs(det) < 1e-6 * length[i] * length[j]:
            return None
        r = b0 - a0
        t = (-r[0] * db[1] + db[0] * r[1]) / det
        q[k] = a0 + t * da
    if not cv2.isContourConvex(q.astype(np.float32).reshape(-1, 1, 2)):
        return None
    return q + offset


def _component_quad(row, x0, x1, root, r: int, y0: int, xl: int, y1: int, xr: int) -> FloatArray | None:  # type: ignore[no-untyped-def]
    """The quadrangle of a component's outer contour, corners (4, 2) in downscaled pixels, or None when
    the contour is not a plausible quadrangle. Tried in turn: a 4-vertex ``approxPolyDP`` at 2 % of the
    perimeter (:func:`_approx_quad`), the 4 longest sides of that polygon (:func:`_longest_sides_quad`),
    a 4-vertex approximation at 3.5 %; then no side may be shorter than a fifth of the longest and no
    corner angle outside [32, 148] deg."""
    mask = _paint(row, x0, x1, root, r, y0 - 1, xl - 1, y1 - y0 + 3, xr - xl + 3)
    offset = (xl - 1, y0 - 1)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return None
    c = max(contours, key=len)
    q = _approx_quad(c, 0.02, offset)
    if q is None:
        q = _longest_sides_quad(c, offset)
    if q is None:
        q = _approx_quad(c, 0.035, offset)
    if q is None:
        return None
    return q if _quad_shape_ok(q) else None
