"""Perspective-n-Point: the pad's pose in the camera frame from 2D-3D correspondences, with a covariance.

Paper 000 (Sec. II-B) solves PnP on the tag's corners once the metric size of the tag is known. Here:

1. ``cv2.solvePnPGeneric`` with IPPE (Collins and Bartoli, IJCV 2014) when every model point lies on the
   pad plane (z = 0, the case of every pad in alight): it returns both local minima of the planar
   problem, and the one with the smaller reprojection error is kept. Non-planar points use SQPnP.
2. Levenberg-Marquardt refinement of the reprojection error (``cv2.solvePnPRefineLM``), so that the
   result is the maximum-likelihood pose under i.i.d. Gaussian pixel noise.
3. First-order covariance of the 6 pose parameters ``(rvec, p_CP)``: ``Sigma = sigma_px^2 (J^T J)^-1``
   with ``J`` the (2N, 6) Jacobian of the projected pixels with respect to ``(rvec, tvec)``, taken from
   ``cv2.projectPoints`` (the test suite checks it against finite differences).

Frames: ``x_C = R_CP x_P + p_CP`` (OpenCV's ``tvec`` is ``p_CP``, the pad centre in the camera frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import cv2
import numpy as np

from alight.types import FloatArray


@dataclass(frozen=True, slots=True)
class PnpResult:
    """Pose of the pad frame P in the camera frame C."""

    R_CP: FloatArray
    """Rotation taking P-vectors into C, shape (3, 3)."""
    p_CP: FloatArray
    """Pad origin in C (m), shape (3,)."""
    cov_p_CP: FloatArray
    """First-order covariance of ``p_CP`` (m^2), shape (3, 3)."""
    reprojection_rms_px: float
    """Root mean square reprojection error over the points (px)."""
    rvec: FloatArray
    """Rodrigues vector of ``R_CP`` (rad), shape (3,)."""
    cov_pose: FloatArray
    """First-order covariance of ``(rvec, p_CP)``, shape (6, 6) (rad^2, rad m, m^2)."""
    n_points: int
    """Number of correspondences used."""


class PinholeIntrinsics(Protocol):
    """What PnP needs of a camera: a pinhole model's intrinsics (:class:`alight.cameras.PinholeCamera`)."""

    @property
    def K(self) -> FloatArray:
        """Camera matrix (3, 3), px."""
        ...

    @property
    def dist(self) -> FloatArray:
        """Distortion coefficients in OpenCV's order (k1, k2, p1, p2[, k3 ...]); zeros: none."""
        ...


def camera_matrices(camera: PinholeIntrinsics) -> tuple[FloatArray, FloatArray]:
    """``(K (3, 3), dist (k,))`` of a pinhole camera model."""
    K = np.asarray(camera.K, dtype=np.float64)
    if K.shape != (3, 3) or not np.isfinite(K).all():
        raise ValueError(f"camera.K must be a finite (3, 3) matrix, got shape {K.shape}")
    d = np.asarray(camera.dist, dtype=np.float64).ravel()
    if not np.isfinite(d).all():
        raise ValueError("camera.dist must be finite")
    return K, d


def project_with_jacobian(
    points_P: FloatArray, rvec: FloatArray, tvec: FloatArray, K: FloatArray, dist: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Pixels of ``points_P`` (N, 3) under the pose ``(rvec, tvec)``, shape (N, 2), and their Jacobian
    with respect to ``(rvec, tvec)``, shape (2N, 6), rows ordered (u0, v0, u1, v1, ...)."""
    px, jac = cv2.projectPoints(
        np.ascontiguousarray(points_P, dtype=np.float64).reshape(-1, 1, 3),
        np.asarray(rvec, dtype=np.float64).reshape(3, 1),
        np.asarray(tvec, dtype=np.float64).reshape(3, 1),
        K,
        dist if dist.size else None,
    )
    # float64 like the inputs (so no conversion here); OpenCV's stubs type the results MatLike, no dtype
    return np.asarray(px, dtype=np.float64).reshape(-1, 2), np.asarray(jac, dtype=np.float64)[:, :6].copy()


_Candidate = tuple[float, FloatArray, FloatArray]
"""A PnP solution: its reprojection error (px; nan when the solver gave none), ``rvec`` and ``tvec``."""


def _in_front(n_sol: int, rvecs: Any, tvecs: Any, errs: Any) -> list[_Candidate]:
    """The solver's finite solutions with the pad in front of the camera, with their errors."""
    e = np.asarray(errs, dtype=np.float64).ravel() if errs is not None else np.zeros(0)
    candidates = []
    for k in range(n_sol):
        rv = np.asarray(rvecs[k], dtype=np.float64).reshape(3, 1)
        tv = np.asarray(tvecs[k], dtype=np.float64).reshape(3, 1)
        if np.isfinite(rv).all() and np.isfinite(tv).all() and tv[2, 0] > 0:
            candidates.append((float(e[k]) if e.size == n_sol else math.nan, rv, tv))
    return candidates


def _best_refined(
    candidates: list[_Candidate],
    obj: FloatArray,
    img: FloatArray,
    K: FloatArray,
    d: FloatArray | None,
    pts: FloatArray,
    px: FloatArray,
    dist: FloatArray,
) -> _Candidate | None:
    """The candidate with the smallest RMS reprojection error after LM refinement, as (rms, rvec (3,),
    tvec (3,)).

    IPPE's two solutions (the planar ambiguity) come with their reprojection errors. Refining both costs
    half of the solve; a solution with an error over 4x (and 1 px above) the best one's in front of the
    camera is in another basin, which LM refinement (a local step) cannot turn into the better fit."""
    errors = [c[0] for c in candidates if math.isfinite(c[0])]
    e_best = min(errors) if len(errors) == len(candidates) and errors else math.inf
    best: _Candidate | None = None
    for err, rv, tv in candidates:
        if err > max(4.0 * e_best, e_best + 1.0):
            continue
        try:
            rv_lm, tv_lm = cv2.solvePnPRefineLM(obj, img, K, d, rv, tv)
            # the refined float64 rv, tv (no conversion); OpenCV's stubs type them MatLike, without the dtype
            rv, tv = np.asarray(rv_lm, dtype=np.float64), np.asarray(tv_lm, dtype=np.float64)
        except cv2.error:
            pass
        proj, _ = project_with_jacobian(pts, rv, tv, K, dist)
        rms = float(np.sqrt(np.mean(np.sum((proj - px) ** 2, axis=1))))
        if best is None or rms < best[0]:
            best = (rms, rv.ravel().copy(), tv.ravel().copy())
    return best


def solve_pnp(
    pixels: FloatArray,
    points_P: FloatArray,
    camera: PinholeIntrinsics,
    sigma_px: float = 1.0,
) -> PnpResult | None:
    """Pose of the pad in the camera frame from ``pixels`` (N, 2) seen at ``points_P`` (N, 3, m).

    ``camera`` is a pinhole model (``K`` (3, 3) and ``dist``). ``sigma_px`` is the standard
    deviation of the pixel noise used for the covariance (px). Returns None when the problem is
    degenerate (fewer than 4 points, collinear points, or a solution behind the camera).

    Raises ``ValueError`` for inconsistent shapes or non-finite values.
    """
    px = np.asarray(pixels, dtype=np.float64)
    pts = np.asarray(points_P, dtype=np.float64)
    if px.ndim != 2 or px.shape[1] != 2 or pts.shape != (px.shape[0], 3):
        raise ValueError(f"pixels must be (N, 2) and points_P (N, 3), got {px.shape} and {pts.shape}")
    if not (np.isfinite(px).all() and np.isfinite(pts).all()):
        raise ValueError("pixels and points_P must be finite")
    if not (math.isfinite(sigma_px) and sigma_px > 0):
        raise ValueError(f"sigma_px must be finite and positive, got {sigma_px}")
    K, dist = camera_matrices(camera)
    n = px.shape[0]
    if n < 4:
        return None
    # A planar target needs non-collinear points; check the spread of the model points.
    centred = pts - pts.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[1] < 1e-9 * max(sv[0], 1e-12):
        return None
    planar = bool(np.all(np.abs(pts[:, 2]) < 1e-9))
    obj = np.ascontiguousarray(pts.reshape(-1, 1, 3))
    img = np.ascontiguousarray(px.reshape(-1, 1, 2))
    d = dist if dist.size else None
    flag = cv2.SOLVEPNP_IPPE if planar else cv2.SOLVEPNP_SQPNP
    try:
        n_sol, rvecs, tvecs, errs = cv2.solvePnPGeneric(obj, img, K, d, flags=flag)
    except cv2.error:
        return None
    candidates = _in_front(int(n_sol), rvecs, tvecs, errs)
    best = _best_refined(candidates, obj, img, K, d, pts, px, dist)
    if best is None:
        return None
    rms, rvec, tvec = best
    if tvec[2] <= 0:
        return None
    _, J = project_with_jacobian(pts, rvec, tvec, K, dist)
    JtJ = J.T @ J
    try:
        cov = sigma_px**2 * np.linalg.inv(JtJ)
    except np.linalg.LinAlgError:
        return None
    cov = 0.5 * (cov + cov.T)
    if not np.isfinite(cov).all():
        return None
    R_CP, _ = cv2.Rodrigues(rvec)
    return PnpResult(
        R_CP=np.asarray(R_CP, dtype=np.float64),
        p_CP=tvec,
        cov_p_CP=cov[3:, 3:].copy(),
        reprojection_rms_px=rms,
        rvec=rvec,
        cov_pose=cov,
        n_points=n,
    )
