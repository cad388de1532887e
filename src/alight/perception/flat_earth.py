"""Flat-earth geolocation of paper 003 (Kim et al., Sec. III-B, eq. 5-9): one pixel, the camera's attitude
and its height above the target's plane -> the target's position.

The paper writes the fisheye model as ``s R_N^C x_CT = [u, v, f(u, v)]^T`` (eq. 5): the vector
``p = [u, v, f(rho)]`` is the ray through pixel (u, v) in the camera frame (eq. 2-4), ``R_N^C`` rotates
navigation-frame (NED) vectors into the camera frame, ``x_CT = [x, y, H]`` is the target relative to
the camera in NED and ``s`` a scale. With ``M = (R_N^C)^-1`` and ``H`` known ("flat earth": the height of
the camera above the ground), the third row fixes the scale (eq. 7, ``s = (M_3 . p) / H``) and

    x = H (M_1 . p) / (M_3 . p),   y = H (M_2 . p) / (M_3 . p).                         (8, 9)

(Eq. 8 and 9 as printed drop the factor ``H``; it follows from eq. 6 and 7.) Here the ray comes from any
:class:`alight.cameras.CameraModel`'s ``unproject`` (pinhole, or the omnidirectional model whose
``unproject`` is exactly ``[u, v, f(rho)]`` normalised), ``d = R_WC ray_C`` is ``M p`` in alight's world
frame W (ENU, z up, so the target is at ``-H`` in z) and

    p_CT = -H d / d_z,   p_WP = p_WC + p_CT,                                              (5-9)

valid for rays pointing down (``d_z < 0``); a ray at or above the horizon, or more than
``max_nadir_angle_rad`` from straight down, does not meet the plane usefully and gives None.

**Height source.** The paper takes H as the UAV's altitude above the ground ("the relative altitude of
the UAV from the ground becomes the position difference between the UAV and the target in vertical
direction", Sec. III-B), i.e. the target lies on the ground. alight's target is a pad on a moving
platform's deck, so ``H = p_WC[2] - deck_height_m`` with the deck's height above the world origin a
parameter (the camera's height from the ego estimate at the capture time, the deck's from the scenario).
The result's z is therefore ``deck_height_m`` exactly.

**Covariance** (first order). The inputs are the measured pixel (noise ``sigma_px`` per axis), a small
attitude error ``delta_theta`` in W (``sigma_att_rad`` per axis; ``d -> d + delta_theta x d``, as in
:mod:`alight.perception.geolocation`), the height (``sigma_height_m``) and the ego's horizontal position
(``sigma_ego_pos_m`` per axis). With ``p_CT = -H d / d_z``:

    dp/dd = -(H / d_z) (I - d e_z^T / d_z),   dp/d(delta_theta) = -(dp/dd) [d]x,   dp/dH = p_CT / H,
    dp/d(px) = (dp/dd) R_WC d(ray_C)/d(px)   (central differences through ``unproject``),

    Sigma = J_px J_px^T sigma_px^2 + J_att J_att^T sigma_att^2 + J_H J_H^T sigma_H^2
            + diag(sigma_ego^2, sigma_ego^2, 0).

``sigma_height_m`` is the uncertainty of ``H`` relative to the ego's own altitude, i.e. of the deck's
height under the vehicle: the result's z (``p_WC[2] - H``) moves by ``-dH`` with it (``J_H`` has z
component -1) and the horizontal position by ``p_CT / H``. (An error of the ego's altitude itself shifts
the vehicle and the target alike and is the ego estimator's business.) A test compares ``Sigma`` with
Monte Carlo.
"""

from __future__ import annotations

import math

import numpy as np

from alight.cameras import CameraModel
from alight.cameras.pinhole import CameraMount, camera_pose_W
from alight.perception.geolocation import skew
from alight.types import FloatArray, Observation, PlatformMeasurement

_E_Z = np.array([0.0, 0.0, 1.0])


def ground_intersection(d_W: FloatArray, H: float, min_cos: float = 0.0) -> FloatArray | None:
    """Eq. 5-9: the point ``-H d / d_z`` (m, relative to the camera, in W) where the ray direction
    ``d_W`` (3,) (any length) meets the plane ``H`` (m, > 0) below the camera. None when the ray does not
    point down by more than ``min_cos`` (the cosine of its angle from straight down)."""
    n = math.sqrt(float(d_W @ d_W))
    if not (n > 0 and H > 0 and math.isfinite(H)) or not (-d_W[2] > min_cos * n):
        return None
    p: FloatArray = -H * d_W / d_W[2]  # an ndarray element is typed Any
    return p


def flat_earth_jacobians(d_W: FloatArray, H: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """For ``p = -H d / d_z``: ``dp/dd`` (3, 3), ``dp/d(delta_theta)`` (3, 3) for an attitude error in W
    (``d -> d + delta_theta x d``) and ``dp/dH`` (3,)."""
    dz = d_W[2]
    J_d = -(H / dz) * (np.eye(3) - np.outer(d_W, _E_Z) / dz)
    J_att = -J_d @ skew(d_W)
    J_H = -d_W / dz
    return J_d, J_att, J_H


class FlatEarthGeolocator:
    """Pixel + attitude + height -> target position in W (paper 003 eq. 5-9); see the module docstring.

    Parameters
    ----------
    camera:
        Any :class:`alight.cameras.CameraModel` (``unproject(pixels (N, 2)) -> rays (N, 3)``).
    mount:
        Camera mount on the body.
    deck_height_m:
        Height of the target's plane (the platform's deck) in W (m); ``H = p_WC[2] - deck_height_m``.
    sigma_px:
        Pixel noise of the measured point (px, per axis).
    sigma_att_rad:
        Attitude error of the ego estimate (rad, per axis).
    sigma_height_m:
        Error of the height H (m) of the camera above the deck (see the module docstring).
    sigma_ego_pos_m:
        Horizontal error of the ego position (m, per axis).
    max_nadir_angle_rad:
        Rays further than this from straight down give None (at 85 deg the range is 11 H).
    pixel_step:
        Step (px) of the central differences through ``unproject``.
    """

    def __init__(
        self,
        camera: CameraModel,
        mount: CameraMount,
        *,
        deck_height_m: float = 0.0,
        sigma_px: float = 2.0,
        sigma_att_rad: float = 0.01,
        sigma_height_m: float = 0.1,
        sigma_ego_pos_m: float = 0.0,
        max_nadir_angle_rad: float = math.radians(85.0),
        pixel_step: float = 0.05,
    ) -> None:
        if not isinstance(camera, CameraModel):
            raise ValueError(
                f"camera must be a CameraModel (unproject(pixels) -> rays), got {type(camera).__name__}"
            )
        for name, v in (
            ("sigma_px", sigma_px),
            ("sigma_att_rad", sigma_att_rad),
            ("sigma_height_m", sigma_height_m),
            ("sigma_ego_pos_m", sigma_ego_pos_m),
        ):
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")
        if not math.isfinite(deck_height_m):
            raise ValueError(f"deck_height_m must be finite, got {deck_height_m}")
        if not (0 < max_nadir_angle_rad < math.pi / 2):
            raise ValueError(f"max_nadir_angle_rad must be in (0, pi/2), got {max_nadir_angle_rad}")
        if not (math.isfinite(pixel_step) and pixel_step > 0):
            raise ValueError(f"pixel_step must be finite and > 0, got {pixel_step}")
        self.camera = camera
        self.mount = mount
        self.deck_height_m = float(deck_height_m)
        self.sigma_px = float(sigma_px)
        self.sigma_att_rad = float(sigma_att_rad)
        self.sigma_height_m = float(sigma_height_m)
        self.sigma_ego_pos_m = float(sigma_ego_pos_m)
        self.max_nadir_angle_rad = float(max_nadir_angle_rad)
        self._min_cos = math.cos(max_nadir_angle_rad)
        self.pixel_step = float(pixel_step)

    def relative_position(
        self, px: FloatArray, R_WC: FloatArray, H: float
    ) -> tuple[FloatArray, FloatArray] | None:
        """Target relative to the camera in W (m), (3,), and its covariance (3, 3) for the pixel ``px``
        (u, v), camera attitude ``R_WC`` and height ``H`` (m) above the target's plane; None when the ray
        misses the plane (or the camera model has no ray there)."""
        px = np.asarray(px, dtype=np.float64).ravel()
        if px.shape != (2,) or not np.isfinite(px).all() or not (H > 0 and math.isfinite(H)):
            return None
        h = self.pixel_step
        q = np.array([px, px + (h, 0.0), px - (h, 0.0), px + (0.0, h), px - (0.0, h)])
        rays = np.asarray(self.camera.unproject(q), dtype=np.float64)
        if rays.shape != (5, 3) or not np.isfinite(rays[0]).all():
            return None
        d = R_WC @ rays[0]
        p = ground_intersection(d, H, self._min_cos)
        if p is None:
            return None
        J_d, J_att, J_H = flat_earth_jacobians(d, H)
        J_px = np.empty((3, 2))
        for k in range(2):
            plus, minus = rays[1 + 2 * k], rays[2 + 2 * k]
            # the rays are unit: difference them at unit length, one-sided at the edge of the model
            if np.isfinite(plus).all() and np.isfinite(minus).all():
                dr = (plus - minus) / (2 * h)
            elif np.isfinite(plus).all():
                dr = (plus - rays[0]) / h
            elif np.isfinite(minus).all():
                dr = (rays[0] - minus) / h
            else:
                return None
            J_px[:, k] = J_d @ (R_WC @ dr)
        cov = (
            self.sigma_px**2 * (J_px @ J_px.T)
            + self.sigma_att_rad**2 * (J_att @ J_att.T)
            + self.sigma_height_m**2 * np.outer(J_H, J_H)
        )
        cov[0, 0] += self.sigma_ego_pos_m**2
        cov[1, 1] += self.sigma_ego_pos_m**2
        return p, 0.5 * (cov + cov.T)

    def locate(self, obs: Observation, p_WB: FloatArray, R_WB: FloatArray) -> PlatformMeasurement | None:
        """Target position in W from the observation's pixel (its single point; the mean of its points
        when it has several) and the ego pose at the capture time. None without pixels, with the camera
        at or below the deck, or when the ray misses the plane."""
        p_WB = np.asarray(p_WB, dtype=np.float64)
        R_WB = np.asarray(R_WB, dtype=np.float64)
        if (
            p_WB.shape != (3,)
            or R_WB.shape != (3, 3)
            or not (np.isfinite(p_WB).all() and np.isfinite(R_WB).all())
        ):
            raise ValueError(f"need a finite p_WB (3,) and R_WB (3, 3), got {p_WB.shape} and {R_WB.shape}")
        if obs.pixels.shape[0] == 0:
            return None
        px = obs.pixels[0] if obs.pixels.shape[0] == 1 else obs.pixels.mean(axis=0)
        p_WC, R_WC = camera_pose_W(p_WB, R_WB, self.mount)
        H = float(p_WC[2] - self.deck_height_m)
        res = self.relative_position(px, R_WC, H)
        if res is None:
            return None
        p_CT, cov = res
        cov = cov.copy()
        if cov[2, 2] <= 0.0:
            # sigma_height_m = 0: z is exact; keep the covariance positive definite for the filters
            cov[2, 2] = 1e-12
        return PlatformMeasurement(t=obs.t, p_WP=p_WC + p_CT, cov_p_WP=cov)


__all__ = ["FlatEarthGeolocator", "flat_earth_jacobians", "ground_intersection"]
