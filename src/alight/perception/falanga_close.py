"""Close-range stage of the Falanga tag detector: the black cross when the white square is no longer
entirely in view. **Our extension of paper 000's Alg. 1, not in the paper.**

Why: Alg. 1 starts from the largest white quadrangle, so it needs the whole 1.5 m square in view. The
downward camera (752x480, ~90x63 deg) loses the square below ~1.3-1.6 m above the pad, and the paper's
vehicle then lands on the estimator's prediction alone: on a turning platform at 2-4 m/s that misses by
0.3-2 m. The cross (arms ``L = 0.28 s`` from the centre, bars ``w = 0.10 s`` wide) stays in view much
longer: whole down to ~0.7 m above the pad, its 4 inner corners (a ``w`` x ``w`` square around the centre)
down to ~0.3 m. :class:`FalangaTagDetector` calls this stage only when the quad stage found nothing, so
the paper's order (circle, else cross, else quad inside the quad) is kept whenever the quad is found.

Steps (``C`` = :class:`CloseRangeConfig`):

1. Threshold. The image is box-downscaled like the quad search (752x480 -> 376x240); a pixel is dark
   below its 2nd brightness percentile plus ``C.dark_fraction`` (0.35) of the spread to the 98th: at close
   range the tag's black and white are the extremes of the view, and the cross is surrounded by white on
   the pad, so it is a dark component of its own whatever the ground and the deck do beside the pad.
   Below the midpoint so that white in the vehicle's shadow (about half as bright, while black stays
   black) stays white. The spread must be at least ``C.min_contrast`` (a uniform view has no tag).
2. Components. 8-connected labelling of the dark runs (union-find over runs, numba: OpenCV's labelling
   with statistics takes ~1 ms on the thousands of specks of a textured ground); components with at least
   the area of a cross whose bars are ``C.min_bar_px`` wide and at most 2.2 runs per row (a row meets each
   of the cross's two convex bars once; ground components are full of holes) go on, the
   ``C.max_candidates`` largest first.
3. Polygon. The component's outer contour (``cv2.findContours`` on its painted bounding box, with a frame
   of 0 that closes it along the image edge) is simplified by ``cv2.approxPolyDP`` (tolerance 3 % of the
   square root of the area, 1-6 px); runs of edges shorter than a third of the bar width that turn the
   same way (a corner chamfered by the downscale) become one vertex at the intersection of the long edges
   on either side. A vertex is a *corner* when the outline turns by 40-140 deg there (a right angle of
   the pad under the tilts and lens of a landing camera; lens distortion bends straight bar edges into
   shallow turns, which stay below 40 deg) and it is off the image edge, *concave* when it turns against
   the outline's orientation. The cross has exactly 4 concave corners, its inner corners; any other count
   rejects the component.
4. Topology. Walked in the order that is counter-clockwise on the pad (negative shoelace area in
   ``(u, v)``: the camera sees the pad's top face, and ``x_C x y_C = z_C = -z_P`` reverses orientation),
   the outline between two consecutive inner corners must run along one arm: either out of the image
   (it touches the border) or around the arm's end through exactly 2 sharp convex vertices, the arm's
   outer corners (order of :meth:`FalangaTag.cross_outline_P`). An arm cut by the image keeps an outer
   corner when exactly one sharp convex vertex lies between the inner corner and the border on that side.
5. Labels (4-fold symmetry). The cross is symmetric under rotations by 90 deg, so the 4 cyclic labellings
   that respect the walk order all describe the same tag with the same centre; only the yaw changes, by
   multiples of 90 deg, and the yaw is only defined modulo 90 deg anyway (``yaw_fold = 4`` in
   :class:`alight.perception.PnpGeolocator`). The inner corner nearest the top-left of the image gets the
   label ``(+w/2, +w/2)``, the convention of the quad's corners (right for a camera with the image top
   toward the pad's front, +x).
6. Corners. ``cv2.cornerSubPix`` at full resolution (half-window 0.3 of the bar width in pixels, so no
   other corner of the cross is inside it); a corner that moves more than ``0.7`` of the half-window is
   dropped (every inner corner must survive).
7. Verification. A homography from the pad plane to the image is fitted to the corners (least squares, the
   normalised DLT of :mod:`alight.numerics.homography`; outer corners off it by more than ``max(1.5 px,
   6 % of the bar width)`` are dropped and it is refitted; an inner corner off it, or more than half of 4 or
   more outer corners, rejects the component). Through it, the image is sampled at points of known colour
   around the centre, at least 3.5 cm from any edge of the tag: the cross's centre and arm centre lines
   (black) and the white quadrants between the arms (white). At least ``C.min_pattern_fraction`` of the
   samples in view must fall on the right side of the midpoint between the black and white means, the
   means must differ by ``C.min_contrast`` and the black mean be at most ``C.max_dark_ratio`` of the white
   mean (black ink on white paint; dark joints in concrete, grass or asphalt are 0.6-0.9 of their
   surroundings).
   Ground-only frames, the AprilTag pad and the real photos in the tests give nothing.

Result: an :class:`alight.types.Observation` with the refined corners and their points in P (z = 0), for
:class:`alight.perception.PnpGeolocator`. Kind ``cross`` when all 12 corners of the cross's outline are
used (the same points as Alg. 1's cross), ``cross_close`` when the cross is cut by the image and only its 4
inner corners (plus the outer corners in view) are used. Quality: the pattern fraction times
``0.5 + 0.5 n / 12`` for ``n`` corners.

Cost on one core, 752x480 (a shared 2-core machine, best of 5 per frame): median 0.75 ms, 90th
percentile 1.0 ms on rendered frames 0.3-1.6 m above the pad where Alg. 1 finds no quad; 0.05-0.4 ms on
ground-only frames (most of it the labelling of the ground's specks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

from alight.numerics.histogram import histogram_quantile
from alight.numerics.homography import homography_lsq, map_point
from alight.numerics.image import bilinear
from alight.numerics.runs import link_run, run_roots
from alight.pads.falanga_tag import FalangaTag
from alight.types import FloatArray, Observation, U8Array


@dataclass(frozen=True, kw_only=True)
class CloseRangeConfig:
    """Parameters of :class:`CloseRangeCrossDetector` (pixels are full-resolution pixels, grey levels
    8-bit)."""

    search_max_side_px: int = 400
    """The component search runs on the image box-downscaled by the smallest integer factor that brings
    its long side to at most this (752x480 -> 376x240)."""
    min_bar_px: float = 14.0
    """Least width of the cross's bars in the image (px): about 4.3 m above the 1.5 m tag with the default
    camera; smaller crosses are the quad stage's business."""
    dark_fraction: float = 0.35
    """A pixel is dark when below the 2nd brightness percentile plus this fraction of the spread to the
    98th. Below one half, so that white in the vehicle's shadow (about half as bright as in the sun, while
    black stays black) stays white around the cross."""
    max_candidates: int = 4
    """How many of the largest dark components are examined."""
    min_contrast: float = 50.0
    """Least brightness spread of the image (98th - 2nd percentile) and least difference between the
    white and the black samples of the verification (grey levels)."""
    max_dark_ratio: float = 0.5
    """Greatest ratio of the black samples' mean to the white samples' mean."""
    min_pattern_fraction: float = 0.9
    """Least fraction of the verification samples in view that have the colour of the tag there."""
    min_turn_deg: float = 40.0
    """Least turn of the outline at a vertex for it to count as a corner of the cross (deg)."""
    max_turn_deg: float = 140.0
    """Greatest turn of the outline at a corner of the cross (deg)."""

    def __post_init__(self) -> None:
        checks = {
            "search_max_side_px": self.search_max_side_px >= 32,
            "min_bar_px": math.isfinite(self.min_bar_px) and self.min_bar_px >= 4.0,
            "dark_fraction": 0.0 < self.dark_fraction < 1.0,
            "max_candidates": self.max_candidates >= 1,
            "min_contrast": math.isfinite(self.min_contrast) and self.min_contrast >= 0,
            "max_dark_ratio": 0.0 < self.max_dark_ratio <= 1.0,
            "min_pattern_fraction": 0.0 < self.min_pattern_fraction <= 1.0,
            "min_turn_deg": 0.0 < self.min_turn_deg < self.max_turn_deg < 180.0,
            "max_turn_deg": 0.0 < self.max_turn_deg < 180.0,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"invalid CloseRangeConfig values: {bad}")


def _verification_samples(tag: FalangaTag) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Points (N, 2) in P (m) around the cross's centre and whether the tag is white there: the centre
    and the arms' centre lines (black), the quadrants between the arms (white), each at least
    ``min(3.5 cm, w / 2)`` from any edge of the tag, none past the ring's inner edge."""
    L, h = tag.cross_arm_half_length_m, tag.cross_bar_width_m / 2
    margin = min(0.035, h)
    r_max = tag.ring_inner_radius_m - margin
    pts: list[tuple[float, float]] = [(0.0, 0.0)]
    white: list[bool] = [False]
    # arm centre lines: from the central square out to a margin short of the bar end
    for t in np.linspace(h, L - margin, 4):
        for dx, dy in ((1, 0), (0, 1), (-1, 0), (0, -1)):
            pts.append((dx * t, dy * t))
            white.append(False)
    # quadrants: on the diagonal and beside each arm, out to the ring's inner edge
    d0 = h + margin
    for s in np.linspace(d0, r_max / math.sqrt(2.0), 4):
        for sx in (1, -1):
            for sy in (1, -1):
                pts.append((sx * s, sy * s))
                white.append(True)
    for s in np.linspace(d0 + 0.5 * (L - d0), L, 2):
        for sx in (1, -1):
            for sy in (1, -1):
                for p in ((sx * d0, sy * s), (sx * s, sy * d0)):
                    if math.hypot(*p) <= r_max:
                        pts.append(p)
                        white.append(True)
    return np.array(pts, dtype=np.float64), np.array(white, dtype=bool)


# --------------------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _dark_runs(img, min_contrast, dark_frac):  # pragma: no cover - numba
    """Step 1-2: threshold at the midpoint of the 2nd and 98th percentiles and 8-connected labelling of
    the dark runs (union-find over runs, :mod:`alight.numerics.runs`; a ground texture makes thousands of
    specks, which OpenCV's labelling with statistics takes ~1 ms for at 376x240).

    Returns ``(n_runs, row, x0, x1, root, area, runs_per_row)``: run k spans columns x0[k]..x1[k] of
    row[k], ``root[k]`` is the run that represents k's component; ``area[r]`` (px) and
    ``runs_per_row[r]`` (the component's runs per row it spans, times 1000) are valid at roots.
    ``n_runs = 0`` when the percentile spread is below ``min_contrast``.
    """
    h, w = img.shape
    hist = np.zeros(256, np.int64)
    for i in range(0, h, 2):  # a 2x2 subsample is plenty for two percentiles
        for j in range(0, w, 2):
            hist[img[i, j]] += 1
    total = hist.sum()
    p_lo = histogram_quantile(hist, total, 0.02)
    p_hi = histogram_quantile(hist, total, 0.98)
    cap = h * ((w + 1) // 2) + 1
    row = np.empty(cap, np.int32)
    x0 = np.empty(cap, np.int32)
    x1 = np.empty(cap, np.int32)
    parent = np.empty(cap, np.int32)
    if p_hi - p_lo < min_contrast:
        return 0, row[:0], x0[:0], x1[:0], parent[:0], parent[:0], parent[:0]
    thr = p_lo + dark_frac * (p_hi - p_lo)  # dark: v < thr
    # int64 zeros, not literal ones: typed as Literal[int](0) before the loop unifies them, they would
    # make numba compile link_run and run_roots once more for that literal type
    n = np.int64(0)
    prev_s = np.int64(0)
    prev_e = np.int64(0)
    for i in range(h):
        r = img[i]
        cur_s = n
        q = prev_s
        j = 0
        while j < w:
            if r[j] < thr:
                s = j
                j += 1
                while j < w and r[j] < thr:
                    j += 1
                e = j - 1
                row[n] = i
                x0[n] = s
                x1[n] = e
                parent[n] = n
                q = link_run(parent, x0, x1, n, q, prev_e)  # with the previous row's runs
                n += 1
            else:
                j += 1
        prev_s = cur_s
        prev_e = n
    root = run_roots(parent, n)
    area = np.zeros(n, np.int32)
    n_runs = np.zeros(n, np.int32)
    y_lo = np.full(n, h, np.int32)
    y_hi = np.zeros(n, np.int32)
    for k in range(n):
        rk = root[k]
        area[rk] += x1[k] - x0[k] + 1
        n_runs[rk] += 1
        y_lo[rk] = min(y_lo[rk], row[k])
        y_hi[rk] = max(y_hi[rk], row[k])
    # runs per row: a line meets each of the cross's two (convex) bars once, so the cross has at most 2
    # runs in a row; textured ground makes components full of holes, with many
    for k in range(n):
        if root[k] == k:
            n_runs[k] = n_runs[k] * 1000 // (y_hi[k] - y_lo[k] + 1)
    return n, row[:n], x0[:n], x1[:n], root, area, n_runs


@numba.njit(cache=True)
def _paint_bbox(row, x0, x1, root, r):  # pragma: no cover - numba
    """Mask (uint8, 0/1) of the component rooted at run r on its bounding box plus a 1-px frame of 0, and
    the box's top-left ``(ox, oy)`` in the image minus 1."""
    ymin = 1 << 30
    ymax = -1
    xmin = 1 << 30
    xmax = -1
    for k in range(row.shape[0]):
        if root[k] == r:
            ymin = min(ymin, row[k])
            ymax = max(ymax, row[k])
            xmin = min(xmin, x0[k])
            xmax = max(xmax, x1[k])
    mask = np.zeros((ymax - ymin + 3, xmax - xmin + 3), np.uint8)
    for k in range(row.shape[0]):
        if root[k] == r:
            mask[row[k] - ymin + 1, x0[k] - xmin + 1 : x1[k] - xmin + 2] = 1
    return mask, xmin - 1, ymin - 1


@numba.njit(cache=True)
def _merge_short_edges(P, B, min_edge):  # pragma: no cover - numba
    """Polygon (n, 2) with border flags (n,) -> the polygon where every run of vertices joined by edges
    shorter than ``min_edge``, all turning the same way and all on or all off the border, is one vertex,
    at the intersection of the long edges on either side (a corner that the downscale and threshold
    chamfered, which approxPolyDP keeps as two shallow turns; a short edge between turns of opposite
    sense is a real feature, like a corner of the cross just inside the image edge). Returns
    ``(V, VB, m)``, the first m rows valid; m = 0 when no edge can start the walk."""
    n = P.shape[0]
    V = np.empty((n, 2))
    VB = np.zeros(n, np.bool_)
    S = np.empty(n, np.bool_)  # turn sense
    for i in range(n):
        a = P[(i - 1) % n]
        c = P[(i + 1) % n]
        S[i] = (P[i, 0] - a[0]) * (c[1] - P[i, 1]) - (P[i, 1] - a[1]) * (c[0] - P[i, 0]) > 0

    def joined(i, j):
        return math.hypot(P[j, 0] - P[i, 0], P[j, 1] - P[i, 1]) < min_edge and S[i] == S[j] and B[i] == B[j]

    start = -1
    for i in range(n):
        if not joined((i - 1) % n, i):
            start = i
            break
    if start < 0:
        return V, VB, 0
    m = 0
    i = 0
    while i < n:
        a = (start + i) % n
        j = i
        while j + 1 < n and joined((start + j) % n, (start + j + 1) % n):
            j += 1
        b = (start + j) % n
        border = False
        cx = 0.0
        cy = 0.0
        for t in range(i, j + 1):
            c = (start + t) % n
            border = border or B[c]
            cx += P[c, 0]
            cy += P[c, 1]
        cx /= j - i + 1
        cy /= j - i + 1
        if j > i:
            # intersection of the lines (P[a-1], P[a]) and (P[b], P[b+1])
            pa = P[(a - 1) % n]
            da0 = P[a, 0] - pa[0]
            da1 = P[a, 1] - pa[1]
            pb = P[b]
            db0 = P[(b + 1) % n, 0] - pb[0]
            db1 = P[(b + 1) % n, 1] - pb[1]
            det = da0 * db1 - da1 * db0
            la = math.hypot(da0, da1)
            lb = math.hypot(db0, db1)
            if abs(det) > 0.2 * la * lb:
                r0 = pb[0] - pa[0]
                r1 = pb[1] - pa[1]
                s = (r0 * db1 - r1 * db0) / det
                ix = pa[0] + s * da0
                iy = pa[1] + s * da1
                if math.hypot(ix - cx, iy - cy) <= 2.0 * min_edge:
                    cx = ix
                    cy = iy
        V[m, 0] = cx
        V[m, 1] = cy
        VB[m] = border
        m += 1
        i = j + 1
    return V, VB, m


@numba.njit(cache=True)
def _cross_corners(poly, ws, hs, min_edge, cos_lo, cos_hi):  # pragma: no cover - numba
    """Steps 3-5 on a component's simplified outline ``poly`` (n, 2) in downscaled pixels of an image of
    ``ws x hs``: the cross's inner corners and the outer corners in view, labelled.

    A vertex is a corner when ``cos_lo <= cos(turn) <= cos_hi``. Returns ``(ok, inner (4, 2), outer (8, 2),
    has_outer (8,))``: ``inner[k]`` is the image of ``FalangaTag.cross_inner_corners_P()[k]``, ``outer[k]``
    that of ``cross_outer_corners_P()[k]`` where ``has_outer[k]``.

    One kernel: steps 3-5 walk the same merged outline (``V``, ``VB``) and its corner and concavity flags back
    and forth with indices modulo n, and any failed arm ends the whole search early; split, those four arrays
    and the labels would go through every call. The edge merging is already apart (``_merge_short_edges``).
    """
    inner = np.zeros((4, 2))
    outer = np.zeros((8, 2))
    has = np.zeros(8, np.bool_)
    n0 = poly.shape[0]
    a2 = 0.0
    for i in range(n0):
        j = (i + 1) % n0
        a2 += poly[i, 0] * poly[j, 1] - poly[j, 0] * poly[i, 1]
    # walk counter-clockwise on the pad: negative shoelace area in (u, v)
    P = np.empty((n0, 2))
    B = np.empty(n0, np.bool_)
    for i in range(n0):
        s = i if a2 <= 0 else n0 - 1 - i
        P[i, 0] = poly[s, 0]
        P[i, 1] = poly[s, 1]
        B[i] = poly[s, 0] <= 0.5 or poly[s, 1] <= 0.5 or poly[s, 0] >= ws - 1.5 or poly[s, 1] >= hs - 1.5
    V, VB, n = _merge_short_edges(P, B, min_edge)
    if n < 6:
        return False, inner, outer, has
    corner = np.zeros(n, np.bool_)
    concave = np.zeros(n, np.bool_)
    n_in = 0
    for i in range(n):
        ein0 = V[i, 0] - V[(i - 1) % n, 0]
        ein1 = V[i, 1] - V[(i - 1) % n, 1]
        eo0 = V[(i + 1) % n, 0] - V[i, 0]
        eo1 = V[(i + 1) % n, 1] - V[i, 1]
        den = math.hypot(ein0, ein1) * math.hypot(eo0, eo1)
        c = (ein0 * eo0 + ein1 * eo1) / den if den > 0.0 else 1.0
        corner[i] = (not VB[i]) and cos_lo <= c <= cos_hi
        concave[i] = ein0 * eo1 - ein1 * eo0 > 0  # a convex vertex turns clockwise in (u, v) here
        if corner[i] and concave[i]:
            n_in += 1
    if n_in != 4:
        return False, inner, outer, has
    idx = np.empty(4, np.int64)
    k = 0
    for i in range(n):
        if corner[i] and concave[i]:
            idx[k] = i
            k += 1
    # step 5: the inner corner nearest the image's top-left gets label 0, (+w/2, +w/2)
    mx = 0.25 * (V[idx[0], 0] + V[idx[1], 0] + V[idx[2], 0] + V[idx[3], 0])
    my = 0.25 * (V[idx[0], 1] + V[idx[1], 1] + V[idx[2], 1] + V[idx[3], 1])
    m_star = 0
    best = -1e300
    for m in range(4):
        sc = -(V[idx[m], 0] - mx) - (V[idx[m], 1] - my)
        if sc > best:
            best = sc
            m_star = m
    for m in range(4):
        q = (m - m_star) % 4  # label of the m-th inner corner of the walk
        inner[q, 0] = V[idx[m], 0]
        inner[q, 1] = V[idx[m], 1]
        # step 4: the stretch to the next inner corner runs along one arm, whose end has the outer
        # corners 2q+1, 2q+2 (mod 8) of the outline's order
        a = idx[m]
        b = idx[(m + 1) % 4]
        L = (b - a) % n
        n_b = 0
        first_b = -1
        last_b = -1
        for t in range(1, L):
            if VB[(a + t) % n]:
                n_b += 1
                if first_b < 0:
                    first_b = t
                last_b = t
        o1 = (2 * q + 1) % 8
        o2 = (2 * q + 2) % 8
        if n_b == 0:
            cnt = 0
            for t in range(1, L):
                v = (a + t) % n
                if corner[v]:
                    if cnt == 0:
                        outer[o1, 0] = V[v, 0]
                        outer[o1, 1] = V[v, 1]
                    elif cnt == 1:
                        outer[o2, 0] = V[v, 0]
                        outer[o2, 1] = V[v, 1]
                    cnt += 1
            if cnt != 2:
                return False, inner, outer, has
            has[o1] = True
            has[o2] = True
        else:
            # an arm cut by the image: keep an outer corner when it is the only corner on its side
            cnt = 0
            last = -1
            for t in range(1, first_b):
                if corner[(a + t) % n]:
                    cnt += 1
                    last = (a + t) % n
            if cnt == 1:
                outer[o1, 0] = V[last, 0]
                outer[o1, 1] = V[last, 1]
                has[o1] = True
            cnt = 0
            for t in range(last_b + 1, L):
                if corner[(a + t) % n]:
                    cnt += 1
                    last = (a + t) % n
            if cnt == 1:
                outer[o2, 0] = V[last, 0]
                outer[o2, 1] = V[last, 1]
                has[o2] = True
    return True, inner, outer, has


@numba.njit(cache=True)
def _prepare(inner_s, outer_s, has_outer, f, w_img, h_img, min_bar_px):  # pragma: no cover - numba
    """Full-resolution start points for step 6 from the labelled corners in downscaled pixels.

    Returns ``(ok, start (k, 1, 2) float32, idx (k,), win, bar_px)``: ``idx`` 0-3 are the inner corners,
    4 + j the outer corner j; corners too near the image edge for the corner window are left out (all
    inner corners must stay). ``ok`` is False when the inner corners are not a plausible image of the
    central square: bars narrower than ``min_bar_px``, a side under 0.4 of the longest, a non-convex
    quadrangle or a corner angle outside [30, 150] deg.
    """
    c = 0.5 * (f - 1)  # pixel centres of the box-downscaled image
    q = np.empty((4, 2))
    for k in range(4):
        q[k, 0] = f * inner_s[k, 0] + c
        q[k, 1] = f * inner_s[k, 1] + c
    smin = 1e300
    smax = 0.0
    ssum = 0.0
    sign = 0
    for k in range(4):
        a = q[(k - 1) % 4]
        b = q[k]
        d = q[(k + 1) % 4]
        e0 = b[0] - a[0]
        e1 = b[1] - a[1]
        g0 = d[0] - b[0]
        g1 = d[1] - b[1]
        le = math.hypot(e0, e1)
        lg = math.hypot(g0, g1)
        if le <= 0.0 or lg <= 0.0:
            return False, np.zeros((0, 1, 2), np.float32), np.zeros(0, np.int64), 0, 0.0
        smin = min(smin, lg)
        smax = max(smax, lg)
        ssum += lg
        crs = e0 * g1 - e1 * g0
        sk = 1 if crs > 0 else -1
        if sign == 0:
            sign = sk
        cosang = -(e0 * g0 + e1 * g1) / (le * lg)
        if sk != sign or abs(cosang) > 0.8660254037844387:  # cos 30 deg
            return False, np.zeros((0, 1, 2), np.float32), np.zeros(0, np.int64), 0, 0.0
    bar_px = 0.25 * ssum
    if bar_px < min_bar_px or smin < 0.4 * smax:
        return False, np.zeros((0, 1, 2), np.float32), np.zeros(0, np.int64), 0, 0.0
    win = int(min(12.0, max(2.0, 0.3 * bar_px)))
    start = np.empty((12, 1, 2), np.float32)
    idx = np.empty(12, np.int64)
    m = 0
    for k in range(12):
        if k < 4:
            x = q[k, 0]
            y = q[k, 1]
        else:
            if not has_outer[k - 4]:
                continue
            x = f * outer_s[k - 4, 0] + c
            y = f * outer_s[k - 4, 1] + c
        if x < win + 1 or y < win + 1 or x > w_img - win - 2 or y > h_img - win - 2:
            if k < 4:
                return False, np.zeros((0, 1, 2), np.float32), np.zeros(0, np.int64), 0, 0.0
            continue
        start[m, 0, 0] = x
        start[m, 0, 1] = y
        idx[m] = k
        m += 1
    return True, start[:m], idx[:m], win, bar_px


@numba.njit(cache=True)
def _verify(  # pragma: no cover - numba
    gray, start, ref, idx, P_xy, win, f, bar_px, samp_xy, samp_w, min_c, max_ratio, min_frac
):
    """Steps 6 (acceptance of the refined corners) and 7 (homography and pattern).

    ``start``/``ref`` (k, 1, 2): corners before and after ``cv2.cornerSubPix``; ``idx`` (k,): which corner
    (0-3 inner, 4 + j outer j); ``P_xy`` (12, 2): the inner then outer corners in P (m). Returns ``(ok,
    keep (k,), frac)``: the corners to use and the pattern fraction.

    One kernel: steps 6 and 7 share the homography ``H``, which step 6 refits when it drops outer corners and
    step 7 samples the pattern through, and each check can end the verification early; the maths it uses
    (``homography_lsq``, ``map_point``, ``bilinear``) is apart already.
    """
    k = idx.shape[0]
    keep = np.zeros(k, np.bool_)
    src = np.empty((k, 2))
    dst = np.empty((k, 2))
    max_move = max(0.7 * win, 1.5 * f)
    for i in range(k):
        src[i, 0] = P_xy[idx[i], 0]
        src[i, 1] = P_xy[idx[i], 1]
        dst[i, 0] = ref[i, 0, 0]
        dst[i, 1] = ref[i, 0, 1]
        ok_i = math.hypot(ref[i, 0, 0] - start[i, 0, 0], ref[i, 0, 1] - start[i, 0, 1]) <= max_move
        if idx[i] < 4 and not ok_i:
            return False, keep, 0.0
        keep[i] = ok_i
    ok, H = homography_lsq(src, dst, keep)
    if not ok:
        return False, keep, 0.0
    tol = max(1.5, 0.06 * bar_px)
    n_outer = 0
    n_dropped = 0
    for i in range(k):
        if not keep[i]:
            continue
        if idx[i] >= 4:
            n_outer += 1
        u, v = map_point(H, src[i, 0], src[i, 1])
        res = math.hypot(u - dst[i, 0], v - dst[i, 1])
        if not res <= tol:
            if idx[i] < 4:
                return False, keep, 0.0
            keep[i] = False
            n_dropped += 1
    # a shape whose outer corners mostly miss the cross's homography is not the cross
    if n_outer >= 4 and 2 * n_dropped > n_outer:
        return False, keep, 0.0
    if n_dropped > 0:
        ok, H = homography_lsq(src, dst, keep)
        if not ok:
            return False, keep, 0.0
    # pattern: bilinear samples at the points of known colour that are in view
    h_img, w_img = gray.shape
    n_s = samp_xy.shape[0]
    val = np.empty(n_s)
    use = np.zeros(n_s, np.bool_)
    sw = 0.0
    sb = 0.0
    nw = 0
    nb = 0
    for i in range(n_s):
        x, y = map_point(H, samp_xy[i, 0], samp_xy[i, 1])
        if not (x >= 0.0 and y >= 0.0 and x <= w_img - 1 and y <= h_img - 1):
            continue
        val[i] = bilinear(gray, x, y)
        use[i] = True
        if samp_w[i]:
            sw += val[i]
            nw += 1
        else:
            sb += val[i]
            nb += 1
    if nw < 4 or nb < 4:
        return False, keep, 0.0
    mw = sw / nw
    mb = sb / nb
    if mw - mb < min_c or mb > max_ratio * mw:
        return False, keep, 0.0
    mid = 0.5 * (mw + mb)
    good = 0
    for i in range(n_s):
        if use[i] and (val[i] > mid) == samp_w[i]:
            good += 1
    frac = good / (nw + nb)
    return frac >= min_frac, keep, frac


# --------------------------------------------------------------------------------------------------
# the detector
# --------------------------------------------------------------------------------------------------


class CloseRangeCrossDetector:
    """The cross of the Falanga tag at close range (see the module docstring). ``detect(gray, t)`` is a
    pure function of the image.

    Parameters
    ----------
    tag:
        The tag's geometry; its lengths fix the metric points for PnP. Default: ``FalangaTag.default()``.
    config:
        :class:`CloseRangeConfig`; the defaults suit 752x480 grey frames.
    """

    def __init__(self, tag: FalangaTag | None = None, config: CloseRangeConfig | None = None) -> None:
        self.tag = FalangaTag.default() if tag is None else tag
        self.config = CloseRangeConfig() if config is None else config
        t = self.tag
        # the inner corners then the outer corners, in P (m): the index space of ``_prepare``
        self._corners_P = np.concatenate([t.cross_inner_corners_P(), t.cross_outer_corners_P()]).astype(
            np.float64
        )
        self._corners_xy = np.ascontiguousarray(self._corners_P[:, :2])
        self._sample_xy, self._sample_white = _verification_samples(t)
        # area of the cross over the square of its bar width: the least component area follows from
        # the least bar width
        w, L = t.cross_bar_width_m, t.cross_arm_half_length_m
        self._area_per_bar2 = (4.0 * L * w - w * w) / (w * w)
        cfg = self.config
        self._cos_lo = math.cos(math.radians(cfg.max_turn_deg))
        self._cos_hi = math.cos(math.radians(cfg.min_turn_deg))

    def detect(self, gray: U8Array, t: float) -> Observation | None:
        """The cross in a grey uint8 image (H, W) captured at ``t`` (s), or None. Raises ``ValueError`` for
        anything else than a 2-D uint8 array (:func:`alight.perception.image_input.as_gray_u8` converts)."""
        if not isinstance(gray, np.ndarray) or gray.ndim != 2 or gray.dtype != np.uint8:
            raise ValueError("CloseRangeCrossDetector.detect needs a 2-D uint8 grey image")
        gray = np.ascontiguousarray(gray)
        cfg = self.config
        H, W = gray.shape
        f = max(1, math.ceil(max(H, W) / cfg.search_max_side_px))
        ws, hs = W // f, H // f
        if min(ws, hs) < 16:
            return None
        small = (
            gray if f == 1 else cv2.resize(gray[: hs * f, : ws * f], (ws, hs), interpolation=cv2.INTER_AREA)
        )
        n, row, x0, x1, root, area, runs_per_row = _dark_runs(
            small, float(cfg.min_contrast), float(cfg.dark_fraction)
        )
        if n == 0:
            return None
        min_area = self._area_per_bar2 * (cfg.min_bar_px / f) ** 2
        roots = np.flatnonzero(
            (root == np.arange(n, dtype=np.int32)) & (area >= min_area) & (runs_per_row <= 2200)
        )
        if roots.size == 0:
            return None
        roots = roots[np.argsort(-area[roots], kind="stable")][: cfg.max_candidates]
        for r in roots:
            obs = self._candidate(gray, row, x0, x1, root, int(r), int(area[r]), f, ws, hs, t)
            if obs is not None:
                return obs
        return None

    # ------------------------------------------------------------------------------------ stages

    def _candidate(
        self,
        gray: U8Array,
        row: NDArray[np.int32],
        x0: NDArray[np.int32],
        x1: NDArray[np.int32],
        root: NDArray[np.int32],
        r: int,
        area: int,
        f: int,
        ws: int,
        hs: int,
        t: float,
    ) -> Observation | None:
        cfg = self.config
        # 3. outline of the component (closed along the image edge by the mask's frame of 0)
        mask, ox, oy = _paint_bbox(row, x0, x1, root, r)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        if not contours:
            return None
        c = max(contours, key=len)
        eps = float(np.clip(0.03 * math.sqrt(area), 1.0, 6.0))
        poly = cv2.approxPolyDP(c, eps, True).reshape(-1, 2).astype(np.float64) + (ox, oy)
        if poly.shape[0] < 6 or poly.shape[0] > 80:
            return None
        # 4-5. corners, topology, labels; chamfers shorter than a third of the bar width (as estimated
        # from the area: an underestimate when the image cuts the cross) are merged into one corner
        min_edge = max(2.5 * eps, 0.35 * math.sqrt(area / self._area_per_bar2))
        ok, inner_s, outer_s, has_outer = _cross_corners(poly, ws, hs, min_edge, self._cos_lo, self._cos_hi)
        if not ok:
            return None
        ok, start, idx, win, bar_px = _prepare(
            inner_s, outer_s, has_outer, f, gray.shape[1], gray.shape[0], float(cfg.min_bar_px)
        )
        if not ok:
            return None
        # 6. sub-pixel corners
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 20, 0.01)
        ref = cv2.cornerSubPix(gray, start.copy(), (win, win), (-1, -1), crit)
        # 7. homography (outer corners off it dropped) and pattern
        ok, keep, frac = _verify(
            gray,
            start,
            ref,
            idx,
            self._corners_xy,
            win,
            f,
            bar_px,
            self._sample_xy,
            self._sample_white,
            float(cfg.min_contrast),
            float(cfg.max_dark_ratio),
            float(cfg.min_pattern_fraction),
        )
        if not ok:
            return None
        pixels = ref.reshape(-1, 2)[keep].astype(np.float64)
        n_pts = pixels.shape[0]
        kind = "cross" if n_pts == 12 else "cross_close"
        quality = min(1.0, frac * (0.5 + 0.5 * n_pts / 12.0))
        return Observation(
            t=t, kind=kind, quality=quality, pixels=pixels, points_P=self._corners_P[idx[keep]]
        )


__all__ = ["CloseRangeConfig", "CloseRangeCrossDetector"]
