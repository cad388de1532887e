"""Pinhole camera with OpenCV's lens-distortion model, and the camera mount on the vehicle.

Camera frame ``C`` is OpenCV's: x right, y down, z forward along the optical axis. Pixel coordinates
``(u, v)`` are OpenCV's too: integer values at pixel centres, (0, 0) the centre of the top-left pixel.

Distortion (OpenCV ``calib3d`` model, coefficients ``(k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3,
s4]]])``): for normalised coordinates ``x = X/Z``, ``y = Y/Z`` and ``r2 = x^2 + y^2``,

    x' = x R + 2 p1 x y + p2 (r2 + 2 x^2) + s1 r2 + s2 r2^2
    y' = y R + p1 (r2 + 2 y^2) + 2 p2 x y + s3 r2 + s4 r2^2,   R = (1 + k1 r2 + k2 r2^2 + k3 r2^3)
                                                                   / (1 + k4 r2 + k5 r2^2 + k6 r2^3)
    (u, v, 1) = K (x', y', 1)

The tilted-sensor terms (14 coefficients) are not supported. Projection is vectorised numpy (faster than
``cv2.projectPoints`` for the small point sets detectors use, and it returns NaN where a point has no
image); unprojection is a damped Newton iteration on the analytic Jacobian per pixel (a numba kernel: the
renderer unprojects every pixel once per camera), so a project/unproject round trip is exact to ~1e-12 px,
where OpenCV's fixed-point ``undistortPoints`` stops at ~1e-6 and can diverge for strong distortion.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import cv2
import numba
import numpy as np

from alight.errors import ConfigError, InputError
from alight.types import FloatArray
from alight.yaml_io import load_yaml_text

_SUPPORTED_DIST_LEN = (0, 4, 5, 8, 12)


@dataclass(frozen=True, eq=False)
class PinholeCamera:
    """A calibrated pinhole camera (OpenCV model)."""

    width: int
    """Image width (px)."""
    height: int
    """Image height (px)."""
    K: FloatArray
    """Intrinsic matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` (px), shape (3, 3); no skew (OpenCV)."""
    dist: FloatArray = field(default_factory=lambda: np.zeros(5))
    """Distortion coefficients ``(k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4]]])``, length 0, 4, 5, 8 or 12."""
    _k12: FloatArray = field(init=False, repr=False)  # dist padded to 12 coefficients, for the kernels
    r_max: float = field(init=False)
    """Largest undistorted radius ``sqrt(x^2 + y^2)`` where the radial model is still monotonic; points
    beyond it have no valid image (a polynomial lens model folds back there) and project to NaN."""

    def __post_init__(self) -> None:
        if (
            int(self.width) != self.width
            or int(self.height) != self.height
            or self.width < 1
            or self.height < 1
        ):
            raise ValueError(f"image size must be positive integers, got {self.width} x {self.height}")
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))
        K = np.array(self.K, dtype=np.float64)
        if K.shape != (3, 3) or not np.isfinite(K).all():
            raise ValueError(f"K must be a finite 3x3 matrix, got shape {K.shape}")
        if (
            K[0, 0] <= 0
            or K[1, 1] <= 0
            or np.any(K[[0, 1, 1, 2, 2, 2], [1, 0, 0, 0, 1, 2]] != (0, 0, 0, 0, 0, 1))
        ):
            # OpenCV's model (projectPoints, calibrateCamera) has no skew: a K with one would be read
            # differently by OpenCV and by us
            raise ValueError(f"K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, got {K}")
        d = np.array(self.dist, dtype=np.float64).ravel()
        if d.size not in _SUPPORTED_DIST_LEN or not np.isfinite(d).all():
            raise ValueError(f"dist must have {_SUPPORTED_DIST_LEN} finite coefficients, got {d.size}: {d}")
        K.setflags(write=False)
        d.setflags(write=False)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "dist", d)
        object.__setattr__(self, "r_max", _monotonic_radius(_full12(d)))
        object.__setattr__(self, "_k12", _full12(d))

    # ------------------------------------------------------------------------------------ constructors

    @classmethod
    def from_opencv_yaml(
        cls, path: str | os.PathLike[str], *, width: int | None = None, height: int | None = None
    ) -> PinholeCamera:
        """Read an OpenCV ``FileStorage`` calibration (YAML, XML or JSON) with ``camera_matrix``,
        ``distortion_coefficients``, ``image_width`` and ``image_height`` (the names OpenCV's calibration
        samples write; ``K``/``D`` and ROS ``camera_info`` style ``{rows, cols, data}`` maps also work).
        ``width``/``height`` (px) supply the image size for files that do not store it (and override it
        when they do).

        Raises ``alight.errors.InputError`` when the file is missing or lacks these entries."""
        p = os.fspath(path)
        if not os.path.isfile(p):
            raise InputError(f"{p}: camera calibration file not found")
        ros = _ros_camera_info(p)
        if ros is not None:
            K_ros, dist_ros, w_ros, h_ros = ros
            try:
                return cls(width or w_ros, height or h_ros, K_ros, dist_ros)
            except ValueError as e:
                raise InputError(f"{p}: {e}") from None
        try:
            fs = cv2.FileStorage(p, cv2.FILE_STORAGE_READ)
        except cv2.error as e:
            raise InputError(f"{p}: not a readable OpenCV calibration file ({e.err})") from None
        except SystemError:  # OpenCV's Python binding surfaces some parse errors this way
            raise InputError(f"{p}: not a readable OpenCV calibration file (parse error)") from None
        try:
            K = _read_matrix(fs, ("camera_matrix", "K"))
            dist = _read_matrix(fs, ("distortion_coefficients", "dist_coeffs", "D"))
            w = _read_int(fs, ("image_width", "width")) if width is None else width
            h = _read_int(fs, ("image_height", "height")) if height is None else height
        finally:
            fs.release()
        if K is None:
            raise InputError(f"{p}: no camera_matrix")
        if w is None or h is None:
            raise InputError(f"{p}: no image_width / image_height (pass width= and height=)")
        try:
            return cls(w, h, K.reshape(3, 3), np.zeros(5) if dist is None else dist.ravel())
        except ValueError as e:
            raise InputError(f"{p}: {e}") from None

    @classmethod
    def default_downward(cls) -> PinholeCamera:
        """The downward camera of paper 000 (Sec. III-C): a mvBlueFOX-MLC200w, 752 x 480 px global
        shutter, 6.0 um pixels. The paper does not name the lens; this is a 2.4 mm S-mount lens
        (f = 2.4 mm / 6 um = 400 px) with mild barrel distortion k1 = -0.08, k2 = 0.01 (monotonic at
        every radius), giving a horizontal field of view of 90.7 deg and a vertical one of 63.4 deg,
        principal point at the image centre."""
        f = 400.0
        K = np.array([[f, 0.0, 375.5], [0.0, f, 239.5], [0.0, 0.0, 1.0]])
        return cls(752, 480, K, np.array([-0.08, 0.01, 0.0, 0.0, 0.0]))

    # ------------------------------------------------------------------------------------ model

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0))

    def project(self, points_C: FloatArray) -> FloatArray:
        """Pixels ``(u, v)`` of points in C (m), shape (N, 3) -> (N, 2). Points on or behind the image
        plane through the centre (z <= 0) or outside the lens model's valid radius give NaN rows.
        Pixels outside the image are returned as they are (no clipping)."""
        P = np.ascontiguousarray(points_C, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"points_C must have shape (N, 3), got {P.shape}")
        out = np.empty((P.shape[0], 2))
        K = self.K
        _project_kernel(P, self._k12, K[0, 0], K[1, 1], K[0, 2], K[1, 2], self.r_max, True, out)
        return out

    def normalized_to_pixels(self, xy: FloatArray) -> FloatArray:
        """Apply distortion and K to undistorted normalised coordinates ``(x, y)``, shape (N, 2) -> (N, 2)."""
        p = np.ascontiguousarray(xy, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 2:
            raise ValueError(f"xy must have shape (N, 2), got {p.shape}")
        out = np.empty((p.shape[0], 2))
        K = self.K
        _project_kernel(p, self._k12, K[0, 0], K[1, 1], K[0, 2], K[1, 2], self.r_max, False, out)
        return out

    def pixels_to_normalized(self, pixels: FloatArray) -> FloatArray:
        """Undistorted normalised coordinates ``(x, y)`` of pixels, shape (N, 2) -> (N, 2). Pixels the
        lens model cannot invert (beyond its monotonic radius) give NaN rows."""
        uv = np.asarray(pixels, dtype=np.float64)
        if uv.ndim != 2 or uv.shape[1] != 2:
            raise ValueError(f"pixels must have shape (N, 2), got {uv.shape}")
        K = self.K
        yd = (uv[:, 1] - K[1, 2]) / K[1, 1]
        xd = (uv[:, 0] - K[0, 2]) / K[0, 0]
        if not self.has_distortion or uv.shape[0] == 0:
            return np.stack([xd, yd], axis=1)
        out = np.empty((uv.shape[0], 2))
        _undistort_kernel(self._k12, xd, yd, self.r_max, out)
        return out

    def unproject(self, pixels: FloatArray) -> FloatArray:
        """Unit rays in C through pixels ``(u, v)``, shape (N, 2) -> (N, 3) (z > 0). NaN rows where the
        lens model has no inverse."""
        xy = self.pixels_to_normalized(pixels)
        r = np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1)
        rays: FloatArray = r / np.linalg.norm(r, axis=1, keepdims=True)  # norm(axis=...) is typed Any
        return rays

    def fov_rad(self) -> tuple[float, float]:
        """Full horizontal and vertical field of view (rad): the angle between the rays through the
        middles of the left and right (top and bottom) image edges (pixel outer edges, -0.5 and
        size - 0.5)."""
        cx, cy = self.K[0, 2], self.K[1, 2]
        W, H = self.width, self.height
        r = self.unproject(np.array([[-0.5, cy], [W - 0.5, cy], [cx, -0.5], [cx, H - 0.5]]))
        h = math.acos(float(np.clip(r[0] @ r[1], -1.0, 1.0)))
        v = math.acos(float(np.clip(r[2] @ r[3], -1.0, 1.0)))
        return h, v

    def pixel_grid_rays(self) -> FloatArray:
        """Undistorted normalised coordinates ``(x, y)`` of every pixel centre, shape (height, width, 2),
        float64 (NaN where the model has no inverse). The renderer precomputes this once per camera."""
        v, u = np.mgrid[0 : self.height, 0 : self.width]
        uv = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64)
        return self.pixels_to_normalized(uv).reshape(self.height, self.width, 2)


@dataclass(frozen=True, eq=False)
class CameraMount:
    """Rigid mount of a camera on the body: ``p_WC = p_WB + R_WB p_BC`` and ``R_WC = R_WB R_BC``."""

    R_BC: FloatArray
    """Rotation of C-vectors into B, shape (3, 3)."""
    p_BC: FloatArray = field(default_factory=lambda: np.zeros(3))
    """Camera centre in B (m), shape (3,)."""

    def __post_init__(self) -> None:
        R = np.array(self.R_BC, dtype=np.float64)
        p = np.array(self.p_BC, dtype=np.float64).ravel()
        if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
            raise ValueError(f"R_BC must be a rotation matrix, got {R}")
        if p.shape != (3,) or not np.isfinite(p).all():
            raise ValueError(f"p_BC must be a finite 3-vector, got {p}")
        R.setflags(write=False)
        p.setflags(write=False)
        object.__setattr__(self, "R_BC", R)
        object.__setattr__(self, "p_BC", p)

    @classmethod
    def downward(cls, p_BC: FloatArray | None = None) -> CameraMount:
        """A camera looking straight down: optical axis ``z_C = -z_B``, image right ``x_C = -y_B`` (the
        vehicle's right), hence image down ``y_C = -x_B``: the top of the image points to the vehicle's
        front. ``p_BC`` defaults to the body origin."""
        R_BC = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
        return cls(R_BC, np.zeros(3) if p_BC is None else p_BC)


def camera_pose_W(p_WB: FloatArray, R_WB: FloatArray, mount: CameraMount) -> tuple[FloatArray, FloatArray]:
    """Camera pose in W from the body pose: ``(p_WC (3,), R_WC (3, 3))``."""
    R_WB = np.asarray(R_WB, dtype=np.float64)
    return np.asarray(p_WB, dtype=np.float64) + R_WB @ mount.p_BC, R_WB @ mount.R_BC


# ------------------------------------------------------------------------------------------------
# Pure functions of the distortion model
# ------------------------------------------------------------------------------------------------


def _full12(d: FloatArray) -> FloatArray:
    """Coefficients padded to (k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4)."""
    k = np.zeros(12)
    k[: d.size] = d
    return k


def _monotonic_radius(k: FloatArray, r_limit: float = 20.0) -> float:
    """First radius where the radial map ``r -> r R(r^2)`` stops increasing (or ``r_limit``)."""
    r = np.linspace(0.0, r_limit, 20001)[1:]
    r2 = r * r
    N = 1 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]))
    D = 1 + r2 * (k[5] + r2 * (k[6] + r2 * k[7]))
    with np.errstate(divide="ignore", invalid="ignore"):
        f = r * N / D
    # a pole of the rational model (D = 0) also ends the valid region
    bad = ~(np.diff(f) > 0) | ~(D[1:] > 0) | ~np.isfinite(f[1:])
    if not bad.any():
        return r_limit
    return float(r[int(np.argmax(bad))])


# ROS camera_info distortion models and the number of OpenCV coefficients each is (same order as
# OpenCV's: k1, k2, p1, p2[, k3[, k4, k5, k6]]). ``equidistant`` (Kannala-Brandt, OpenCV's cv::fisheye) is a
# different lens model: read as radial-tangential it would silently bend every ray, so it is refused.
ROS_DISTORTION_MODELS = {"plumb_bob": (4, 5), "rational_polynomial": (8,)}


def _ros_camera_info(path: str) -> tuple[FloatArray, FloatArray, int, int] | None:
    """(K, dist, width, height) of a ROS ``camera_info`` YAML (a file with ``distortion_model``), None for
    any other file (OpenCV's ``%YAML:1.0`` FileStorage files). Raises InputError for a model it cannot
    read as OpenCV's radial-tangential one."""

    if not path.lower().endswith((".yaml", ".yml")):
        return None
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError):
        return None
    if text.lstrip().startswith("%YAML:"):
        return None  # OpenCV FileStorage syntax, not plain YAML
    try:
        data = load_yaml_text(text, path, "camera", allow_empty=True)
    except ConfigError:
        return None  # not YAML at all: not a camera_info file
    if not isinstance(data, dict) or "distortion_model" not in data:
        return None
    model = data["distortion_model"]
    if model not in ROS_DISTORTION_MODELS:
        hint = (
            " (a Kannala-Brandt fisheye: calibrate with OCamCalib and use camera: fisheye)"
            if model in ("equidistant", "fisheye", "kannala_brandt")
            else ""
        )
        raise InputError(
            f"{path}: distortion_model {model!r} is not supported{hint}; "
            f"supported: {sorted(ROS_DISTORTION_MODELS)}"
        )

    def matrix(key: str) -> FloatArray:
        node = data.get(key)
        values = node.get("data") if isinstance(node, dict) else node
        try:
            arr = np.asarray(values, dtype=np.float64).ravel()
        except (TypeError, ValueError):
            raise InputError(f"{path}: {key} is not a list of numbers") from None
        return arr

    K = matrix("camera_matrix")
    if K.size != 9:
        raise InputError(f"{path}: camera_matrix must have 9 entries, got {K.size}")
    dist = matrix("distortion_coefficients") if "distortion_coefficients" in data else matrix("D")
    if dist.size not in ROS_DISTORTION_MODELS[model]:
        raise InputError(
            f"{path}: distortion_model {model} has {ROS_DISTORTION_MODELS[model]} coefficients, "
            f"got {dist.size}"
        )
    w, h = data.get("image_width"), data.get("image_height")
    if not isinstance(w, int) or not isinstance(h, int):
        raise InputError(f"{path}: no image_width / image_height")
    return K.reshape(3, 3), dist, w, h


def _read_matrix(fs: cv2.FileStorage, names: tuple[str, ...]) -> FloatArray | None:
    for name in names:
        node = fs.getNode(name)
        if node.empty() or node.isNone():
            continue
        if node.isMap() and not node.getNode("data").empty():  # ROS camera_info style
            data = node.getNode("data")
            vals = [data.at(i).real() for i in range(data.size())]
            return np.array(vals, dtype=np.float64)
        m = node.mat()
        if m is not None:
            return np.asarray(m, dtype=np.float64)
        if node.isSeq():
            return np.array([node.at(i).real() for i in range(node.size())], dtype=np.float64)
    return None


def _read_int(fs: cv2.FileStorage, names: tuple[str, ...]) -> int | None:
    for name in names:
        node = fs.getNode(name)
        if not node.empty() and (node.isReal() or node.isInt()):
            return int(node.real())
    return None


@numba.njit(cache=True)
def _undistort_kernel(k, xd, yd, r_max, out):  # type: ignore[no-untyped-def]
    """Invert the distortion per point by damped Newton from the distorted point; NaN where it fails
    (non-finite input, no inverse inside the monotonic radius, or a singular Jacobian)."""
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = k
    r_max2 = r_max * r_max
    for i in range(xd.shape[0]):
        tx = xd[i]
        ty = yd[i]
        x = tx
        y = ty
        ok = np.isfinite(tx) and np.isfinite(ty)
        err = np.inf
        for _ in range(60):
            if not ok:
                break
            r2 = x * x + y * y
            r4 = r2 * r2
            N = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            D = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
            R = N / D
            dR = ((k1 + r2 * (2 * k2 + 3 * k3 * r2)) * D - N * (k4 + r2 * (2 * k5 + 3 * k6 * r2))) / (D * D)
            ex = x * R + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4 - tx
            ey = y * R + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4 - ty
            e = ex * ex + ey * ey
            if e < 1e-28:
                err = e
                break
            a = R + 2 * x * x * dR + 2 * p1 * y + 6 * p2 * x + 2 * s1 * x + 4 * s2 * r2 * x
            b = 2 * x * y * dR + 2 * p1 * x + 2 * p2 * y + 2 * s1 * y + 4 * s2 * r2 * y
            c = 2 * x * y * dR + 2 * p1 * x + 2 * p2 * y + 2 * s3 * x + 4 * s4 * r2 * x
            d = R + 2 * y * y * dR + 6 * p1 * y + 2 * p2 * x + 2 * s3 * y + 4 * s4 * r2 * y
            det = a * d - b * c
            if not det > 0:
                ok = False
                break
            sx = (d * ex - b * ey) / det
            sy = (-c * ex + a * ey) / det
            # halve the step while it leaves the valid radius (the polynomial folds back beyond it)
            lam = 1.0
            while (x - lam * sx) ** 2 + (y - lam * sy) ** 2 > r_max2 and lam > 1e-6:
                lam *= 0.5
            x -= lam * sx
            y -= lam * sy
            err = e
        if ok and err < 1e-24 and x * x + y * y <= r_max2:
            out[i, 0] = x
            out[i, 1] = y
        else:
            out[i, 0] = np.nan
            out[i, 1] = np.nan


@numba.njit(cache=True)
def _project_kernel(P, k, fx, fy, cx, cy, r_max, homogeneous, out):  # type: ignore[no-untyped-def]
    """Distortion and K for each point: rows of ``P`` are 3D points in C when ``homogeneous`` (divided by
    z; z <= 0 gives NaN) else normalised ``(x, y)``. Beyond the monotonic radius: NaN."""
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = k
    r_max2 = r_max * r_max
    for i in range(P.shape[0]):
        if homogeneous:
            z = P[i, 2]
            if not z > 0:
                out[i, 0] = np.nan
                out[i, 1] = np.nan
                continue
            x = P[i, 0] / z
            y = P[i, 1] / z
        else:
            x = P[i, 0]
            y = P[i, 1]
        r2 = x * x + y * y
        if not r2 <= r_max2:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            continue
        r4 = r2 * r2
        R = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        xd = x * R + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
        yd = y * R + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
        out[i, 0] = fx * xd + cx
        out[i, 1] = fy * yd + cy
