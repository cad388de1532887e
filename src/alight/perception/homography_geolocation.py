"""Pixel -> world by a homography built from the camera's attitude and altitude (paper 004, Sec. IV-A).

The paper's eight steps, as implemented here (the paper works in NED with an FRD body; alight's world W
is ENU and its body B is FLU, see "Frames" below):

1. The camera's pose in the vehicle's *level heading frame* ``H`` from roll and pitch only: with ``psi``
   the heading (``yaw_of(R_WB)``), ``R_WB = Rz(psi) R_tilt`` where ``R_tilt = Ry(pitch) Rx(roll)``, and
   ``R_HC = R_tilt R_BC`` (``R_BC`` the camera mount).
2. The normalised coordinates of the four image corners from the horizontal and vertical fields of view,
   ``(+-tan(hfov / 2), +-tan(vfov / 2), 1)`` in C, rotated into H by ``R_HC``.
3. Their intersection with the ground plane ``h`` metres below the camera (``h`` the camera's height
   above the plane: its altitude ``p_WC.z`` minus the plane's height ``plane_z_W``):
   ``g_i = -h r_i[:2] / r_i[2]`` in H, relative to the camera.
4. The perspective homography ``G`` from the image corners (pixels, outer pixel edges
   ``(-0.5, -0.5) ... (W - 0.5, H - 0.5)``) to those four ground points, by the closed-form
   square-to-quadrilateral map (Heckbert 1989) in float64: ``cv2.getPerspectiveTransform`` takes float32
   only (good to ~1e-3 m here) and ``cv2.findHomography`` iterates (1e-6 m); the tests compare both.
5. Pixel -> ground: ``g = G (u, v, 1)`` (dehomogenised), in H relative to the camera.
6. H -> world axes by the heading: ``g_W = Rz(psi) g``.
7. -> the landing site's frame. The paper outputs the UAV relative to the marker; alight's geolocators
   output the marker in W, ``p_W = p_WC + (g_W, -h)`` (the UAV relative to the marker is ``p_WB - p_W``).
8. Landmarks that are not the pad centre (the paper's ArUco markers, with their known offsets):
   ``p_WP = p_W - R_WP o_P`` with the landmark's offset ``o_P`` in the pad frame P and the pad's heading.

Observations (coordinated with the detectors): ``pixels`` (N, 2); ``points_P`` (N, 3), when given, are the
offsets ``o_P`` of those pixels' points on the pad. With ``points="first"`` (default) only row 0 is used:
the SDU detector (:mod:`alight.perception.sdu_marker`, kind ``sdu``) puts its fused landing-marker pixel
there with ``points_P[0] = (0, 0, 0)``, the pad centre, and appends the raw points it fused for PnP; with
``points="all"`` every row is geolocated and the centre is their mean. Without ``points_P``,
``landmark_offsets[obs.kind]`` gives the offset of a single-point observation (``"aruco:7": (0.5, 0.4)``),
and any other kind is taken as the pad centre. The pad heading ``R_WP`` that turns the offsets into W
comes, in this order, from ``obs.yaw_CP`` (the marker's orientation in the image, as
:func:`alight.perception.geolocation.level_pad_yaw` reads it), from a 2-D Procrustes fit of the ground
points to their pad points (N >= 2 distinct offsets), or from ``assume_pad_yaw``; with none of these an
observation with a non-zero offset gives None. Several points give the centre as the mean of the
per-point centres (the paper: "the mean measurements ... are used").

Frames (NED vs ENU). The method only needs the rotation split into heading and tilt and the height, so
running the steps on ENU/FLU quantities is the paper's computation written in other axes: a pose given in
NED/FRD, ``R_NF``, is ``R_WB = T R_NF D`` in alight with ``T = [[0,1,0],[1,0,0],[0,0,-1]]`` (NED -> ENU)
and ``D = diag(1, -1, -1)`` (FLU -> FRD); its z-y-x Euler angles are ``roll_FLU = roll_FRD``,
``pitch_FLU = -pitch_FRD``, ``yaw_ENU = pi/2 - yaw_NED`` (:func:`enu_flu_from_ned_frd`, tested). The paper's
altitude (down = -altitude) is ``h`` here; its north-east output ``(x_N, y_E)`` is ``(y_W, x_W)``.

Accuracy, and how it differs from exact ray casting. With the corners' rays taken from the fields of view,
steps 2-5 are exactly a ray-plane intersection for a *virtual* pinhole camera whose focal lengths are
``W / (2 tan(hfov/2))``, ``H / (2 tan(vfov/2))`` and whose principal point is the image centre
``((W-1)/2, (H-1)/2)`` (pixel -> normalised coordinates is affine and normalised -> plane is projective,
so the four corners fix the composition). Hence:

- an undistorted pinhole camera with its principal point at the image centre and these fields of view:
  the method *is* exact ray casting (the tests check 1e-9 m);
- a principal point ``delta_c`` px off the centre: every ray is off by ``delta_c / f`` rad, a ground error
  of about ``h delta_c / f`` (1 cm per px at 4 m with f = 400 px, more at oblique rays);
- lens distortion: the paper maps raw pixels linearly; with ``camera.fov_rad()`` (the real lens's edge
  angles) the error is zero on the edges' midpoints and the image centre and largest in between and at the
  corners. For ``PinholeCamera.default_downward()`` (k1 = -0.08, k2 = 0.01; its fields of view make a
  virtual camera of fx = 371, fy = 388 px where the lens has 400) looking straight down from ``h`` m:
  0.028 h a quarter of the width from the centre, 0.024 h half-way to a corner, 0.057 h at a corner (11,
  10 and 23 cm at 4 m; ``test_distortion_error_of_the_paper_method``);
  ``exact_intrinsics=True`` undistorts the pixel first and takes the corners from ``K``: exact;
- the plane's height wrong by ``dz`` (e.g. the deck height ignored: the paper uses the altitude above the
  take-off point, ``plane_z_W = 0``, while the pad is ``pad_height_m`` higher): the ground point is pushed
  radially from the camera's nadir by ``d dz / h`` (``d`` its horizontal distance from the nadir) and its
  height is off by ``dz``. Set ``plane_z_W`` to the deck height when it is known.

Covariance (first order). With ``r = R_WC (x, y, 1)`` the ray of the (virtual or undistorted) normalised
point and ``g = p_WC - h r / r_z``:

    dg/dr = M = -(h / r_z) (I - r e_z^T / r_z),   dg/dp_WC = A = I - (r / r_z) e_z^T,   dg/dz_plane = r / r_z

- pixel noise ``sigma_px``: ``J_px = M R_WC d(x, y, 1)/d(u, v)`` (``2 tan(fov/2) / size`` per pixel for the
  paper's map; the undistortion's Jacobian by central differences in exact mode);
- attitude ``sigma_att_rad`` per axis, a rotation ``delta_theta`` in W on ``R_WB``:
  ``J_att = -A [R_WB p_BC]x - M [r]x`` (the mount's lever arm moves the camera too);
- ego position: ``sigma_ego_pos_m`` on x and y, ``sigma_alt_m`` on z, through ``A``;
- the plane's height ``sigma_plane_m`` through ``r / r_z``;
- the pad heading used to rotate a landmark's offset ``o``: ``sigma_yaw_rad`` through ``e_z x R_WP o``.

Several points: the pixel terms of independent points are averaged (``/ N^2``), the common terms use the
mean Jacobian. ``test_covariance_matches_monte_carlo`` checks the whole against sampling.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from numba import njit

from alight.cameras import CameraModel
from alight.cameras.pinhole import CameraMount, PinholeCamera, camera_pose_W
from alight.perception.geolocation import _check_pose, _check_sigmas, level_pad_yaw, skew
from alight.types import FloatArray, Observation, PlatformMeasurement, rot_z, yaw_of

_HORIZON_COS = 1e-3
"""A corner ray closer to the horizon than this (|r_z| / |r|) sends its ground point to infinity; the
homography is then built from the half-size rectangle about the image centre (the same projective map)."""


# --------------------------------------------------------------------------------------------------
# Homography kernels (steps 3-5)
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _square_to_quad(q: FloatArray, H: FloatArray) -> bool:
    """Homography (3, 3) mapping the unit square's corners (0,0), (1,0), (1,1), (0,1) to ``q`` (4, 2), in
    closed form (Heckbert 1989, "Fundamentals of texture mapping", Sec. 2.2.3). False if degenerate."""
    sx = q[0, 0] - q[1, 0] + q[2, 0] - q[3, 0]
    sy = q[0, 1] - q[1, 1] + q[2, 1] - q[3, 1]
    dx1 = q[1, 0] - q[2, 0]
    dx2 = q[3, 0] - q[2, 0]
    dy1 = q[1, 1] - q[2, 1]
    dy2 = q[3, 1] - q[2, 1]
    den = dx1 * dy2 - dx2 * dy1
    scale = abs(dx1) + abs(dx2) + abs(dy1) + abs(dy2)
    if not abs(den) > 1e-14 * scale * scale:
        return False
    g = (sx * dy2 - dx2 * sy) / den
    h = (dx1 * sy - sx * dy1) / den
    H[0, 0] = q[1, 0] - q[0, 0] + g * q[1, 0]
    H[0, 1] = q[3, 0] - q[0, 0] + h * q[3, 0]
    H[0, 2] = q[0, 0]
    H[1, 0] = q[1, 1] - q[0, 1] + g * q[1, 1]
    H[1, 1] = q[3, 1] - q[0, 1] + h * q[3, 1]
    H[1, 2] = q[0, 1]
    H[2, 0] = g
    H[2, 1] = h
    H[2, 2] = 1.0
    return True


@njit(cache=True)
def _inv3(A: FloatArray, out: FloatArray) -> bool:
    a, b, c = A[0, 0], A[0, 1], A[0, 2]
    d, e, f = A[1, 0], A[1, 1], A[1, 2]
    g, h, i = A[2, 0], A[2, 1], A[2, 2]
    c00 = e * i - f * h
    c01 = f * g - d * i
    c02 = d * h - e * g
    det = a * c00 + b * c01 + c * c02
    if det == 0.0 or not math.isfinite(det):
        return False
    out[0, 0] = c00 / det
    out[0, 1] = (c * h - b * i) / det
    out[0, 2] = (b * f - c * e) / det
    out[1, 0] = c01 / det
    out[1, 1] = (a * i - c * g) / det
    out[1, 2] = (c * d - a * f) / det
    out[2, 0] = c02 / det
    out[2, 1] = (b * g - a * h) / det
    out[2, 2] = (a * e - b * d) / det
    return True


@njit(cache=True)
def _general_position(q: FloatArray) -> bool:
    """No three of the four points ``q`` (4, 2) collinear (relative to the points' spread)."""
    scale = 0.0
    for i in range(4):
        for j in range(2):
            scale = max(scale, abs(q[i, j] - q[0, j]))
    if not scale > 0.0:
        return False
    for a in range(4):
        b = (a + 1) % 4
        c = (a + 2) % 4
        cross = (q[b, 0] - q[a, 0]) * (q[c, 1] - q[a, 1]) - (q[b, 1] - q[a, 1]) * (q[c, 0] - q[a, 0])
        if not abs(cross) > 1e-12 * scale * scale:
            return False
    return True


@njit(cache=True)
def homography_4pt(src: FloatArray, dst: FloatArray, H: FloatArray) -> bool:
    """The homography ``H`` (3, 3), ``H[2, 2] = 1``, mapping four points ``src`` (4, 2) onto ``dst`` (4, 2)
    (float64, closed form: ``H = S_dst S_src^-1`` with ``S`` the unit-square maps). False when three of
    either set are collinear."""
    if not (_general_position(src) and _general_position(dst)):
        return False
    Ss = np.empty((3, 3))
    Sd = np.empty((3, 3))
    Si = np.empty((3, 3))
    if not (_square_to_quad(src, Ss) and _square_to_quad(dst, Sd) and _inv3(Ss, Si)):
        return False
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                s += Sd[i, k] * Si[k, j]
            H[i, j] = s
    n = H[2, 2]
    if n == 0.0 or not math.isfinite(n):
        return False
    for i in range(3):
        for j in range(3):
            H[i, j] /= n
    return True


@njit(cache=True)
def apply_homography(H: FloatArray, pts: FloatArray, out: FloatArray) -> None:
    """``out[i] = H (pts[i], 1)`` dehomogenised, (N, 2) -> (N, 2)."""
    for i in range(pts.shape[0]):
        u = pts[i, 0]
        v = pts[i, 1]
        w = H[2, 0] * u + H[2, 1] * v + H[2, 2]
        out[i, 0] = (H[0, 0] * u + H[0, 1] * v + H[0, 2]) / w
        out[i, 1] = (H[1, 0] * u + H[1, 1] * v + H[1, 2]) / w


@njit(cache=True)
def _ground_homography(
    R_HC: FloatArray, h: float, corners_n: FloatArray, corners_px: FloatArray, G: FloatArray
) -> int:
    """Steps 2-4: corner rays (normalised ``corners_n`` (4, 2) in C) rotated into H, intersected with the
    plane ``h`` below (``g = -h r_xy / r_z``), and the homography ``G`` from ``corners_px`` (4, 2) to them.
    Returns 0 on success, 1 when a corner ray lies on the horizon, 2 when degenerate."""
    dst = np.empty((4, 2))
    for i in range(4):
        x = corners_n[i, 0]
        y = corners_n[i, 1]
        rx = R_HC[0, 0] * x + R_HC[0, 1] * y + R_HC[0, 2]
        ry = R_HC[1, 0] * x + R_HC[1, 1] * y + R_HC[1, 2]
        rz = R_HC[2, 0] * x + R_HC[2, 1] * y + R_HC[2, 2]
        if abs(rz) < _HORIZON_COS * math.sqrt(rx * rx + ry * ry + rz * rz):
            return 1
        # a corner above the horizon lands "behind" the camera: still the same projective map
        dst[i, 0] = -h * rx / rz
        dst[i, 1] = -h * ry / rz
    if not homography_4pt(corners_px, dst, G):
        return 2
    return 0


@njit(cache=True)
def _geolocate_kernel(
    p_WC: FloatArray,
    R_WC: FloatArray,
    psi: float,
    h: float,
    plane_z: float,
    corners_n: FloatArray,
    corners_px: FloatArray,
    inner_n: FloatArray,
    inner_px: FloatArray,
    mpx: FloatArray,
    xy: FloatArray,
    dxy: FloatArray,
    lever: FloatArray,
    var: FloatArray,
    pts: FloatArray,
    cov: FloatArray,
) -> int:
    """Steps 1-7 for the method's pixels ``mpx`` (N, 2) (normalised ``xy`` (N, 2), their Jacobians ``dxy``
    (N, 2, 2)) -> ``pts`` (N, 3) in W, and the first-order covariance of their mean -> ``cov`` (3, 3) from
    the variances ``var`` = (pixel, attitude, ego x/y, altitude, plane). ``lever`` = ``[R_WB p_BC]x``.
    Returns 0, or 1 when a pixel's ray misses the plane, 2 when the homography is degenerate.

    One kernel: one compiled call per detection gives the points and the first-order covariance of their mean,
    which share ``R_WC``, the normalised pixels and their Jacobians; the ground homography and its application
    are apart already (``_ground_homography``, ``apply_homography``). The covariance pass is the seam if it is
    ever split; it stays here so as not to add a compiled kernel (compile/kernels.json, the warm-up).
    """
    c = math.cos(psi)
    s = math.sin(psi)
    # step 1: R_HC = Rz(psi)^T R_WC = R_tilt R_BC, the camera in the level heading frame
    R_HC = np.empty((3, 3))
    for j in range(3):
        R_HC[0, j] = c * R_WC[0, j] + s * R_WC[1, j]
        R_HC[1, j] = -s * R_WC[0, j] + c * R_WC[1, j]
        R_HC[2, j] = R_WC[2, j]
    G = np.empty((3, 3))
    status = _ground_homography(R_HC, h, corners_n, corners_px, G)
    if status == 1:
        status = _ground_homography(R_HC, h, inner_n, inner_px, G)
    if status != 0:
        return 2
    n = mpx.shape[0]
    g = np.empty((n, 2))
    for i in range(n):
        # the pixel's own ray must point down to the plane (the projective map also "sees" behind)
        if not R_HC[2, 0] * xy[i, 0] + R_HC[2, 1] * xy[i, 1] + R_HC[2, 2] < 0.0:
            return 1
    apply_homography(G, mpx, g)  # step 5
    for i in range(n):
        pts[i, 0] = p_WC[0] + c * g[i, 0] - s * g[i, 1]  # steps 6-7
        pts[i, 1] = p_WC[1] + s * g[i, 0] + c * g[i, 1]
        pts[i, 2] = plane_z
    # covariance (module docstring)
    for a in range(3):
        for b in range(3):
            cov[a, b] = 0.0
    J_att = np.zeros((3, 3))
    A_m = np.zeros((3, 3))
    q_m = np.zeros(3)
    A = np.empty((3, 3))
    Jp = np.empty((3, 2))
    r = np.empty(3)
    for i in range(n):
        for a in range(3):
            r[a] = R_WC[a, 0] * xy[i, 0] + R_WC[a, 1] * xy[i, 1] + R_WC[a, 2]
        q0 = r[0] / r[2]
        q1 = r[1] / r[2]
        k = -h / r[2]
        for a in range(3):
            qa = r[a] / r[2]
            for b in range(3):
                A[a, b] = (1.0 if a == b else 0.0) - (qa if b == 2 else 0.0)
        # J_px = M R_WC[:, :2] dxy = k A R_WC[:, :2] dxy
        for a in range(3):
            for b in range(2):
                acc = 0.0
                for m in range(3):
                    acc += A[a, m] * (R_WC[m, 0] * dxy[i, 0, b] + R_WC[m, 1] * dxy[i, 1, b])
                Jp[a, b] = k * acc
        for a in range(3):
            for b in range(3):
                cov[a, b] += var[0] * (Jp[a, 0] * Jp[b, 0] + Jp[a, 1] * Jp[b, 1])
        # J_att = -A [R_WB p_BC]x - k A [r]x  =  -A ([lever] + k [r]x)
        S0 = np.empty((3, 3))
        S0[0, 0] = lever[0, 0]
        S0[0, 1] = lever[0, 1] - k * r[2]
        S0[0, 2] = lever[0, 2] + k * r[1]
        S0[1, 0] = lever[1, 0] + k * r[2]
        S0[1, 1] = lever[1, 1]
        S0[1, 2] = lever[1, 2] - k * r[0]
        S0[2, 0] = lever[2, 0] - k * r[1]
        S0[2, 1] = lever[2, 1] + k * r[0]
        S0[2, 2] = lever[2, 2]
        for a in range(3):
            for b in range(3):
                acc = 0.0
                for m in range(3):
                    acc += A[a, m] * S0[m, b]
                J_att[a, b] -= acc / n
                A_m[a, b] += A[a, b] / n
        q_m[0] += q0 / n
        q_m[1] += q1 / n
        q_m[2] += 1.0 / n
    inv_n2 = 1.0 / (n * n)
    for a in range(3):
        for b in range(3):
            cov[a, b] *= inv_n2
    for a in range(3):
        for b in range(3):
            acc = 0.0
            for m in range(3):
                acc += var[1] * J_att[a, m] * J_att[b, m]
            acc += var[2] * (A_m[a, 0] * A_m[b, 0] + A_m[a, 1] * A_m[b, 1]) + var[3] * A_m[a, 2] * A_m[b, 2]
            acc += var[4] * q_m[a] * q_m[b]
            cov[a, b] += acc
    for a in range(3):
        for b in range(a + 1, 3):
            v = 0.5 * (cov[a, b] + cov[b, a])
            cov[a, b] = v
            cov[b, a] = v
    return 0


# --------------------------------------------------------------------------------------------------
# Frames
# --------------------------------------------------------------------------------------------------

_T_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_D_FRD_FLU = np.diag([1.0, -1.0, -1.0])


def enu_flu_from_ned_frd(R_NF: FloatArray) -> FloatArray:
    """``R_WB`` (ENU world, FLU body) of an attitude given as the paper does, NED world and FRD body:
    ``R_WB = T R_NF D`` (both constant matrices are their own inverse)."""
    return _T_ENU_NED @ np.asarray(R_NF, dtype=np.float64) @ _D_FRD_FLU


def heading_and_tilt(R_WB: FloatArray) -> tuple[float, FloatArray]:
    """Step 1's split ``R_WB = Rz(psi) R_tilt``: the heading ``psi`` (rad) and ``R_tilt = Ry(pitch)
    Rx(roll)`` (3, 3), the part of the attitude that roll and pitch make."""
    psi = yaw_of(R_WB)
    return psi, rot_z(psi).T @ R_WB


def ray_plane_point(p_WC: FloatArray, ray_W: FloatArray, plane_z_W: float) -> FloatArray | None:
    """Exact intersection of the ray from ``p_WC`` along ``ray_W`` (3,) with the plane ``z = plane_z_W``;
    None when the ray does not reach it. The reference the homography method is compared with."""
    if not ray_W[2] * (plane_z_W - p_WC[2]) > 0.0:
        return None
    p: FloatArray = p_WC + (plane_z_W - p_WC[2]) / ray_W[2] * ray_W  # an ndarray element is typed Any
    return p


# --------------------------------------------------------------------------------------------------
# The geolocator
# --------------------------------------------------------------------------------------------------


def _virtual_intrinsics(
    camera: CameraModel, exact: PinholeCamera | None, fov_rad: tuple[float, float] | None
) -> tuple[float, float, float, float]:
    """``(fx, fy, cx, cy)`` (px) of the pinhole camera the method amounts to: ``exact``'s own ``K`` in the
    exact-intrinsics mode, else the virtual camera of the fields of view (steps 2-5, module docstring)."""
    if exact is not None:
        K = np.asarray(exact.K, dtype=np.float64)
        return float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
    W, Hh = int(camera.width), int(camera.height)
    hfov, vfov = camera.fov_rad() if fov_rad is None else fov_rad
    if not (0.0 < hfov < math.pi and 0.0 < vfov < math.pi):
        raise ValueError(f"fields of view must be in (0, pi), got {hfov}, {vfov}")
    fx, fy = W / (2.0 * math.tan(0.5 * hfov)), Hh / (2.0 * math.tan(0.5 * vfov))
    return float(fx), float(fy), 0.5 * W - 0.5, 0.5 * Hh - 0.5


class HomographyGeolocator:
    """Paper 004's pixel-to-world homography as a :class:`alight.perception.Geolocator`.

    Parameters
    ----------
    camera:
        The camera the pixels come from: needs ``width`` and ``height`` (px), and ``fov_rad()`` when
        ``fov_rad`` is not given; ``exact_intrinsics`` also needs ``K`` and ``pixels_to_normalized``
        (:class:`alight.cameras.PinholeCamera`).
    mount:
        Camera mount on the body (:class:`alight.cameras.CameraMount`).
    plane_z_W:
        Height in W of the plane the marker lies on (m). The paper's choice (the altitude above the
        take-off point) is 0; the pad deck's height when known (the module docstring gives the error).
    fov_rad:
        (horizontal, vertical) full field of view (rad) of step 2; None: ``camera.fov_rad()``.
    exact_intrinsics:
        False: the paper's method (corners from the fields of view, raw pixels). True: the pixel is
        undistorted and the corners come from ``K``, which makes steps 2-5 exact ray casting.
    landmark_offsets:
        Offsets ``(x, y)`` or ``(x, y, z)`` in P (m) of single-point observations by ``kind`` (step 8).
    assume_pad_yaw:
        Pad heading in W (rad) to use when an observation with an offset carries none; None: such an
        observation gives no measurement.
    sigma_px:
        Pixel noise standard deviation (px).
    sigma_att_rad:
        Ego attitude standard deviation per axis (rad).
    sigma_ego_pos_m, sigma_alt_m:
        Ego horizontal position (per axis) and altitude standard deviations (m).
    sigma_plane_m:
        Standard deviation of the plane's height (m).
    sigma_yaw_rad:
        Standard deviation of the pad heading that rotates landmark offsets (rad); also reported as the
        measurement's yaw variance when the heading was measured.
    min_height_m:
        No measurement when the camera is less than this above the plane (m).
    points:
        ``"first"``: geolocate the observation's first pixel only (the SDU detector's fused
        landing-marker pixel; its other rows are for PnP). ``"all"``: every pixel, the centre as the mean
        of the per-point centres.
    """

    def __init__(
        self,
        camera: CameraModel,
        mount: CameraMount,
        *,
        plane_z_W: float = 0.0,
        fov_rad: tuple[float, float] | None = None,
        exact_intrinsics: bool = False,
        landmark_offsets: dict[str, Any] | None = None,
        assume_pad_yaw: float | None = None,
        sigma_px: float = 1.0,
        sigma_att_rad: float = 0.01,
        sigma_ego_pos_m: float = 0.0,
        sigma_alt_m: float = 0.05,
        sigma_plane_m: float = 0.05,
        sigma_yaw_rad: float = 0.05,
        min_height_m: float = 0.05,
        points: Literal["first", "all"] = "first",
    ) -> None:
        _check_sigmas(
            sigma_att_rad=sigma_att_rad,
            sigma_ego_pos_m=sigma_ego_pos_m,
            sigma_alt_m=sigma_alt_m,
            sigma_plane_m=sigma_plane_m,
            sigma_yaw_rad=sigma_yaw_rad,
        )
        if not (math.isfinite(sigma_px) and sigma_px > 0):
            raise ValueError(f"sigma_px must be finite and positive, got {sigma_px}")
        if not (math.isfinite(plane_z_W) and math.isfinite(min_height_m) and min_height_m > 0):
            raise ValueError("plane_z_W must be finite and min_height_m finite and positive")
        if points not in ("first", "all"):
            raise ValueError(f"points must be 'first' or 'all', got {points!r}")
        if assume_pad_yaw is not None and not math.isfinite(assume_pad_yaw):
            raise ValueError(f"assume_pad_yaw must be finite or None, got {assume_pad_yaw}")
        if exact_intrinsics and not isinstance(camera, PinholeCamera):
            raise ValueError(
                f"exact_intrinsics needs a pinhole camera model (K and its lens), got {type(camera).__name__}"
            )
        self.camera = camera
        self._pinhole: PinholeCamera | None = camera if isinstance(camera, PinholeCamera) else None
        """The camera as a pinhole model, for the exact-intrinsics mode (None for other models)."""
        self.mount = mount
        self.plane_z_W = float(plane_z_W)
        self.exact_intrinsics = bool(exact_intrinsics)
        self.assume_pad_yaw = None if assume_pad_yaw is None else float(assume_pad_yaw)
        self.sigma_px = float(sigma_px)
        self.sigma_att_rad = float(sigma_att_rad)
        self.sigma_ego_pos_m = float(sigma_ego_pos_m)
        self.sigma_alt_m = float(sigma_alt_m)
        self.sigma_plane_m = float(sigma_plane_m)
        self.sigma_yaw_rad = float(sigma_yaw_rad)
        self.min_height_m = float(min_height_m)
        self.points = points
        self.landmark_offsets: dict[str, FloatArray] = {}
        for kind, off in (landmark_offsets or {}).items():
            o = np.zeros(3)
            a = np.asarray(off, dtype=np.float64).ravel()
            if a.size not in (2, 3) or not np.isfinite(a).all():
                raise ValueError(f"landmark offset of {kind!r} must be 2 or 3 finite numbers, got {off}")
            o[: a.size] = a
            self.landmark_offsets[kind] = o
        W, Hh = int(camera.width), int(camera.height)
        corners_px = np.array([[-0.5, -0.5], [W - 0.5, -0.5], [W - 0.5, Hh - 0.5], [-0.5, Hh - 0.5]])
        exact = self._pinhole if self.exact_intrinsics else None
        self._f = _virtual_intrinsics(camera, exact, fov_rad)
        fx, fy, cx, cy = self._f
        self._corners_px = corners_px
        self._corners_n = np.column_stack([(corners_px[:, 0] - cx) / fx, (corners_px[:, 1] - cy) / fy])
        centre = np.array([cx, cy])
        self._inner_px = centre + 0.5 * (corners_px - centre)
        self._inner_n = 0.5 * self._corners_n
        self._var = np.array(
            [sigma_px**2, sigma_att_rad**2, sigma_ego_pos_m**2, sigma_alt_m**2, sigma_plane_m**2]
        )

    @property
    def virtual_intrinsics(self) -> tuple[float, float, float, float]:
        """``(fx, fy, cx, cy)`` (px) of the pinhole camera for which steps 2-5 are exact ray casting."""
        return self._f

    # ---- steps 1-7 -----------------------------------------------------------------------------------

    def _method_pixels(self, pixels: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """The pixels the homography maps (raw, or undistorted to the ideal pinhole in exact mode) and
        their normalised coordinates (N, 2) for the Jacobians."""
        fx, fy, cx, cy = self._f
        if not self.exact_intrinsics:
            xy = np.empty_like(pixels)
            xy[:, 0] = (pixels[:, 0] - cx) / fx
            xy[:, 1] = (pixels[:, 1] - cy) / fy
            return pixels, xy
        assert self._pinhole is not None  # exact mode is refused for other models in __init__
        xy = self._pinhole.pixels_to_normalized(pixels)
        if not np.isfinite(xy).all():
            return None
        return np.column_stack([fx * xy[:, 0] + cx, fy * xy[:, 1] + cy]), xy

    def _solve(
        self, pixels: FloatArray, p_WB: FloatArray, R_WB: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """Ground points (N, 3) in W, the covariance of their mean (3, 3), and ``R_WC``; None if none."""
        px = np.ascontiguousarray(pixels, dtype=np.float64)
        if px.ndim != 2 or px.shape[1] != 2 or px.shape[0] == 0 or not np.isfinite(px).all():
            return None
        p_WC, R_WC = camera_pose_W(p_WB, R_WB, self.mount)
        h = float(p_WC[2]) - self.plane_z_W
        if not h >= self.min_height_m:
            return None
        m = self._method_pixels(px)
        if m is None:
            return None
        mpx, xy = m
        n = px.shape[0]
        pts = np.empty((n, 3))
        cov = np.empty((3, 3))
        status = _geolocate_kernel(
            p_WC,
            np.ascontiguousarray(R_WC),
            yaw_of(R_WB),
            h,
            self.plane_z_W,
            self._corners_n,
            self._corners_px,
            self._inner_n,
            self._inner_px,
            np.ascontiguousarray(mpx),
            np.ascontiguousarray(xy),
            self._normalised_jacobians(xy),
            skew(R_WB @ self.mount.p_BC),
            self._var,
            pts,
            cov,
        )
        if status != 0:
            return None
        return pts, cov, R_WC

    def ground_points(self, pixels: FloatArray, p_WB: FloatArray, R_WB: FloatArray) -> FloatArray | None:
        """Steps 1-7 for pixels (N, 2): the points in W (N, 3) on the plane ``z = plane_z_W``. None when
        the camera is not above the plane, the homography is degenerate, or a pixel's ray misses the
        plane."""
        p_WB, R_WB = _check_pose(p_WB, R_WB)
        res = self._solve(pixels, p_WB, R_WB)
        return None if res is None else res[0]

    # ---- step 8 and the measurement ------------------------------------------------------------------

    def _offsets(self, obs: Observation, n: int) -> FloatArray | None:
        if obs.points_P is not None:
            return np.asarray(obs.points_P[:n], dtype=np.float64)
        off = self.landmark_offsets.get(obs.kind)
        if off is None:
            return np.zeros((n, 3))
        if n != 1:
            return None  # one offset for several points of one landmark is ambiguous
        return off[None, :].copy()

    def locate(self, obs: Observation, p_WB: FloatArray, R_WB: FloatArray) -> PlatformMeasurement | None:
        """Pad centre in W from an observation and the ego pose (``p_WB`` (3,) m, ``R_WB`` (3, 3)) at its
        capture time; None when it gives none (see :meth:`ground_points`, and the module docstring for
        offsets without a heading)."""
        p_WB, R_WB = _check_pose(p_WB, R_WB)
        n_use = 1 if self.points == "first" else obs.pixels.shape[0]
        offsets = self._offsets(obs, n_use)
        if offsets is None:
            return None
        res = self._solve(obs.pixels[:n_use], p_WB, R_WB)
        if res is None:
            return None
        pts_W, cov, R_WC = res
        n = pts_W.shape[0]
        has_offset = bool(np.abs(offsets[:, :2]).max() > 0.0)
        yaw: float | None = None
        if obs.yaw_CP is not None and math.isfinite(obs.yaw_CP):
            yaw = level_pad_yaw(R_WC, obs.yaw_CP)
        if yaw is None and n >= 2:
            yaw = _procrustes_yaw(pts_W[:, :2], offsets[:, :2])
        measured = yaw is not None
        if yaw is None and has_offset:
            if self.assume_pad_yaw is None:
                return None
            yaw = self.assume_pad_yaw
        p_WP = pts_W.mean(axis=0) if n > 1 else pts_W[0]
        if has_offset and yaw is not None:
            # step 8: the landmark's ground point minus its offset turned into W; z stays on the plane
            c, s = math.cos(yaw), math.sin(yaw)
            ox, oy = float(offsets[:, 0].mean()), float(offsets[:, 1].mean())
            rx, ry = c * ox - s * oy, s * ox + c * oy
            p_WP[0] -= rx
            p_WP[1] -= ry
            # the heading's uncertainty moves the centre across the offset: e_z x R_WP o
            v0, v1 = -ry, rx
            s2 = self.sigma_yaw_rad**2
            cov[0, 0] += s2 * v0 * v0
            cov[0, 1] += s2 * v0 * v1
            cov[1, 0] += s2 * v0 * v1
            cov[1, 1] += s2 * v1 * v1
        return PlatformMeasurement(
            t=obs.t,
            p_WP=p_WP,
            cov_p_WP=cov,
            yaw=yaw if measured else None,
            yaw_var=self.sigma_yaw_rad**2 if measured and self.sigma_yaw_rad > 0 else None,
        )

    def _normalised_jacobians(self, xy: FloatArray) -> FloatArray:
        """d(x, y)/d(u, v) of the method's normalised coordinates, (N, 2, 2)."""
        fx, fy, _, _ = self._f
        n = xy.shape[0]
        J = np.zeros((n, 2, 2))
        lens = self._pinhole if self.exact_intrinsics else None
        if lens is None or not lens.has_distortion:
            J[:, 0, 0] = 1.0 / fx
            J[:, 1, 1] = 1.0 / fy
            return J
        # the inverse of the lens map, by central differences
        px = lens.normalized_to_pixels(xy)
        step = 1e-3
        for k in range(2):
            d = np.zeros(2)
            d[k] = step
            J[:, :, k] = (lens.pixels_to_normalized(px + d) - lens.pixels_to_normalized(px - d)) / (2 * step)
        return J


def _procrustes_yaw(g_xy: FloatArray, o_xy: FloatArray) -> float | None:
    """Heading ``psi`` (rad) minimising ``sum |g_i - c - R(psi) o_i|^2`` over ``psi`` and ``c`` (2-D
    Procrustes), or None when the offsets do not span a direction."""
    gc = g_xy - g_xy.mean(axis=0)
    oc = o_xy - o_xy.mean(axis=0)
    if not float(np.max(np.abs(oc))) > 1e-9:
        return None
    s = float(np.sum(oc[:, 0] * gc[:, 1] - oc[:, 1] * gc[:, 0]))
    c = float(np.sum(oc[:, 0] * gc[:, 0] + oc[:, 1] * gc[:, 1]))
    return math.atan2(s, c)


__all__ = [
    "HomographyGeolocator",
    "apply_homography",
    "enu_flu_from_ned_frd",
    "heading_and_tilt",
    "homography_4pt",
    "ray_plane_point",
]
