"""Omnidirectional (fisheye / catadioptric) camera: Scaramuzza's polynomial model, as calibrated and
written by the OCamCalib toolbox (paper 003 eq. 1-4, which cites Scaramuzza et al. 2006 for it).

The model (OCamCalib's own frame, "OCam"): a pixel at ideal sensor-plane offset ``(x, y)`` from the
distortion centre, ``rho = sqrt(x^2 + y^2)``, sees along the ray ``(x, y, f(rho))`` with the direct
polynomial ``f(rho) = a0 + a1 rho + a2 rho^2 + ...`` (paper 003 eq. 2-4; ``ss`` = ``(a0, a1, ...)``).
The inverse polynomial ``invpol`` maps a ray's elevation ``theta = atan(z / sqrt(x^2 + y^2))`` back to
``rho`` (the toolbox's ``world2cam``). Ideal offsets map to pixels through the affine
``[[c, d], [e, 1]]`` and the centre ``(xc, yc)``.

**Axis convention.** OCamCalib's pixels are ``(row, col)``, 0-based, integer values at pixel centres: its
``xc`` is the centre's *row* (our ``v``) and ``yc`` its *column* (our ``u``); OpenCV's ``(u, v) = (col,
row)`` has the same origin, so there is no half-pixel shift. The OCam frame has x along increasing row
(down), y along increasing column (right) and z = f(rho), with ``a0 < 0``: rays in front of the lens have
**z < 0**, the optical axis is -z. Our camera frame C is OpenCV's (x right, y down, z forward), so

    p_C = M p_OCam,  M = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]:  x_C = y_OCam, y_C = x_OCam, z_C = -z_OCam,

x and y swap and z changes sign. ``M`` is its own inverse with det +1 (a 180 deg rotation about
``(1, 1, 0)/sqrt(2)``), so poses and normals carry over without a mirror. Written in C and ``(u, v)``:

    unproject:  du = u - yc,  dv = v - xc,  det = c - d e,
                Xs = (c du - e dv) / det,  Ys = (dv - d du) / det,  ray_C = normalise(Xs, Ys, -f(|(Xs, Ys)|))
    project:    r = hypot(X, Y),  theta = atan2(-Z, r),  rho = invpol(theta),
                Xs = rho X / r,  Ys = rho Y / r,  u = yc + Xs + e Ys,  v = xc + d Xs + c Ys

``theta`` is OCamCalib's elevation above the sensor plane: -pi/2 on the optical axis, 0 at 90 deg off
axis, positive beyond (a > 180 deg lens).

**Valid region.** The calibration file does not store the image circle; ``rho_max`` (the circle's radius in
the ideal sensor plane, px) does. By default it is the largest radius where the model is usable: within the
half-diagonal ``R = hypot(W/2, H/2)`` on which the toolbox fits ``invpol``, and where the elevation still
increases with ``rho`` (beyond that a ray has more than one pixel). ``unproject`` gives NaN outside the
circle, ``project`` gives NaN for rays beyond the circle's cone (elevation above ``theta_max``), for a ray
straight back, and for the zero or a non-finite vector. Pixels outside the frame are not clipped.

**Projection accuracy.** ``invpol`` only approximates the inverse of ``f`` (the toolbox stops at 0.01 px,
and its 6-decimal print precision costs up to 0.6 px near the axis for a 33-term ``invpol``). ``project``
therefore polishes ``invpol``'s radius with ``newton_steps`` Newton steps on the direct polynomial
(``r f(rho) - z rho = 0``, eq. 24 times ``r``), which makes it exact to ~1e-9 px; ``newton_steps=0`` is the
toolbox's ``world2cam``. ``project_exact`` solves eq. 24 by its polynomial roots instead (paper 003's
root selection, :func:`solve_rho`), which needs no ``invpol`` at all.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numba
import numpy as np
from numpy.polynomial import Polynomial

from alight.errors import InputError
from alight.numerics.poly import horner, horner_d, positive_real_roots, positive_real_roots_into
from alight.types import FloatArray

_INVPOL_TOL_PX = 0.01
"""Largest error of a fitted ``invpol`` against the exact inverse (px): the toolbox's own criterion."""
_INVPOL_MAX_ERR_PX = 2.0
"""A given ``invpol`` further than this from the exact inverse anywhere in the circle is rejected: the
Newton polish would start too far from the root."""
_THETA_TOL = 1e-12
"""Slack on the circle's edge (rad, px relative) so a ray exactly at the edge stays valid."""
_N_CHECK = 8001
"""Samples of rho used to check monotonicity and ``invpol``."""


@dataclass(frozen=True, eq=False, kw_only=True)
class OmniCamera:
    """A calibrated omnidirectional camera (Scaramuzza / OCamCalib model); see the module docstring for
    the model and the axis convention. All arguments are keyword-only because ``xc`` is a *row*."""

    width: int
    """Image width (px)."""
    height: int
    """Image height (px)."""
    ss: FloatArray
    """Direct polynomial ``(a0, a1, ..., a(N-1))`` in ascending powers of rho (px): OCam's z of the ray
    through the ideal-plane radius rho (paper 003 eq. 4). ``a0 < 0``; any length >= 2."""
    xc: float
    """Distortion centre **row** (OCamCalib's ``xc``; our ``v``), px, 0-based, pixel centres at integers."""
    yc: float
    """Distortion centre **column** (OCamCalib's ``yc``; our ``u``), px."""
    invpol: FloatArray | None = None
    """Inverse polynomial ``(p0, p1, ...)`` in ascending powers of theta (rad) giving rho (px), any length;
    None: fitted by least squares (the toolbox's procedure, max error 0.01 px)."""
    c: float = 1.0
    """Affine parameter c (OCamCalib): ``row_offset = c x + d y``, ``col_offset = e x + y``."""
    d: float = 0.0
    """Affine parameter d."""
    e: float = 0.0
    """Affine parameter e."""
    rho_max: float | None = None
    """Radius of the image circle in the ideal sensor plane (px); None: the largest valid radius (see the
    module docstring). After construction it is always a float."""
    newton_steps: int = 2
    """Newton steps polishing ``invpol``'s radius in :meth:`project` (0: the toolbox's ``world2cam``)."""
    theta_max: float = field(init=False)
    """Elevation (OCam theta, rad) of the circle's edge; the circle's half field of view is
    ``theta_max + pi/2``."""
    invpol_max_err_px: float = field(init=False)
    """Largest difference between ``invpol`` and the exact inverse of ``ss`` over the circle (px)."""

    def __post_init__(self) -> None:
        if (
            int(self.width) != self.width
            or int(self.height) != self.height
            or self.width < 1
            or self.height < 1
        ):
            raise ValueError(f"image size must be positive integers, got {self.width} x {self.height}")
        W, H = int(self.width), int(self.height)
        object.__setattr__(self, "width", W)
        object.__setattr__(self, "height", H)
        ss = _coefficients(self.ss, "ss", 2)
        if not ss[0] < 0:
            raise ValueError(f"ss[0] = a0 must be negative (the optical axis is OCam's -z), got {ss[0]}")
        object.__setattr__(self, "ss", ss)
        for name in ("xc", "yc", "c", "d", "e"):
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v}")
            object.__setattr__(self, name, v)
        if not self.c - self.d * self.e > 0:
            raise ValueError(f"affine c - d e must be positive (no mirror), got {self.c - self.d * self.e}")
        if int(self.newton_steps) != self.newton_steps or not 0 <= self.newton_steps <= 10:
            raise ValueError(f"newton_steps must be an integer in 0..10, got {self.newton_steps}")
        object.__setattr__(self, "newton_steps", int(self.newton_steps))

        if self.rho_max is None:
            # the toolbox fits invpol only out to the half-diagonal
            rho_max = valid_radius(ss, math.hypot(W / 2, H / 2))
        else:
            rho_max = float(self.rho_max)
            if not (rho_max > 0 and math.isfinite(rho_max)):
                raise ValueError(f"rho_max must be positive and finite, got {rho_max}")
            if valid_radius(ss, rho_max) < rho_max:
                raise ValueError(
                    f"rho_max = {rho_max:.3f} px: the elevation stops increasing at "
                    f"{valid_radius(ss, rho_max):.3f} px (ss has no unique inverse there)"
                )
        object.__setattr__(self, "rho_max", rho_max)
        object.__setattr__(self, "theta_max", math.atan2(_polyval(ss, rho_max), rho_max))

        if self.invpol is None:
            inv = fit_invpol(ss, rho_max)
        else:
            inv = _coefficients(self.invpol, "invpol", 1)
        err = _invpol_error(ss, inv, rho_max)
        if not err <= _INVPOL_MAX_ERR_PX:
            raise ValueError(
                f"invpol does not invert ss within the image circle (max error {err:.3g} px over rho <= "
                f"{rho_max:.1f} px); pass invpol=None to fit one"
            )
        object.__setattr__(self, "invpol", inv)
        object.__setattr__(self, "invpol_max_err_px", err)

    # ------------------------------------------------------------------------------------ constructors

    @classmethod
    def from_ocamcalib(
        cls, path: str | os.PathLike[str], *, rho_max: float | None = None, newton_steps: int = 2
    ) -> OmniCamera:
        """Read OCamCalib's ``calib_results.txt``. After dropping blank lines and ``#`` comments, five data
        lines remain, in this order: ``N a0 .. a(N-1)`` (ss), ``M p0 .. p(M-1)`` (invpol, any length),
        ``xc yc`` (centre row, column), ``c d e`` (affine), ``height width``. Each polynomial's count must
        match its values. ``rho_max``: the image circle's radius (px), which the file does not store.

        Raises ``alight.errors.InputError`` (one line naming the file and the problem) when the file is
        missing, unreadable or malformed, holds a non-finite value, or describes an invalid model."""
        p = Path(path)
        if not p.is_file():
            raise InputError(f"{p}: camera calibration file not found")
        try:
            text = p.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as ex:
            raise InputError(f"{p}: not a readable OCamCalib text file ({type(ex).__name__})") from None
        rows: list[tuple[int, list[float]]] = []
        for lineno, line in enumerate(text.splitlines(), start=1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            vals = []
            for tok in s.split():
                try:
                    v = float(tok)
                except ValueError:
                    raise InputError(f"{p}: line {lineno}: not a number: {tok[:40]!r}") from None
                if not math.isfinite(v):
                    raise InputError(f"{p}: line {lineno}: non-finite value {tok!r}")
                vals.append(v)
            rows.append((lineno, vals))
        names = ("ss (direct polynomial)", "invpol (inverse polynomial)", "centre", "affine", "image size")
        if len(rows) != 5:
            raise InputError(
                f"{p}: expected 5 data lines (ss, invpol, centre, affine, image size) after comments and "
                f"blank lines, found {len(rows)}"
            )
        polys = []
        for (lineno, vals), name in zip(rows[:2], names[:2], strict=True):
            n = vals[0]
            if n != int(n) or n < 1 or len(vals) - 1 != n:
                raise InputError(
                    f"{p}: line {lineno}: {name} declares {vals[0]:g} coefficients but has {len(vals) - 1}"
                )
            polys.append(np.array(vals[1:]))
        for (lineno, vals), name, n in zip(rows[2:], names[2:], (2, 3, 2), strict=True):
            if len(vals) != n:
                raise InputError(f"{p}: line {lineno}: {name} needs {n} values, found {len(vals)}")
        (xc, yc), (c, d, e), (h, w) = rows[2][1], rows[3][1], rows[4][1]
        if h != int(h) or w != int(w) or h < 1 or w < 1:
            raise InputError(f"{p}: line {rows[4][0]}: image size must be positive integers, got {h:g} {w:g}")
        try:
            return cls(
                width=int(w),
                height=int(h),
                ss=polys[0],
                invpol=polys[1],
                xc=xc,
                yc=yc,
                c=c,
                d=d,
                e=e,
                rho_max=rho_max,
                newton_steps=newton_steps,
            )
        except ValueError as ex:
            raise InputError(f"{p}: {ex}") from None

    @classmethod
    def synthetic(
        cls,
        width: int = 752,
        height: int = 480,
        *,
        fov_deg: float = 185.0,
        circle_radius_px: float | None = None,
    ) -> OmniCamera:
        """A generic fisheye for simulation: centre in the middle of the frame, no affine, the image circle
        of radius ``circle_radius_px`` (default: inscribed, ``min(width, height) / 2``) spanning the full
        cone ``fov_deg`` (0 < fov_deg <= 270). ``ss`` is ``a0 + a2 rho^2 + a3 rho^3 + a4 rho^4`` (``a1 = 0``
        as OCamCalib fits it), least-squares fitted to an equidistant lens (off-axis angle proportional to
        rho) and constrained to put the circle's edge exactly at ``fov_deg / 2``; ``invpol`` is then fitted
        like the toolbox does. E.g. ``synthetic(752, 480)``: a 185 deg circular fisheye on the 752 x 480
        sensor of paper 000's camera (a 480 px circle, black sides and corners)."""
        if not 0 < fov_deg <= 270:
            raise ValueError(f"fov_deg must be in (0, 270], got {fov_deg}")
        rho_max = min(width, height) / 2 if circle_radius_px is None else float(circle_radius_px)
        if not rho_max > 0:
            raise ValueError(f"circle_radius_px must be positive, got {circle_radius_px}")
        alpha_max = math.radians(fov_deg) / 2
        # equidistant: alpha = alpha_max x with x = rho / rho_max, so the ray (rho, f) has
        # f = -rho cot(alpha); fitted in x for conditioning, with x = 0 exact (f(0) = -rho_max / alpha_max)
        x = np.linspace(0.0, 1.0, 400)[1:]
        target = -x / np.tan(alpha_max * x)  # f / rho_max
        powers = (0, 2, 3, 4)
        A = np.stack([x**k for k in powers], axis=1)
        w_edge = 1e6  # the edge row as an (effectively) exact constraint: the circle spans fov_deg
        A = np.vstack([A, w_edge * A[-1]])
        b = np.concatenate([target, [w_edge * target[-1]]])
        coef = np.linalg.lstsq(A, b, rcond=None)[0]
        ss = np.zeros(5)
        for k, a in zip(powers, coef, strict=True):
            ss[k] = a * rho_max / rho_max**k
        return cls(
            width=width, height=height, ss=ss, xc=(height - 1) / 2, yc=(width - 1) / 2, rho_max=rho_max
        )

    # ------------------------------------------------------------------------------------ model

    def project(self, points_C: FloatArray) -> FloatArray:
        """Pixels ``(u, v)`` of points in C (any units), shape (N, 3) -> (N, 2): ``invpol`` polished by
        ``newton_steps`` Newton steps. NaN rows for rays outside the image circle's cone, straight back,
        zero or non-finite. Pixels outside the frame are returned as they are."""
        P = np.ascontiguousarray(points_C, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"points_C must have shape (N, 3), got {P.shape}")
        out = np.empty((P.shape[0], 2))
        _project_kernel(
            P, self.ss, self.invpol, self.xc, self.yc, self.c, self.d, self.e,
            self.theta_max, self.rho_max, self.newton_steps, out,
        )  # fmt: skip
        return out

    def project_exact(self, points_C: FloatArray) -> FloatArray:
        """Like :meth:`project`, but rho is the root of paper 003 eq. 24 chosen by :func:`solve_rho`
        (no ``invpol``); a few times slower. Shape (N, 3) -> (N, 2)."""
        P = np.ascontiguousarray(points_C, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 3:
            raise ValueError(f"points_C must have shape (N, 3), got {P.shape}")
        out = np.empty((P.shape[0], 2))
        _project_exact_kernel(
            P, self.ss, self.xc, self.yc, self.c, self.d, self.e, self.theta_max, self.rho_max, out
        )
        return out

    def unproject(self, pixels: FloatArray) -> FloatArray:
        """Unit rays in C through pixels ``(u, v)``, shape (N, 2) -> (N, 3) (direct polynomial). NaN rows
        outside the image circle (``rho > rho_max``) or for non-finite pixels. Rays beyond 90 deg off
        axis (a > 180 deg lens) have z < 0."""
        uv = np.ascontiguousarray(pixels, dtype=np.float64)
        if uv.ndim != 2 or uv.shape[1] != 2:
            raise ValueError(f"pixels must have shape (N, 2), got {uv.shape}")
        out = np.empty((uv.shape[0], 3))
        _unproject_kernel(uv, self.ss, self.xc, self.yc, self.c, self.d, self.e, self.rho_max, out)
        return out

    def ideal_radius(self, pixels: FloatArray) -> FloatArray:
        """rho of pixels ``(u, v)``: the distance from the centre after undoing the affine (px), shape
        (N, 2) -> (N,)."""
        uv = np.asarray(pixels, dtype=np.float64)
        if uv.ndim != 2 or uv.shape[1] != 2:
            raise ValueError(f"pixels must have shape (N, 2), got {uv.shape}")
        du, dv = uv[:, 0] - self.yc, uv[:, 1] - self.xc
        det = self.c - self.d * self.e
        return np.sqrt(((self.c * du - self.e * dv) / det) ** 2 + ((dv - self.d * du) / det) ** 2)

    def off_axis_angle(self, rho: float) -> float:
        """Angle between the optical axis and the ray through ideal radius ``rho`` (px), rad."""
        return math.atan2(rho, -_polyval(self.ss, rho))

    @property
    def circle_fov_rad(self) -> float:
        """Full cone angle of the image circle (rad), ``2 (theta_max + pi/2)``; > pi for a > 180 deg lens."""
        return 2.0 * self.off_axis_angle(self.rho_max)  # type: ignore[arg-type]

    def fov_rad(self) -> tuple[float, float]:
        """Full horizontal and vertical field of view (rad): the sum of the off-axis angles where the
        centre row (column) leaves the image, at the frame's outer pixel edge (-0.5, size - 0.5) or at
        the image circle, whichever comes first. Equals :meth:`circle_fov_rad` both ways when the frame
        contains the circle; as for :class:`PinholeCamera`, but can exceed pi."""
        W, H = self.width, self.height
        edges = np.array([[-0.5, self.xc], [W - 0.5, self.xc], [self.yc, -0.5], [self.yc, H - 0.5]])
        rho = np.minimum(self.ideal_radius(edges), self.rho_max)  # type: ignore[arg-type]  # float once built
        a = [self.off_axis_angle(float(r)) for r in rho]
        return a[0] + a[1], a[2] + a[3]

    def valid_mask(self) -> np.ndarray:
        """Pixels inside the image circle, bool (height, width): exactly where :meth:`unproject` of the
        pixel centre is finite."""
        du = np.arange(self.width, dtype=np.float64)[None, :] - self.yc
        dv = np.arange(self.height, dtype=np.float64)[:, None] - self.xc
        det = self.c - self.d * self.e
        # the same arithmetic as the unproject kernel, so the two agree on the circle's edge
        rho = np.sqrt(((self.c * du - self.e * dv) / det) ** 2 + ((dv - self.d * du) / det) ** 2)
        return np.asarray(rho <= self.rho_max)


# ------------------------------------------------------------------------------------------------
# Pure functions of the model
# ------------------------------------------------------------------------------------------------


def _coefficients(a: object, name: str, min_len: int) -> FloatArray:
    arr = np.array(a, dtype=np.float64).ravel()
    if arr.size < min_len or not np.isfinite(arr).all():
        raise ValueError(f"{name} must hold at least {min_len} finite coefficients, got {arr}")
    arr.setflags(write=False)
    return arr


def _polyval(coef: FloatArray, x: float) -> float:
    return float(np.polynomial.polynomial.polyval(x, coef))


def valid_radius(ss: FloatArray, rho_limit: float) -> float:
    """Largest rho in (0, ``rho_limit``] up to which the elevation ``atan2(f(rho), rho)`` strictly
    increases, i.e. ``rho f'(rho) - f(rho) > 0`` (px): within it every ray has one pixel. Checked on a
    grid of 8000 steps (the result is a grid point below the first failure, or ``rho_limit``)."""
    ss = np.asarray(ss, dtype=np.float64)
    rho = np.linspace(0.0, rho_limit, _N_CHECK)
    P = np.polynomial.polynomial
    g = rho * P.polyval(rho, P.polyder(ss)) - P.polyval(rho, ss)
    bad = ~(g > 0)
    if not bad.any():
        return float(rho_limit)
    i = int(np.argmax(bad))
    return float(rho[i - 1]) if i > 0 else 0.0


def _invpol_error(ss: FloatArray, invpol: FloatArray, rho_max: float) -> float:
    """Max |invpol(theta(rho)) - rho| over rho in [0, rho_max] (px)."""
    rho = np.linspace(0.0, rho_max, _N_CHECK)
    theta = np.arctan2(np.polynomial.polynomial.polyval(rho, ss), rho)
    return float(np.max(np.abs(np.polynomial.polynomial.polyval(theta, invpol) - rho)))


def fit_invpol(
    ss: FloatArray, rho_max: float, tol_px: float = _INVPOL_TOL_PX, max_terms: int = 40
) -> FloatArray:
    """The inverse polynomial of ``ss`` over the circle ``rho <= rho_max`` (ascending powers of theta,
    rad -> px): a least-squares fit of rho against theta, raising the degree (as the OCamCalib toolbox
    does) until the largest error is below ``tol_px``. ``ss`` must be monotonic there (see
    :func:`valid_radius`). Raises ValueError when ``max_terms`` do not suffice."""
    ss = np.asarray(ss, dtype=np.float64)
    rho = np.linspace(0.0, rho_max, 2000)
    theta = np.arctan2(np.polynomial.polynomial.polyval(rho, ss), rho)
    best = np.inf
    for n in range(2, max_terms + 1):
        # fitted in a scaled domain, then converted to plain powers of theta (the file format)
        poly, (_, rank, _, _) = Polynomial.fit(theta, rho, n - 1, full=True)
        if rank < n:
            break  # the samples cannot determine more terms
        coef = poly.convert().coef
        coef = np.pad(coef, (0, n - coef.size))
        err = float(np.max(np.abs(np.polynomial.polynomial.polyval(theta, coef) - rho)))
        best = min(best, err)
        if err < tol_px:
            coef.setflags(write=False)
            # float64, fitted to float64 samples: numpy's stubs type a Polynomial's coef inexact or object
            return cast(FloatArray, coef)
    raise ValueError(
        f"no inverse polynomial with <= {max_terms} terms within {tol_px} px over rho <= {rho_max:.1f} px "
        f"(best {best:.3g} px): is the elevation nearly flat there? (use a smaller rho_max)"
    )


def solve_rho(
    ss: FloatArray, K: float | FloatArray, rho_prev: float | None = None, rho_max: float = math.inf
) -> float | FloatArray:
    """rho (px) of the ray with ``K = z / r`` (OCam frame: tan of the elevation theta; in C, ``-Z / hypot(X,
    Y)``) by paper 003 eq. 24: the roots of ``a0 + (a1 - K) rho + a2 rho^2 + ... = 0`` (any number of
    coefficients, not just a quartic). The paper uses the closed-form quartic roots; here every real root
    in ``(0, min(rho_max, Cauchy bound)]`` is isolated between the roots of the polynomial's derivatives
    and refined by bracketed Newton: the same positive real roots to full precision, for any degree,
    in ~1 us (no complex arithmetic).

    Root selection, as the paper says: the root must be positive and real (and, here, no larger than
    ``rho_max``, the image circle). If several qualify, the one nearest ``rho_prev`` (the radius of the
    previous measurement, px); without a previous one, the smallest, which is the root on the branch
    connected to the image centre (where the elevation increases with rho, it is the only one). NaN where
    no root qualifies; 0 for ``K = -inf`` (the optical axis). ``K`` scalar or array (same shape out).

    ``solve_rho_jit(ss, K, rho_prev, rho_max)`` is the same function compiled for numba callers
    (``rho_prev = nan`` for none); call it directly from a filter's per-sigma-point code (~1 us, where
    this checked wrapper costs ~20 us)."""
    ss = np.ascontiguousarray(ss, dtype=np.float64).ravel()
    if ss.size < 2 or not np.isfinite(ss).all():
        raise ValueError(f"ss must hold at least 2 finite coefficients, got {ss}")
    prev = math.nan if rho_prev is None else float(rho_prev)
    if np.ndim(K) == 0:
        return float(solve_rho_jit(ss, float(K), prev, float(rho_max)))
    Ka = np.asarray(K, dtype=np.float64)
    out = np.array([solve_rho_jit(ss, float(k), prev, float(rho_max)) for k in Ka.ravel()])
    return out.reshape(Ka.shape)


@numba.njit(cache=True)
def select_root(roots: FloatArray, nr: int, rho_ref: float) -> float:  # pragma: no cover
    """Paper 003 after eq. 24: among the ``nr`` positive real roots ``roots`` (ascending), the one nearest
    ``rho_ref`` (the smallest when ``rho_ref`` is NaN, and on a tie); NaN when there is none."""
    if nr == 0:
        return math.nan
    best: float = roots[0]
    if np.isnan(rho_ref):
        return best
    for i in range(1, nr):
        if abs(roots[i] - rho_ref) < abs(best - rho_ref):
            best = roots[i]
    return best


@numba.njit(cache=True)
def solve_rho_jit(ss, K, rho_prev, rho_max):  # type: ignore[no-untyped-def]
    """:func:`solve_rho` for one ``K`` (numba; ``rho_prev = nan`` for none)."""
    if K == -np.inf:
        return 0.0
    if not (np.isfinite(K) and rho_max > 0):
        return np.nan
    p = ss.copy()
    p[1] -= K  # eq. 24: a0 + a1 rho + ... = rho K
    roots = np.empty(p.shape[0])
    nr = positive_real_roots(p, rho_max * (1.0 + _THETA_TOL), roots)
    return select_root(roots, nr, rho_prev)


@numba.njit(cache=True)
def project_exact_work(n):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The work arrays ``(coef, roots, D, crit)`` of :func:`project_exact_point` for ``n = len(ss)``."""
    return np.empty(n), np.empty(n), np.empty((n, n)), np.empty(n)


@numba.njit(cache=True)
def project_exact_point(  # type: ignore[no-untyped-def]
    Xc, Yc, Zc, ss, xc, yc, c, d, e, rho_ref, rho_max, coef, roots, D, crit
):  # pragma: no cover
    """Pixel ``(u, v)`` of one point ``(Xc, Yc, Zc)`` in C by paper 003 eq. 22-27: rho is the positive
    real root of eq. 24 within ``rho_max`` nearest ``rho_ref`` (:func:`select_root`); NaN when there is
    none or the point is straight behind. Work arrays for a caller in a loop (``n = len(ss)``): ``coef``,
    ``roots`` and ``crit`` of length n, ``D`` of shape (n, n)."""
    r = math.hypot(Xc, Yc)
    if not r > 0.0:
        if Zc > 0.0:
            return yc, xc  # on the optical axis
        return np.nan, np.nan
    for k in range(ss.shape[0]):
        coef[k] = ss[k]
    coef[1] += Zc / r  # eq. 24: a0 + (a1 - K) rho + ... = 0 with K = -Z_C / r
    nr = positive_real_roots_into(coef, rho_max, roots, D, crit)
    rho = select_root(roots, nr, rho_ref)
    if np.isnan(rho):
        return np.nan, np.nan
    Xs = rho * Xc / r  # eq. 26, 27 in the ideal sensor plane
    Ys = rho * Yc / r
    return yc + Xs + e * Ys, xc + d * Xs + c * Ys


@numba.njit(cache=True)
def _unproject_kernel(uv, ss, xc, yc, c, d, e, rho_max, out):  # type: ignore[no-untyped-def]
    det = c - d * e
    for i in range(uv.shape[0]):
        du = uv[i, 0] - yc
        dv = uv[i, 1] - xc
        # undo the affine: OCam's (row, col) offsets are [[c, d], [e, 1]] (x_ocam, y_ocam), and
        # x_C = y_OCam, y_C = x_OCam
        X = (c * du - e * dv) / det
        Y = (dv - d * du) / det
        rho = math.sqrt(X * X + Y * Y)
        if not rho <= rho_max:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            out[i, 2] = np.nan
            continue
        Z = -horner(ss, ss.shape[0] - 1, rho)  # z_C = -z_OCam = -f(rho), eq. 2-4
        n = math.sqrt(X * X + Y * Y + Z * Z)
        out[i, 0] = X / n
        out[i, 1] = Y / n
        out[i, 2] = Z / n


@numba.njit(cache=True)
def _ray_elevation(P, i):  # type: ignore[no-untyped-def]
    """Unit-scaled (r, z_OCam) of row i and whether it is a usable ray."""
    X = P[i, 0]
    Y = P[i, 1]
    Z = P[i, 2]
    r = math.sqrt(X * X + Y * Y)
    n = math.sqrt(r * r + Z * Z)
    ok = n > 0 and np.isfinite(n)
    if not ok:
        return 0.0, 0.0, False
    return r / n, -Z / n, True


@numba.njit(cache=True)
def _ray_in_circle(P, i, theta_max):  # type: ignore[no-untyped-def]
    """:func:`_ray_elevation` of row i, its elevation theta, and whether it projects: a usable ray, not
    straight back, within the image circle's cone (``theta <= theta_max``, with slack)."""
    r, zo, ok = _ray_elevation(P, i)
    theta = math.atan2(zo, r)
    return r, zo, theta, ok and theta <= theta_max + _THETA_TOL and not (r == 0.0 and zo >= 0.0)


@numba.njit(cache=True)
def _to_pixel(X, Y, r, rho, xc, yc, c, d, e, out, i):  # type: ignore[no-untyped-def]
    if r > 0:
        Xs = rho * X / r
        Ys = rho * Y / r
    else:
        Xs = 0.0
        Ys = 0.0
    out[i, 0] = yc + Xs + e * Ys
    out[i, 1] = xc + d * Xs + c * Ys


@numba.njit(cache=True)
def _project_kernel(P, ss, invpol, xc, yc, c, d, e, theta_max, rho_max, newton_steps, out):  # type: ignore[no-untyped-def]
    for i in range(P.shape[0]):
        r, zo, theta, ok = _ray_in_circle(P, i, theta_max)
        if not ok:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            continue
        if r == 0.0:
            rho = 0.0  # the axis: invpol(-pi/2) is not exactly 0
        else:
            rho = horner(invpol, invpol.shape[0] - 1, theta)
            # Newton on F(rho) = r f(rho) - z rho (eq. 24 times r); F' = r f' - z > 0 wherever the
            # elevation increases, i.e. inside the circle
            for _ in range(newton_steps):
                f, df = horner_d(ss, ss.shape[0] - 1, rho)
                F = r * f - zo * rho
                dF = r * df - zo
                if not dF > 0:
                    break
                step = F / dF
                if not (rho - step >= 0.0 and rho - step <= rho_max * 1.01):
                    break
                rho -= step
        _to_pixel(P[i, 0], P[i, 1], math.sqrt(P[i, 0] ** 2 + P[i, 1] ** 2), rho, xc, yc, c, d, e, out, i)


@numba.njit(cache=True)
def _project_exact_kernel(P, ss, xc, yc, c, d, e, theta_max, rho_max, out):  # type: ignore[no-untyped-def]
    coef, roots, D, crit = project_exact_work(ss.shape[0])
    for i in range(P.shape[0]):
        r, zo, theta, ok = _ray_in_circle(P, i, theta_max)
        if not ok:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            continue
        u, v = project_exact_point(
            P[i, 0], P[i, 1], P[i, 2], ss, xc, yc, c, d, e, np.nan, rho_max * (1.0 + _THETA_TOL),
            coef, roots, D, crit,
        )  # fmt: skip
        out[i, 0] = u
        out[i, 1] = v
