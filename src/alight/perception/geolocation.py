"""Geolocation: a detection plus the vehicle's pose at the capture time -> the pad's position in W.

Paper 000 (Sec. II-B, last step): "we exploit the knowledge of the quadrotor's pose in world frame {W}
to transform the position of the ground platform from frame {B} to {W}". With the camera mount
(``p_WC = p_WB + R_WB p_BC``, ``R_WC = R_WB R_BC``):

    p_WP = p_WC + R_WC p_CP                                                         (1)

Covariance (first order), with the PnP covariance of ``p_CP`` and the ego pose uncertainty as isotropic
position noise ``sigma_p`` (m) and a small attitude error ``delta_theta`` (rad, in W) of standard
deviation ``sigma_att`` per axis, since
``d(R_WC p_CP) = [delta_theta]x R_WC p_CP = -[R_WC p_CP]x delta_theta``:

    Sigma_WP = R_WC Sigma_CP R_WC^T + sigma_p^2 I + sigma_att^2 [r]x [r]x^T,   r = R_WC p_CP   (2)

The yaw of the pad's x axis in W comes from ``R_WP = R_WC R_CP``; its variance from the PnP rotation
covariance (gradient by central differences) plus ``sigma_att^2``. A pad that is symmetric under
rotations by ``2 pi / yaw_fold`` (the Falanga tag: ``yaw_fold = 4``) only gives the yaw modulo that
angle; it is then reported in ``[-pi / yaw_fold, pi / yaw_fold)``, and a consumer must treat it so.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from alight.cameras.pinhole import CameraMount, camera_pose_W
from alight.numerics.rotation import wrap_period
from alight.perception.pnp import PinholeIntrinsics, PnpResult, solve_pnp
from alight.types import FloatArray, Observation, PlatformMeasurement, yaw_of


def skew(v: FloatArray) -> FloatArray:
    """Cross-product matrix ``[v]x`` of a 3-vector."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def wrap_yaw(yaw: float, fold: int) -> float:
    """``yaw`` modulo ``2 pi / fold``, in ``[-pi / fold, pi / fold)``."""
    return wrap_period.py_func(yaw, 2.0 * math.pi / fold)


def world_covariance(
    R_WC: FloatArray, p_CP: FloatArray, cov_p_CP: FloatArray, sigma_p_m: float, sigma_att_rad: float
) -> FloatArray:
    """Eq. (2): the covariance of ``p_WP`` (m^2), (3, 3), symmetric."""
    r = R_WC @ p_CP
    S = skew(r)
    cov = R_WC @ cov_p_CP @ R_WC.T + sigma_p_m**2 * np.eye(3) + sigma_att_rad**2 * (S @ S.T)
    return 0.5 * (cov + cov.T)


def _check_sigmas(**kw: float) -> None:
    for name, v in kw.items():
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be finite and >= 0, got {v}")


def _check_pose(p_WB: FloatArray, R_WB: FloatArray) -> tuple[FloatArray, FloatArray]:
    p = np.asarray(p_WB, dtype=np.float64)
    R = np.asarray(R_WB, dtype=np.float64)
    if p.shape != (3,) or R.shape != (3, 3) or not (np.isfinite(p).all() and np.isfinite(R).all()):
        raise ValueError(f"need a finite p_WB (3,) and R_WB (3, 3), got shapes {p.shape} and {R.shape}")
    return p, R


class PnpGeolocator:
    """Observation with image points and pad points -> PnP -> pad position (and yaw) in W.

    Parameters
    ----------
    camera:
        Pinhole camera model (``K`` and ``dist``), the one the image came from.
    mount:
        Camera mount on the body (:class:`alight.cameras.CameraMount`).
    sigma_px:
        Pixel noise standard deviation for the PnP covariance (px).
    sigma_ego_pos_m, sigma_ego_att_rad:
        Standard deviations of the ego position (m) and attitude (rad, per axis) at the capture time,
        added to the covariance by eq. (2).
    yaw_fold:
        Rotational symmetry of the pad (1: the yaw is unambiguous; 4: the Falanga tag).
    max_reprojection_px:
        PnP solutions with a larger RMS reprojection error are rejected (``locate`` returns None).
    """

    def __init__(
        self,
        camera: PinholeIntrinsics,
        mount: CameraMount,
        sigma_px: float = 1.0,
        sigma_ego_pos_m: float = 0.0,
        sigma_ego_att_rad: float = 0.0,
        yaw_fold: int = 1,
        max_reprojection_px: float = 5.0,
    ) -> None:
        _check_sigmas(sigma_ego_pos_m=sigma_ego_pos_m, sigma_ego_att_rad=sigma_ego_att_rad)
        if not (math.isfinite(sigma_px) and sigma_px > 0):
            raise ValueError(f"sigma_px must be finite and positive, got {sigma_px}")
        if int(yaw_fold) != yaw_fold or yaw_fold < 1:
            raise ValueError(f"yaw_fold must be a positive integer, got {yaw_fold}")
        if not max_reprojection_px > 0:
            raise ValueError(f"max_reprojection_px must be positive, got {max_reprojection_px}")
        self.camera = camera
        self.mount = mount
        self.sigma_px = float(sigma_px)
        self.sigma_ego_pos_m = float(sigma_ego_pos_m)
        self.sigma_ego_att_rad = float(sigma_ego_att_rad)
        self.yaw_fold = int(yaw_fold)
        self.max_reprojection_px = float(max_reprojection_px)

    def solve(self, obs: Observation) -> PnpResult | None:
        """The PnP pose of the pad in C for an observation with ``points_P`` (None without them, with
        fewer than 4 points, or with a reprojection error above ``max_reprojection_px``)."""
        if obs.points_P is None or obs.pixels.shape[0] < 4:
            return None
        res = solve_pnp(obs.pixels, obs.points_P, self.camera, self.sigma_px)
        if res is None or not res.reprojection_rms_px <= self.max_reprojection_px:
            return None
        return res

    def locate(self, obs: Observation, p_WB: FloatArray, R_WB: FloatArray) -> PlatformMeasurement | None:
        """Pad centre (and yaw) in W from one observation and the ego pose (p_WB (3,) m, R_WB (3, 3)) at
        the observation's capture time. Observations that carry ``p_CP`` but no pad points go through
        :class:`DirectGeolocator`'s path. None when there is nothing to locate."""
        p_WB, R_WB = _check_pose(p_WB, R_WB)
        res = self.solve(obs)
        if res is None:
            if obs.p_CP is None:
                return None
            return DirectGeolocator(self.mount, self.sigma_ego_pos_m, self.sigma_ego_att_rad).locate(
                obs, p_WB, R_WB
            )
        p_WC, R_WC = camera_pose_W(p_WB, R_WB, self.mount)
        p_WP = p_WC + R_WC @ res.p_CP
        cov = world_covariance(R_WC, res.p_CP, res.cov_p_CP, self.sigma_ego_pos_m, self.sigma_ego_att_rad)
        yaw, yaw_var = self._yaw(R_WC, res)
        n_WP, cov_n = self._normal(R_WC, res)
        return PlatformMeasurement(
            t=obs.t, p_WP=p_WP, cov_p_WP=cov, yaw=yaw, yaw_var=yaw_var, n_WP=n_WP, cov_n_WP=cov_n
        )

    def _normal(self, R_WC: FloatArray, res: PnpResult) -> tuple[FloatArray, FloatArray]:
        """The pad's normal in W, ``R_WC R_CP e_z``, and its covariance (3, 3): the PnP rotation's
        covariance through the Jacobian (central differences in the Rodrigues vector) plus the ego
        attitude's ``sigma_att^2`` across the normal (a small rotation moves it perpendicular to itself)."""

        def normal_of_rvec(rvec: FloatArray) -> FloatArray:
            R_CP, _ = cv2.Rodrigues(rvec)
            out: FloatArray = R_WC @ R_CP[:, 2]
            return out

        n = R_WC @ res.R_CP[:, 2]
        n = n / float(np.linalg.norm(n))
        J = np.zeros((3, 3))
        h = 1e-6
        for k in range(3):
            d = np.zeros(3)
            d[k] = h
            J[:, k] = (normal_of_rvec(res.rvec + d) - normal_of_rvec(res.rvec - d)) / (2 * h)
        cov = J @ res.cov_pose[:3, :3] @ J.T + self.sigma_ego_att_rad**2 * (np.eye(3) - np.outer(n, n))
        return n, 0.5 * (cov + cov.T)

    def _yaw(self, R_WC: FloatArray, res: PnpResult) -> tuple[float, float]:
        """Yaw of the pad x axis in W (wrapped by ``yaw_fold``) and its variance (rad^2)."""

        def yaw_of_rvec(rvec: FloatArray) -> float:
            R_CP, _ = cv2.Rodrigues(rvec)
            return yaw_of(R_WC @ R_CP)

        yaw = yaw_of(R_WC @ res.R_CP)
        g = np.zeros(3)
        h = 1e-6
        for k in range(3):
            d = np.zeros(3)
            d[k] = h
            g[k] = math.remainder(yaw_of_rvec(res.rvec + d) - yaw_of_rvec(res.rvec - d), 2 * math.pi) / (
                2 * h
            )
        var = float(g @ res.cov_pose[:3, :3] @ g) + self.sigma_ego_att_rad**2
        return wrap_yaw(yaw, self.yaw_fold), var


class DirectGeolocator:
    """Observations that already carry ``p_CP`` (the ground-truth sensor, a detector that solves its own
    pose) -> pad position in W by eq. (1)-(2).

    ``default_sigma_m`` (m, per axis) stands in for a missing ``cov_p_CP``. The yaw, when the observation
    has ``yaw_CP``, assumes a level pad: ``yaw_CP`` is read as the angle ``atan2(y_C, x_C)`` of the pad's
    x axis in the camera's image plane, and the W heading is the horizontal direction that projects onto
    that angle.
    """

    def __init__(
        self,
        mount: CameraMount,
        sigma_ego_pos_m: float = 0.0,
        sigma_ego_att_rad: float = 0.0,
        default_sigma_m: float = 0.05,
    ) -> None:
        _check_sigmas(sigma_ego_pos_m=sigma_ego_pos_m, sigma_ego_att_rad=sigma_ego_att_rad)
        if not (math.isfinite(default_sigma_m) and default_sigma_m > 0):
            raise ValueError(f"default_sigma_m must be finite and positive, got {default_sigma_m}")
        self.mount = mount
        self.sigma_ego_pos_m = float(sigma_ego_pos_m)
        self.sigma_ego_att_rad = float(sigma_ego_att_rad)
        self.default_sigma_m = float(default_sigma_m)

    def locate(self, obs: Observation, p_WB: FloatArray, R_WB: FloatArray) -> PlatformMeasurement | None:
        """Pad centre in W from ``obs.p_CP`` and the ego pose at the capture time; None without ``p_CP``."""
        p_WB, R_WB = _check_pose(p_WB, R_WB)
        if obs.p_CP is None or not np.isfinite(obs.p_CP).all():
            return None
        p_WC, R_WC = camera_pose_W(p_WB, R_WB, self.mount)
        cov_CP = obs.cov_p_CP if obs.cov_p_CP is not None else self.default_sigma_m**2 * np.eye(3)
        p_WP = p_WC + R_WC @ obs.p_CP
        cov = world_covariance(R_WC, obs.p_CP, cov_CP, self.sigma_ego_pos_m, self.sigma_ego_att_rad)
        yaw = None
        if obs.yaw_CP is not None and math.isfinite(obs.yaw_CP):
            yaw = level_pad_yaw(R_WC, obs.yaw_CP)
        return PlatformMeasurement(t=obs.t, p_WP=p_WP, cov_p_WP=cov, yaw=yaw, yaw_var=None)


def level_pad_yaw(R_WC: FloatArray, yaw_CP: float) -> float | None:
    """W heading of a level pad whose x axis appears at angle ``yaw_CP`` (atan2(y, x) in the camera's
    x-y plane): the horizontal direction in the plane spanned by that image direction and the optical
    axis. None when that plane is horizontal (the optical axis is horizontal and along the direction)."""
    u_C = np.array([math.cos(yaw_CP), math.sin(yaw_CP), 0.0])
    n_W = R_WC @ np.cross(u_C, np.array([0.0, 0.0, 1.0]))
    h_W = np.cross(n_W, np.array([0.0, 0.0, 1.0]))
    if np.linalg.norm(h_W) < 1e-9:
        return None
    if float((R_WC.T @ h_W) @ u_C) < 0:
        h_W = -h_W
    return math.atan2(float(h_W[1]), float(h_W[0]))


__all__ = ["DirectGeolocator", "PnpGeolocator", "level_pad_yaw", "skew", "world_covariance", "wrap_yaw"]


def pad_centre_pixel(obs: Observation) -> FloatArray | None:
    """The pixel of the pad's centre in an observation, for an estimator that measures one pixel.

    A blob (no pad points) is its own centre: ``pixels[0]``. With four or more points on the pad's plane
    the centre is mapped through their homography (DLT, the image's lens distortion neglected over the
    pad, which is what a single pixel measurement of the centre does anyway); a point at the centre is
    taken as it is. None when the observation has no pixel."""
    px = obs.pixels
    if px.shape[0] == 0:
        return None
    pts = obs.points_P
    if pts is None or pts.shape[0] < 4:
        if pts is not None:
            at_centre = np.flatnonzero(np.linalg.norm(pts[:, :2], axis=1) < 1e-9)
            if at_centre.size:
                return np.asarray(px[at_centre[0]], dtype=np.float64)
        return np.asarray(px[0], dtype=np.float64)
    x, y = pts[:, 0], pts[:, 1]
    u, v = px[:, 0], px[:, 1]
    n = pts.shape[0]
    A = np.zeros((2 * n, 9))
    A[0::2, 0], A[0::2, 1], A[0::2, 2] = x, y, 1.0
    A[0::2, 6], A[0::2, 7], A[0::2, 8] = -u * x, -u * y, -u
    A[1::2, 3], A[1::2, 4], A[1::2, 5] = x, y, 1.0
    A[1::2, 6], A[1::2, 7], A[1::2, 8] = -v * x, -v * y, -v
    H = np.linalg.svd(A)[2][-1].reshape(3, 3)
    if abs(H[2, 2]) < 1e-12 or not np.isfinite(H).all():
        return np.asarray(px[0], dtype=np.float64)
    return np.array([H[0, 2] / H[2, 2], H[1, 2] / H[2, 2]])
