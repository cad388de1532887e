"""Plane-to-plane homographies from point pairs, compiled with numba: the exact 4-point solution, the
least-squares normalised DLT and RANSAC. One implementation for the Falanga tag detector (ring and cross
correspondences, :mod:`alight.perception.falanga_tag`) and its close-range cross detector
(:mod:`alight.perception.falanga_close`).

A homography ``H`` (3, 3) maps ``(x, y)`` to ``((H [x, y, 1])_0 / w, (H [x, y, 1])_1 / w)`` with
``w = (H [x, y, 1])_2`` (Hartley and Zisserman, *Multiple View Geometry*, 2nd ed., eq. 2.1 / 4.1).
It is fixed here by ``h33 = 1``: the 8 remaining entries solve ``A h = b`` (two rows per pair,
H&Z eq. 4.3 with ``h33`` moved to the right-hand side). That excludes homographies with ``h33 = 0`` (the
origin of the source plane mapped to infinity), which a camera looking at a pad in front of it never
produces, and keeps every solve a small dense one (no SVD, whose per-call cost dominates at this size).
The least-squares fit is on Hartley-normalised points (H&Z Alg. 4.2: centroid at 0, mean distance
sqrt 2), which makes the normal equations well conditioned.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def apply_homography(H, xy):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Homography applied to points (N, 2) -> (N, 2) (NaN where the point maps to infinity)."""
    out = np.empty((xy.shape[0], 2))
    for k in range(xy.shape[0]):
        x = xy[k, 0]
        y = xy[k, 1]
        wz = H[2, 0] * x + H[2, 1] * y + H[2, 2]
        if abs(wz) < 1e-12:
            out[k, 0] = np.nan
            out[k, 1] = np.nan
        else:
            out[k, 0] = (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / wz
            out[k, 1] = (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / wz
    return out


@numba.njit(cache=True)
def solve_small(A, b):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Gaussian elimination with partial pivoting for a small dense system (no LAPACK call, whose
    per-call cost dominates at this size); (ok, x). A and b are overwritten."""
    n = b.shape[0]
    for c in range(n):
        p = c
        for r in range(c + 1, n):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if not abs(A[p, c]) > 1e-12:
            return False, b
        if p != c:
            for k in range(n):
                A[c, k], A[p, k] = A[p, k], A[c, k]
            b[c], b[p] = b[p], b[c]
        inv = 1.0 / A[c, c]
        for r in range(c + 1, n):
            f = A[r, c] * inv
            if f != 0.0:
                for k in range(c, n):
                    A[r, k] -= f * A[c, k]
                b[r] -= f * b[c]
    x = np.empty(n)
    for r in range(n - 1, -1, -1):
        acc = b[r]
        for k in range(r + 1, n):
            acc -= A[r, k] * x[k]
        x[r] = acc / A[r, r]
    for r in range(n):
        if not np.isfinite(x[r]):
            return False, x
    return True, x


@numba.njit(cache=True)
def homography_4pt(src, dst, i0, i1, i2, i3):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Exact homography from 4 point pairs (h33 = 1); (ok, H)."""
    A = np.zeros((8, 8))
    b = np.zeros(8)
    idx = (i0, i1, i2, i3)
    for r in range(4):
        k = idx[r]
        x, y = src[k, 0], src[k, 1]
        u, v = dst[k, 0], dst[k, 1]
        A[2 * r, 0] = x
        A[2 * r, 1] = y
        A[2 * r, 2] = 1.0
        A[2 * r, 6] = -u * x
        A[2 * r, 7] = -u * y
        A[2 * r + 1, 3] = x
        A[2 * r + 1, 4] = y
        A[2 * r + 1, 5] = 1.0
        A[2 * r + 1, 6] = -v * x
        A[2 * r + 1, 7] = -v * y
        b[2 * r] = u
        b[2 * r + 1] = v
    H = np.eye(3)
    ok, h = solve_small(A, b)
    if not ok:
        return False, H
    for k in range(8):
        H[k // 3, k % 3] = h[k]
    return True, H


@numba.njit(cache=True)
def hartley_normalizer(p, mask):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Hartley normalisation of the masked points (centroid to 0, mean distance sqrt 2): (s, cx, cy)."""
    cx = cy = 0.0
    m = 0
    for k in range(p.shape[0]):
        if mask[k]:
            cx += p[k, 0]
            cy += p[k, 1]
            m += 1
    cx /= m
    cy /= m
    d = 0.0
    for k in range(p.shape[0]):
        if mask[k]:
            d += np.hypot(p[k, 0] - cx, p[k, 1] - cy)
    d /= m
    return np.sqrt(2.0) / max(d, 1e-12), cx, cy


@numba.njit(cache=True)
def homography_lsq(src, dst, mask):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Least-squares homography of the masked point pairs: the DLT on Hartley-normalised points with
    h33 = 1 (its normal equations, 8x8), denormalised; (ok, H). Not ok with fewer than 4 pairs."""
    m = 0
    for k in range(mask.shape[0]):
        if mask[k]:
            m += 1
    if m < 4:
        return False, np.eye(3)
    ss, sx, sy = hartley_normalizer(src, mask)
    sd, dx, dy = hartley_normalizer(dst, mask)
    M = np.zeros((8, 8))
    rhs = np.zeros(8)
    a = np.zeros(8)
    for k in range(src.shape[0]):
        if not mask[k]:
            continue
        x = ss * (src[k, 0] - sx)
        y = ss * (src[k, 1] - sy)
        u = sd * (dst[k, 0] - dx)
        v = sd * (dst[k, 1] - dy)
        for r in range(2):
            a[:] = 0.0
            if r == 0:
                a[0] = x
                a[1] = y
                a[2] = 1.0
                a[6] = -u * x
                a[7] = -u * y
                t = u
            else:
                a[3] = x
                a[4] = y
                a[5] = 1.0
                a[6] = -v * x
                a[7] = -v * y
                t = v
            for i in range(8):
                rhs[i] += a[i] * t
                for j in range(8):
                    M[i, j] += a[i] * a[j]
    ok, h = solve_small(M, rhs)
    if not ok:
        return False, np.eye(3)
    Hn = np.array([[h[0], h[1], h[2]], [h[3], h[4], h[5]], [h[6], h[7], 1.0]])
    Ts = np.array([[ss, 0.0, -ss * sx], [0.0, ss, -ss * sy], [0.0, 0.0, 1.0]])
    Td_inv = np.array([[1.0 / sd, 0.0, dx], [0.0, 1.0 / sd, dy], [0.0, 0.0, 1.0]])
    H = Td_inv @ Hn @ Ts
    if abs(H[2, 2]) < 1e-15 or not np.isfinite(H).all():
        return False, np.eye(3)
    return True, H / H[2, 2]


@numba.njit(cache=True)
def homography_inliers(H, src, dst, thr2):  # type: ignore[no-untyped-def]  # pragma: no cover
    n = src.shape[0]
    mask = np.zeros(n, np.bool_)
    cnt = 0
    for k in range(n):
        x, y = src[k, 0], src[k, 1]
        wz = H[2, 0] * x + H[2, 1] * y + H[2, 2]
        if abs(wz) < 1e-12:
            continue
        u = (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / wz - dst[k, 0]
        v = (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / wz - dst[k, 1]
        if u * u + v * v <= thr2:
            mask[k] = True
            cnt += 1
    return mask, cnt


@numba.njit(cache=True)
def ransac_homography(src, dst, thr, max_iters):  # type: ignore[no-untyped-def]  # pragma: no cover
    """RANSAC homography (Fischler and Bolles 1981) from point pairs (N, 2) -> (N, 2): minimal 4-point
    samples drawn by a fixed-seed xorshift generator (so a detection is a pure function of the image), the
    adaptive number of iterations for 99.5 % confidence, then a least-squares fit on the inliers,
    repeated once on the inliers of that fit if they changed. Returns (ok, H, inlier mask)."""
    n = src.shape[0]
    best_mask = np.zeros(n, np.bool_)
    if n < 4:
        return False, np.eye(3), best_mask
    thr2 = thr * thr
    best_cnt = 0
    state = np.uint64(0x9E3779B97F4A7C15)
    need = max_iters
    it = 0
    while it < need:
        it += 1
        idx = np.empty(4, np.int64)
        for r in range(4):
            while True:
                state ^= state << np.uint64(13)
                state ^= state >> np.uint64(7)
                state ^= state << np.uint64(17)
                c = np.int64(state % np.uint64(n))
                dup = False
                for r2 in range(r):
                    if idx[r2] == c:
                        dup = True
                if not dup:
                    break
            idx[r] = c
        ok, H = homography_4pt(src, dst, idx[0], idx[1], idx[2], idx[3])
        if not ok:
            continue
        mask, cnt = homography_inliers(H, src, dst, thr2)
        if cnt > best_cnt:
            best_cnt = cnt
            best_mask = mask
            w = cnt / n
            if w >= 1.0:
                need = min(need, it)
            else:
                p_good = w**4
                if p_good > 1e-9:
                    need = min(max_iters, int(np.ceil(np.log(0.005) / np.log(1.0 - p_good))))
    if best_cnt < 4:
        return False, np.eye(3), best_mask
    mask = best_mask
    H = np.eye(3)
    for _ in range(2):
        ok, H = homography_lsq(src, dst, mask)
        if not ok:
            return False, np.eye(3), best_mask
        new_mask, cnt = homography_inliers(H, src, dst, thr2)
        if cnt < 4:
            return False, H, new_mask
        same = True
        for k in range(n):
            if new_mask[k] != mask[k]:
                same = False
                break
        mask = new_mask
        if same:
            break
    return True, H, mask


@numba.njit(cache=True)
def map_point(H, x, y):  # type: ignore[no-untyped-def]  # pragma: no cover
    """One point ``(x, y)`` through ``H``; NaN where it maps to infinity (``|w| < 1e-12``)."""
    wz = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    if abs(wz) < 1e-12:
        return np.nan, np.nan
    return (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / wz, (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / wz
