"""n-fold marker detector (MarkerLocator's method, H. S. Midtiby; paper 004, Zamanakos et al., Sec. IV-A).

Written from the method as described in ``shared/references/nfold_marker.md`` (section numbers below are
that sheet's) and paper 004, not from MarkerLocator's code. Conventions: ``x`` is the column (right), ``y``
the row (down); an image angle runs from +x toward +y (clockwise on screen), as ``atan2(dy, dx)``.

The method
----------
*Marker* (sheet 1): ``n`` black and ``n`` white wedges of ``pi/n`` each meeting at the *tip*; the
*oriented* variant leaves one black wedge white (the "missing leg") and so has a unique heading.

*Kernel* (sheet 2): for odd ``k``, ``h = (k-1)/2``, offsets ``(u, v)`` from the kernel centre,
``x = u/h``, ``y = v/h``::

    K_n(u, v) = (x + i y)^n exp(-8 (x^2 + y^2))                                          (S2)

normalised here to ``sum |K| = 1`` (an ideal marker of contrast C then gives ``|R| ~ C/pi``), and with
the mean of its real and imaginary parts removed (Re K of an even order leaks ~1e-3 of DC on the square
grid; without it a uniform image has no response at all).

*Response* (sheet 2-3): the correlation ``R = Re + i Im`` of the grey image with ``K_n`` (reflect-101
border), ``M = |R|^2``; the integer tip is the pixel of the largest ``M`` (paper 004: "the pixel with the
highest magnitude is considered as a candidate tip").

*Orientation* (sheet 4): ``theta0 = (atan2(Im, Re) - pi)/n`` at the tip is the centre line of a black
wedge; ``theta0 + 2 pi j / n`` are equally valid. Oriented marker: the candidate leg whose template core
is brightest is the missing leg, and ``theta`` is its direction (unique). Plain marker: ``theta`` is
reported in ``(-pi/n, pi/n]`` (it holds modulo ``2 pi / n``). The sheet's optional refinement is done:
the phase read bilinearly at the sub-pixel tip, the candidate nearest the integer-peak ``theta`` kept.
(The sheet's missing-leg probe reads one pixel per leg at ``k/3``; here each leg is the mean over that
leg's dark template core, the same region the quality score uses, which a single noisy pixel cannot flip.)

*Quality* (sheet 5), on the ``k x k`` 8-bit patch at the integer tip: template
``A = |K_n| cos(n (phi - theta))`` (negated in the missing-leg wedge ``|wrap(phi - theta)| < pi/(2n)``
for an oriented marker), dark cores ``D = {A > tau}``, bright cores ``B = {A < -tau}``,
``tau = 0.4 max |K_n|``; ``t = (mu_B - mu_D) / (0.5 sigma_B + 0.5 sigma_D)``;
``q = 1 / (1 + exp(-0.75 (t - 7)))``; ``q = 0`` when the patch leaves the image.

*Sub-pixel* (sheet 6): a quadratic ``a x^2 + b x + c y^2 + d y + e`` least-squares fit to ``sqrt(M)`` on the
3x3 neighbourhood, in closed form from the column (row) means ``m-, m0, m+``:
``dx = (m- - m+) / (2 (m- + m+ - 2 m0))``; 0 at the image border or when the fit is not a maximum
(``a >= 0``), clipped to +-1.

*Adaptive kernel size* (paper 004 Sec. IV-A, sheet 7): "an adaptive kernel selection function is created
to ensure the selection of a proper kernel size based on a threshold quality score value", starting at
13 x 13. The paper gives no step or limit; here the sizes of :attr:`NFoldConfig.kernel_sizes` are tried in
turn and the first whose quality reaches ``min_quality`` is the detection; none passing means no marker.

How it is made fast (sheet 9)
-----------------------------
:func:`nfold_response_filter2d` is the plain method (two full-frame ``cv2.filter2D``, float32): the
reference for the tests and the benchmark. :class:`NFoldDetector` computes the same response as follows:

1. *Separable kernel.* ``Re K`` and ``Im K`` are each a sum of a few rank-1 terms (their SVDs; exact,
   since ``(x+iy)^n e^{-8 r^2} = sum_j C(n,j) i^j [x^{n-j} e^{-8x^2}] [y^j e^{-8y^2}]``, sheet 9): rank 4 + 2
   for n = 4 (the DC removal adds one), 3 + 3 for n = 5. Each term is one ``sepFilter2D`` (2 k taps per
   pixel instead of k^2).
2. *Coarse to fine.* The candidates come from the image downscaled by an integer ``s`` (INTER_AREA,
   about ``k / 12``, at least 2; :func:`coarse_plan`) with a kernel of size ``k / s`` (at least
   ``coarse_min_k``, since a too small coarse kernel picks the wrong marker, sheet 9), using the kernel
   without its DC removal (one term fewer, a ~1e-3 change): the ``n_candidates`` strongest local maxima
   of the coarse ``|R|``. Each is then refined at full resolution with the full kernel over a small
   window (a numba kernel with the same separable factors and the same reflect-101 border, so the values
   equal the full-frame ones), moved until its maximum is inside the window.
3. The candidate of largest full-resolution ``M`` is the method's tip (it is the full-frame argmax
   whenever that lies in one of the windows: the same detection as the plain method, checked on rendered
   frames in the tests). Unlike the method, which has one candidate per frame, the next-strongest
   candidates are checked in turn when it fails the quality threshold, so a stronger distractor (another
   marker, a line crossing) does not hide the marker; ``n_candidates = 1`` is the method's single guess.

Speed at 752 x 480 on one core: ``benchmarks/bench_nfold.py`` (its module docstring has the figures).

*Edges through the tip* (``min_ray_consistency``, not in the paper or the sheet). The quality score looks at
one scale, the kernel's, and a pattern that is n-fold only there passes it: where four square markers of a
board meet, the white gaps between them are a cross whose arms, at the kernel's radius, are about as wide
as a 4-fold marker's white wedges (q = 0.997 on a down-scaled board photo). The marker's own geometry
tells them apart: its 2n edges are straight lines through the tip, and a perspective view maps straight
lines to straight lines and the tip to the tip, so its image is a function of the angle about the tip
alone, the same bright and dark arcs on every circle round it (up to blur). A bar's edges run parallel to
the bar, so the angular width of a gap shrinks as 1 / r. :func:`ray_consistency` compares the two circles
at 0.35 and 0.85 of the kernel's half size round the sub-pixel tip, each split at its own mid-grey: the
fraction of angles where they agree was 0.875-1.0 (median 0.97-0.99) on 77 rendered markers from 1.5 to
18 m, tilted up to 0.45 rad, with sensor noise, and 1.0 on the real photo of a marker; 0.58 on the
board's crossing and 0.56-0.67 on drawn crossings of 5-6 px gaps. (A crossing of 3 px gaps is, at that
scale, the image of a marker of 6 px radius: no test at the pixel level tells them apart.) A candidate
below ``min_ray_consistency`` (0.75) is not a marker, and the next candidate is tried.

Known limit of the oriented template: a T-junction of thick dark bars (the border of a square marker meeting
a dark cell, a ChArUco board) looks like three legs and a missing one; on the real ChArUco photos the
oriented 4-fold template scored q = 1.0 there, while the plain 4-fold template stayed at or below 0.27 on
every square-marker photo. :class:`alight.pads.SduPad` therefore uses a plain marker by default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

from alight.perception.image_input import as_gray_u8, check_time
from alight.types import FloatArray, Image, Observation, U8Array

F32Array = NDArray[np.float32]

QUALITY_SLOPE = 0.75
"""Slope of the quality sigmoid in ``t`` (sheet 5)."""
QUALITY_T0 = 7.0
"""Contrast-to-spread ratio ``t`` at which the quality is 0.5 (sheet 5)."""
TEMPLATE_TAU = 0.4
"""Template cores are where ``|A| > TEMPLATE_TAU max |K_n|`` (sheet 5)."""


# --------------------------------------------------------------------------------------------------
# Kernel
# --------------------------------------------------------------------------------------------------


def nfold_kernel(n: int, k: int, centred: bool = True) -> NDArray[np.complex128]:
    """The complex kernel ``K_n`` (S2) of order ``n`` and odd size ``k``, shape (k, k), indexed
    ``[row (v), column (u)]``, normalised to ``sum |K| = 1``; ``centred``: with the means of its real and
    imaginary parts removed (the kernel the detector uses)."""
    _check_order_size(n, k)
    h = (k - 1) / 2
    c = np.arange(k, dtype=np.float64) - h
    x = (c / h)[None, :]
    y = (c / h)[:, None]
    K = (x + 1j * y) ** n * np.exp(-8.0 * (x * x + y * y))
    K = K / np.abs(K).sum()
    if not centred:
        return K  # type: ignore[no-any-return]
    return (K.real - K.real.mean()) + 1j * (K.imag - K.imag.mean())  # type: ignore[no-any-return]


def _check_order_size(n: int, k: int) -> None:
    if int(n) != n or n < 2:
        raise ValueError(f"the marker order n must be an integer >= 2, got {n}")
    if int(k) != k or k < 5 or k % 2 == 0:
        raise ValueError(f"the kernel size k must be an odd integer >= 5, got {k}")


@dataclass(frozen=True, eq=False)
class _KernelParts:
    """What the detector needs of one (n, k): separable factors, float32 2-D parts, template maps."""

    n: int
    k: int
    re: F32Array  # (k, k) Re K
    im: F32Array  # (k, k) Im K
    fx: F32Array  # (T, k) horizontal factors (along x / columns) of the centred kernel
    fy: F32Array  # (T, k) vertical factors (along y / rows)
    part: NDArray[np.int64]  # (T,) 0: term of Re K, 1: term of Im K
    cfx: F32Array  # the same for the uncentred kernel (one term fewer for an even n): coarse search
    cfy: F32Array
    cpart: NDArray[np.int64]
    absK: NDArray[np.float64]  # (k, k) |K_n| before centring (the quality template's weight)
    phi: NDArray[np.float64]  # (k, k) angle of each kernel pixel from the centre (image convention)


_PARTS: dict[tuple[int, int], _KernelParts] = {}


def _separable_factors(K: NDArray[np.complex128]) -> tuple[F32Array, F32Array, NDArray[np.int64]]:
    """Rank-1 terms of Re K and Im K from their SVDs: ``A = sum_t fy[t] (x) fx[t]``. The exact rank is
    small (sheet 9's binomial identity: n + 1 terms, one more for a centred even order); the singular
    values beyond it are rounding noise."""
    fx, fy, part = [], [], []
    for p, A in enumerate((K.real, K.imag)):
        U, S, Vt = np.linalg.svd(A)
        for i in np.flatnonzero(S > 1e-6 * S[0]):
            fy.append(U[:, i] * S[i])
            fx.append(Vt[i])
            part.append(p)
    return (
        np.ascontiguousarray(fx, dtype=np.float32),
        np.ascontiguousarray(fy, dtype=np.float32),
        np.asarray(part, dtype=np.int64),
    )


def _kernel_parts(n: int, k: int) -> _KernelParts:
    key = (int(n), int(k))
    parts = _PARTS.get(key)
    if parts is None:
        K = nfold_kernel(n, k)
        K0 = nfold_kernel(n, k, centred=False)
        fx, fy, part = _separable_factors(K)
        cfx, cfy, cpart = _separable_factors(K0)
        c = np.arange(k, dtype=np.float64) - (k - 1) / 2
        parts = _KernelParts(
            n=int(n),
            k=int(k),
            re=np.ascontiguousarray(K.real, dtype=np.float32),
            im=np.ascontiguousarray(K.imag, dtype=np.float32),
            fx=fx,
            fy=fy,
            part=part,
            cfx=cfx,
            cfy=cfy,
            cpart=cpart,
            absK=np.abs(K0),
            phi=np.arctan2(c[:, None] * np.ones((1, k)), np.ones((k, 1)) * c[None, :]),
        )
        _PARTS[key] = parts
    return parts


# --------------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class NFoldResult:
    """One n-fold marker candidate (pixels in the image the detector was given)."""

    x: float
    """Sub-pixel tip column (px)."""
    y: float
    """Sub-pixel tip row (px)."""
    x_int: int
    """Integer tip column: the pixel of largest magnitude (px)."""
    y_int: int
    """Integer tip row (px)."""
    theta: float
    """Image angle (rad, from +x toward +y): the missing leg's direction for an oriented marker, in
    (-pi, pi]; a black wedge's centre line for a plain one, in (-pi/n, pi/n] (valid modulo 2 pi / n)."""
    quality: float
    """Quality score in [0, 1] (sheet 5)."""
    magnitude: float
    """``|R|`` at the integer tip (grey levels; an ideal marker of contrast C gives about C / pi)."""
    k: int
    """Kernel size that gave this result (px)."""
    n: int
    """Marker order."""
    kernel_sizes_tried: tuple[int, ...] = ()
    """Kernel sizes tried by the adaptive search up to this one (empty for a fixed-size search)."""


# --------------------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------------------


@numba.njit(cache=True, inline="always")
def _refl(i, n):  # type: ignore[no-untyped-def]  # pragma: no cover - numba
    """Reflect-101 index (OpenCV's BORDER_DEFAULT) for ``-n < i < 2n - 1``."""
    if i < 0:
        return -i
    if i >= n:
        return 2 * n - 2 - i
    return i


@numba.njit(cache=True, fastmath=True)
def _window_response(img, x0, y0, w, h, fx, fy, part):  # type: ignore[no-untyped-def]  # pragma: no cover - numba
    """Re and Im of the correlation with the separable kernel ``sum_t fy[t] (x) fx[t]`` over the output
    window of columns ``x0 .. x0+w-1`` and rows ``y0 .. y0+h-1`` (inside the image) of the float32 image,
    with the reflect-101 border. Returns two float64 arrays (h, w). (fastmath: the inputs are finite.)"""
    H, W = img.shape
    T, k = fx.shape
    r = k // 2
    pw = w + 2 * r
    ph = h + 2 * r
    # the window with its margin, reflected at the image border, as one contiguous block
    pad = np.empty((ph, pw), np.float64)
    for i in range(ph):
        row = img[_refl(y0 - r + i, H)]
        for j in range(pw):
            pad[i, j] = row[_refl(x0 - r + j, W)]
    re = np.zeros((h, w), np.float64)
    im = np.zeros((h, w), np.float64)
    tmp = np.empty((ph, w), np.float64)
    for t in range(T):
        ft = fx[t].astype(np.float64)
        gt = fy[t].astype(np.float64)
        for i in range(ph):
            for j in range(w):
                s = 0.0
                for m in range(k):
                    s += pad[i, j + m] * ft[m]
                tmp[i, j] = s
        out = re if part[t] == 0 else im
        for i in range(h):
            for m in range(k):
                g = gt[m]
                for j in range(w):
                    out[i, j] += tmp[i + m, j] * g
    return re, im


@numba.njit(cache=True)
def _wrap(a):  # type: ignore[no-untyped-def]  # pragma: no cover - numba
    """Angle wrapped to (-pi, pi]."""
    b = a - 2.0 * np.pi * np.floor((a + np.pi) / (2.0 * np.pi))
    return np.pi if b <= -np.pi else b


@numba.njit(cache=True)
def _quality_kernel(gray, xi, yi, n, theta0, oriented, absK, phi, tau_frac, slope, t0):  # type: ignore[no-untyped-def]  # pragma: no cover - numba
    """Leg choice and quality score (sheet 4-5) on the k x k patch of the uint8 image at (xi, yi).
    Returns ``(q, theta)``: theta is the missing leg (oriented) or theta0 (plain)."""
    H, W = gray.shape
    k = absK.shape[0]
    r = k // 2
    if xi - r < 0 or yi - r < 0 or xi + r >= W or yi + r >= H:
        return 0.0, theta0
    amax = 0.0
    for i in range(k):
        for j in range(k):
            if absK[i, j] > amax:
                amax = absK[i, j]
    tau = tau_frac * amax
    step = 2.0 * np.pi / n
    theta = theta0
    if oriented:
        # the missing leg: the candidate whose dark core (as the template sees it) is brightest
        sums = np.zeros(n)
        cnts = np.zeros(n)
        for i in range(k):
            for j in range(k):
                if absK[i, j] * np.cos(n * (phi[i, j] - theta0)) > tau:
                    leg = int(np.floor(_wrap(phi[i, j] - theta0) / step + 0.5)) % n
                    sums[leg] += gray[yi - r + i, xi - r + j]
                    cnts[leg] += 1.0
        best = -1.0
        jbest = 0
        for leg in range(n):
            if cnts[leg] > 0 and sums[leg] / cnts[leg] > best:
                best = sums[leg] / cnts[leg]
                jbest = leg
        theta = _wrap(theta0 + jbest * step)
    half = np.pi / (2 * n)
    sb = 0.0
    sbb = 0.0
    nb = 0.0
    sd = 0.0
    sdd = 0.0
    nd = 0.0
    for i in range(k):
        for j in range(k):
            a = absK[i, j] * np.cos(n * (phi[i, j] - theta))
            if oriented and abs(_wrap(phi[i, j] - theta)) < half:
                a = -a
            g = float(gray[yi - r + i, xi - r + j])
            if a > tau:
                sd += g
                sdd += g * g
                nd += 1.0
            elif a < -tau:
                sb += g
                sbb += g * g
                nb += 1.0
    if nb < 1 or nd < 1:
        return 0.0, theta
    mb = sb / nb
    md = sd / nd
    vb = max(sbb / nb - mb * mb, 0.0)
    vd = max(sdd / nd - md * md, 0.0)
    den = 0.5 * np.sqrt(vb) + 0.5 * np.sqrt(vd)
    diff = mb - md
    if den < 1e-9:
        tt = 1e9 if diff > 1e-9 else 0.0
    else:
        tt = diff / den
    z = slope * (tt - t0)
    if z > 50.0:
        return 1.0, theta
    return 1.0 / (1.0 + np.exp(-z)), theta


# --------------------------------------------------------------------------------------------------
# Peak post-processing shared by the reference and the fast path
# --------------------------------------------------------------------------------------------------


def _vertex(m_: float, m0: float, mp: float) -> float:
    """Sheet 6: vertex offset of the parabola through the means (-1, m_), (0, m0), (1, mp); 0 when it is
    not a maximum, clipped to +-1."""
    den = m_ + mp - 2.0 * m0  # = 2a of the fit; a maximum needs a < 0
    if not den < 0.0:
        return 0.0
    return min(1.0, max(-1.0, (m_ - mp) / (2.0 * den)))


def _finish(
    gray: U8Array,
    re: FloatArray,
    im: FloatArray,
    iy: int,
    ix: int,
    ox: int,
    oy: int,
    parts: _KernelParts,
    oriented: bool,
) -> NFoldResult:
    """Orientation, quality and sub-pixel tip at the integer peak ``(iy, ix)`` of the response arrays
    ``re``/``im`` (float64) whose element (0, 0) is the image pixel (ox, oy). The peak must not be on the
    arrays' edge unless it is on the image's."""
    H, W = gray.shape
    n = parts.n
    step = 2.0 * math.pi / n
    X, Y = ix + ox, iy + oy
    r0, i0 = float(re[iy, ix]), float(im[iy, ix])
    theta0 = (math.atan2(i0, r0) - math.pi) / n  # sheet 4
    q, theta = _quality_kernel(
        gray, X, Y, n, theta0, oriented, parts.absK, parts.phi, TEMPLATE_TAU, QUALITY_SLOPE, QUALITY_T0
    )
    dx = dy = 0.0
    if 0 < X < W - 1 and 0 < Y < H - 1:
        P = np.sqrt(re[iy - 1 : iy + 2, ix - 1 : ix + 2] ** 2 + im[iy - 1 : iy + 2, ix - 1 : ix + 2] ** 2)
        c = P.sum(axis=0)  # column sums (the means times 3: the vertex is the same)
        r = P.sum(axis=1)
        dx = _vertex(float(c[0]), float(c[1]), float(c[2]))
        dy = _vertex(float(r[0]), float(r[1]), float(r[2]))
        # orientation refined at the sub-pixel tip (Re, Im bilinear), the candidate nearest the integer one
        bx, by = (ix if dx > 0 else ix - 1), (iy if dy > 0 else iy - 1)  # top-left of the 2x2 cell
        fx, fy = (dx if dx > 0 else 1.0 + dx), (dy if dy > 0 else 1.0 + dy)
        w00, w01, w10, w11 = (1 - fy) * (1 - fx), (1 - fy) * fx, fy * (1 - fx), fy * fx
        rs = w00 * re[by, bx] + w01 * re[by, bx + 1] + w10 * re[by + 1, bx] + w11 * re[by + 1, bx + 1]
        is_ = w00 * im[by, bx] + w01 * im[by, bx + 1] + w10 * im[by + 1, bx] + w11 * im[by + 1, bx + 1]
        if rs != 0.0 or is_ != 0.0:
            ts = (math.atan2(float(is_), float(rs)) - math.pi) / n
            theta = theta + math.remainder(ts - theta, step)
    if oriented:
        theta = _wrap_pi(theta)
    else:
        theta = math.remainder(theta, step)
        if theta <= -step / 2:
            theta += step  # (-pi/n, pi/n]
    return NFoldResult(
        x=X + dx,
        y=Y + dy,
        x_int=int(X),
        y_int=int(Y),
        theta=float(theta),
        quality=min(1.0, max(0.0, float(q))),
        magnitude=math.sqrt(r0 * r0 + i0 * i0),
        k=parts.k,
        n=n,
    )


def _wrap_pi(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    b = math.remainder(a, 2.0 * math.pi)
    return math.pi if b <= -math.pi else b


# --------------------------------------------------------------------------------------------------
# The plain method (reference)
# --------------------------------------------------------------------------------------------------


def nfold_response_filter2d(gray: NDArray[np.generic], n: int, k: int) -> tuple[F32Array, F32Array]:
    """The response of the plain method (sheet 2): ``Re`` and ``Im`` of the correlation of the grey image
    (2-D, any numeric type; used as float32 on the 0..255 scale) with ``K_n`` of size ``k``, each a full-
    frame ``cv2.filter2D`` to float32 with the reflect-101 border. Shapes (H, W)."""
    g = np.asarray(gray)
    if g.ndim != 2:
        raise ValueError(f"gray must be a 2-D image, got shape {g.shape}")
    parts = _kernel_parts(n, k)
    f = g.astype(np.float32, copy=False)
    # float32 (CV_32F); OpenCV's stubs type the results MatLike, without the dtype
    re: NDArray[Any] = cv2.filter2D(f, cv2.CV_32F, parts.re)
    im: NDArray[Any] = cv2.filter2D(f, cv2.CV_32F, parts.im)
    return re, im


def nfold_detect_filter2d(image: Image, n: int, k: int, oriented: bool = False) -> NFoldResult | None:
    """The plain method end to end at one kernel size: :func:`nfold_response_filter2d`, the global
    argmax of ``M`` (sheet 3), orientation, quality and sub-pixel tip. No threshold: the result carries
    its quality. None for an unusable image or one smaller than the kernel."""
    gray = as_gray_u8(image)
    if gray is None or min(gray.shape) < k:
        return None
    re, im = nfold_response_filter2d(gray, n, k)
    M = re.astype(np.float64) ** 2 + im.astype(np.float64) ** 2
    iy, ix = np.unravel_index(int(np.argmax(M)), M.shape)
    return _finish(
        gray,
        re.astype(np.float64),
        im.astype(np.float64),
        int(iy),
        int(ix),
        0,
        0,
        _kernel_parts(n, k),
        oriented,
    )


# --------------------------------------------------------------------------------------------------
# The fast detector
# --------------------------------------------------------------------------------------------------


def _default_sizes() -> tuple[int, ...]:
    # paper 004 starts at 13 x 13 and gives no step or limit; 41 covers the sheet's occluded-tip case
    # (a grey disc of r = 24 px over the tip passed at k = 41) and bounds the cost of a frame without a
    # marker, which tries every size
    return tuple(range(13, 42, 4))


@dataclass(frozen=True, kw_only=True)
class NFoldConfig:
    """Parameters of :class:`NFoldDetector` (pixels are pixels of the image given to ``detect``)."""

    order: int = 4
    """Marker order n: the number of black wedges, a missing leg included (sheet 1)."""
    oriented: bool = False
    """True for a marker with a missing leg (unique heading); False for a plain one."""
    kernel_sizes: tuple[int, ...] = field(default_factory=_default_sizes)
    """Kernel sizes (odd, px) the adaptive selection tries in turn: 13, 17, ..., 41 (paper 004 starts at
    13 x 13 and gives no step or limit; a frame without a marker tries them all)."""
    min_quality: float = 0.9
    """Quality threshold of a detection. Sheet 5: q > 0.5 is "quite confident"; q >= 0.9 rejected every
    negative tested (a line crossing reached 0.65 at k = 31)."""
    n_candidates: int = 4
    """Local maxima of the coarse response refined at full resolution per kernel size (1: the method's
    single candidate)."""
    coarse: bool = True
    """Coarse-to-fine search; False computes the full-resolution response over the whole frame (the
    separable form), which is slower and finds the same peak."""
    coarse_min_k: int = 11
    """Least kernel size at the coarse scale (sheet 9: a 7 x 7 coarse kernel chose the wrong marker)."""
    min_magnitude: float = 0.5
    """Candidates with ``|R|`` below this (grey levels; a marker of contrast C gives ~C/pi) are numerical
    noise of a uniform image, not candidates."""
    min_ray_consistency: float = 0.75
    """Least fraction of angles at which two circles round the tip agree on bright and dark
    (:func:`ray_consistency`; the module docstring's "Edges through the tip", not in the paper): a
    marker's edges are rays from its tip; 0 turns the check off (the paper's method)."""

    def __post_init__(self) -> None:
        sizes = tuple(int(k) for k in self.kernel_sizes)
        object.__setattr__(self, "kernel_sizes", sizes)
        checks = {
            "order": int(self.order) == self.order and self.order >= 2,
            "kernel_sizes": len(sizes) > 0 and all(k >= 5 and k % 2 == 1 for k in sizes),
            "min_quality": math.isfinite(self.min_quality) and 0.0 <= self.min_quality <= 1.0,
            "n_candidates": int(self.n_candidates) == self.n_candidates and self.n_candidates >= 1,
            "coarse_min_k": int(self.coarse_min_k) == self.coarse_min_k
            and self.coarse_min_k >= 5
            and self.coarse_min_k % 2 == 1,
            "min_magnitude": math.isfinite(self.min_magnitude) and self.min_magnitude >= 0,
            "min_ray_consistency": math.isfinite(self.min_ray_consistency)
            and 0.0 <= self.min_ray_consistency <= 1.0,
        }
        bad = [name for name, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"invalid NFoldConfig values: {bad}")


def coarse_plan(k: int, coarse_min_k: int = 11) -> tuple[int, int]:
    """``(s, k_c)``: the integer downscale of the coarse search for kernel size ``k`` (about ``k / 12``,
    at least 2) and the coarse kernel size (odd, about ``k / s``, at least ``coarse_min_k``). Consecutive
    sizes often share a plan (13, 17 and 21 all give (2, 11)), and then one adaptive search computes the
    coarse response once for all of them."""
    s = max(2, int(round(k / 12.0)))
    kc = max(coarse_min_k, int(round(k / s)) | 1)
    return s, kc


class NFoldDetector:
    """n-fold marker detector (the method of the module docstring, made fast). ``detect(image, t)`` is a
    pure function of the image.

    Parameters
    ----------
    config:
        :class:`NFoldConfig` (order, oriented, kernel sizes, quality threshold, search options).
    tip_P:
        Where the tip is on the pad, in P (m), shape (3,); when given, observations carry it as
        ``points_P``.
    """

    def __init__(self, config: NFoldConfig | None = None, tip_P: FloatArray | None = None) -> None:
        self.config = NFoldConfig() if config is None else config
        self.tip_P = None if tip_P is None else np.asarray(tip_P, dtype=np.float64).reshape(3)
        for k in self.config.kernel_sizes:
            _kernel_parts(self.config.order, k)
            if self.config.coarse:
                _kernel_parts(self.config.order, coarse_plan(k, self.config.coarse_min_k)[1])

    # ------------------------------------------------------------------------------------ public API

    def detect(self, image: Image, t: float) -> list[Observation]:
        """At most one observation (kind ``nfold``): the tip as the single image point, the quality, and
        for an oriented marker ``yaw_CP`` = the missing leg's image angle (the pad's x axis when the leg
        points along it, as on :class:`alight.pads.SduPad`); ``[]`` when no kernel size reaches
        ``min_quality`` or the image is unusable (:mod:`alight.perception.image_input`)."""
        t = check_time(t)
        res = self.detect_result(image)
        if res is None:
            return []
        pts = None if self.tip_P is None else self.tip_P[None, :]
        yaw = res.theta if self.config.oriented else None
        return [
            Observation(
                t=t,
                kind="nfold",
                quality=res.quality,
                pixels=np.array([[res.x, res.y]]),
                points_P=pts,
                yaw_CP=yaw,
            )
        ]

    def detect_result(self, image: Image) -> NFoldResult | None:
        """The adaptive search (paper 004): the first kernel size whose strongest candidate reaching
        ``min_quality`` exists; None when there is none (or the image is unusable)."""
        gray = as_gray_u8(image)
        if gray is None:
            return None
        cfg = self.config
        tried: list[int] = []
        search = _Search(gray, cfg)
        for k in cfg.kernel_sizes:
            if min(gray.shape) < k:
                break
            tried.append(k)
            for peak in search.peaks(k):
                res = peak.finish()
                if res.quality >= cfg.min_quality and self._edges_through_tip(gray, res):
                    return _with_tried(res, tuple(tried))
        return None

    def _edges_through_tip(self, gray: U8Array, res: NFoldResult) -> bool:
        floor = self.config.min_ray_consistency
        return floor <= 0.0 or ray_consistency(gray, res.x, res.y, res.k) >= floor

    def detect_at(self, image: Image, k: int) -> NFoldResult | None:
        """The method at one kernel size: the candidate of largest full-resolution magnitude, whatever
        its quality (compare :func:`nfold_detect_filter2d`); None for an unusable image."""
        gray = as_gray_u8(image)
        if gray is None or min(gray.shape) < k:
            return None
        _check_order_size(self.config.order, k)
        peaks = _Search(gray, self.config).peaks(k)
        return peaks[0].finish() if peaks else None

    def candidates(self, image: Image, k: int) -> list[NFoldResult]:
        """Every refined candidate at kernel size ``k``, largest magnitude first."""
        gray = as_gray_u8(image)
        if gray is None or min(gray.shape) < k:
            return []
        _check_order_size(self.config.order, k)
        return [p.finish() for p in _Search(gray, self.config).peaks(k)]


RAY_RADII = (0.35, 0.85)
"""The two circles of :func:`ray_consistency`, as fractions of the kernel's half size ``(k - 1) / 2``:
inside the quality template's ring and near its edge."""
RAY_SAMPLES = 72
"""Samples per circle (5 deg apart: a 4-fold marker's wedges are 45 deg)."""


def ray_consistency(gray: U8Array, x: float, y: float, k: int) -> float:
    """The fraction (0 to 1) of angles at which two circles of radii :data:`RAY_RADII` times
    ``(k - 1) / 2`` round the point ``(x, y)`` (px) of the grey image (bilinear, reflect-101 border) are
    on the same side of their own mid-grey: 1 where the image about the point is a function of the angle
    alone, as a marker's is about its tip (module docstring, "Edges through the tip"); 0 when either
    circle is flat."""
    phi = np.arange(RAY_SAMPLES) * (2.0 * math.pi / RAY_SAMPLES)
    h = 0.5 * (k - 1)
    radii = np.array(RAY_RADII)[:, None] * h
    # cv2.remap is OpenCV's bilinear sampler: one call for both circles
    map_x = (x + radii * np.cos(phi)).astype(np.float32)
    map_y = (y + radii * np.sin(phi)).astype(np.float32)
    rings = cv2.remap(
        gray.astype(np.float32), map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101
    )
    lo, hi = rings.min(axis=1), rings.max(axis=1)
    if not bool((hi - lo > 1e-6).all()):
        return 0.0
    bright = rings > 0.5 * (lo + hi)[:, None]
    return float((bright[0] == bright[1]).mean())


def _with_tried(r: NFoldResult, tried: tuple[int, ...]) -> NFoldResult:
    return NFoldResult(r.x, r.y, r.x_int, r.y_int, r.theta, r.quality, r.magnitude, r.k, r.n, tried)


@dataclass(eq=False)
class _Peak:
    """A full-resolution integer peak with its response window, finished (quality...) on demand."""

    gray: U8Array
    re: FloatArray
    im: FloatArray
    iy: int
    ix: int
    x0: int
    y0: int
    parts: _KernelParts
    oriented: bool
    magnitude: float

    def finish(self) -> NFoldResult:
        return _finish(
            self.gray, self.re, self.im, self.iy, self.ix, self.x0, self.y0, self.parts, self.oriented
        )


class _Search:
    """One image's search state: the float32 image and the coarse candidates, shared between the kernel
    sizes of one adaptive search (consecutive sizes often have the same coarse plan)."""

    def __init__(self, gray: U8Array, cfg: NFoldConfig) -> None:
        self.gray = gray
        self.cfg = cfg
        self.f32 = gray.astype(np.float32)
        self._small: dict[int, F32Array] = {}
        self._seeds: dict[tuple[int, int], list[tuple[int, int]]] = {}

    def peaks(self, k: int) -> list[_Peak]:
        """Refined full-resolution peaks at kernel size ``k``, distinct, largest magnitude first."""
        cfg = self.cfg
        parts = _kernel_parts(cfg.order, k)
        H, W = self.gray.shape
        s, kc = coarse_plan(k, cfg.coarse_min_k)
        if cfg.coarse and min(H // s, W // s) >= kc + 2:
            seeds = self._coarse_seeds(s, kc)
            radius = s + 1
        else:
            mag = _separable_magnitude(self.f32, parts, exact=True)
            seeds = _top_peaks(mag, cfg.n_candidates, max(2, k // 4), cfg.min_magnitude)
            radius = 1
        out: list[_Peak] = []
        seen: set[tuple[int, int]] = set()
        for sx, sy in seeds:
            p = _refine(self.gray, self.f32, parts, sx, sy, radius, cfg.oriented, cfg.min_magnitude)
            if p is not None and (p.ix + p.x0, p.iy + p.y0) not in seen:
                seen.add((p.ix + p.x0, p.iy + p.y0))
                out.append(p)
        out.sort(key=lambda p: -p.magnitude)
        return out

    def _coarse_seeds(self, s: int, kc: int) -> list[tuple[int, int]]:
        key = (s, kc)
        seeds = self._seeds.get(key)
        if seeds is None:
            small = self._small.get(s)
            if small is None:
                H, W = self.gray.shape
                hs, ws = H // s, W // s
                g = self.gray[: hs * s, : ws * s]
                small = cv2.resize(g, (ws, hs), interpolation=cv2.INTER_AREA).astype(np.float32)
                self._small[s] = small
            mag = _separable_magnitude(small, _kernel_parts(self.cfg.order, kc), exact=False)
            # local maxima at least a quarter of the coarse kernel apart (distinct marker-like spots)
            peaks = _top_peaks(mag, self.cfg.n_candidates, max(2, kc // 4), self.cfg.min_magnitude)
            # coarse pixel centre -> full-resolution pixel (sheet 2: x_full = (x + 0.5) s - 0.5)
            seeds = [(int(round((px + 0.5) * s - 0.5)), int(round((py + 0.5) * s - 0.5))) for px, py in peaks]
            self._seeds[key] = seeds
        return seeds


def _separable_magnitude(img: F32Array, parts: _KernelParts, exact: bool) -> F32Array:
    """``|R|`` over the whole image, one ``sepFilter2D`` per rank-1 term (reflect-101). ``exact=False``
    leaves out the DC-removal term of an even order (a ~1e-3 leak, harmless for finding candidates, and
    one filter pass fewer)."""
    re = np.zeros(img.shape, np.float32)
    im = np.zeros(img.shape, np.float32)
    fx, fy, part = (parts.fx, parts.fy, parts.part) if exact else (parts.cfx, parts.cfy, parts.cpart)
    for t in range(fx.shape[0]):
        r = cv2.sepFilter2D(img, cv2.CV_32F, fx[t], fy[t])
        if part[t] == 0:
            re += r
        else:
            im += r
    mag: NDArray[Any] = cv2.magnitude(re, im)  # float32; MatLike in OpenCV's stubs
    return mag


def _top_peaks(mag: F32Array, count: int, nms_radius: int, floor: float) -> list[tuple[int, int]]:
    """Up to ``count`` local maxima ``(x, y)`` of ``mag`` (over a (2 r + 1)^2 window) above ``floor``,
    strongest first."""
    size = 2 * nms_radius + 1
    D = cv2.dilate(mag, cv2.getStructuringElement(cv2.MORPH_RECT, (size, size)))
    idx = np.flatnonzero((mag >= D) & (mag > floor))
    if idx.size == 0:
        return []
    vals = mag.ravel()[idx]
    if idx.size > count:
        keep = np.argpartition(-vals, count - 1)[:count]
        idx, vals = idx[keep], vals[keep]
    idx = idx[np.argsort(-vals, kind="stable")]
    W = mag.shape[1]
    return [(int(i % W), int(i // W)) for i in idx]


def _refine(
    gray: U8Array,
    f32: F32Array,
    parts: _KernelParts,
    sx: int,
    sy: int,
    radius: int,
    oriented: bool,
    floor: float,
) -> _Peak | None:
    """Full-resolution response over the window of half-size ``radius + 1`` round the seed, moved (up to
    4 times) until its maximum is strictly inside the window or on the image border."""
    H, W = gray.shape
    cx, cy = min(max(sx, 0), W - 1), min(max(sy, 0), H - 1)
    for _ in range(4):
        x0, x1 = max(0, cx - radius - 1), min(W, cx + radius + 2)
        y0, y1 = max(0, cy - radius - 1), min(H, cy + radius + 2)
        re, im = _window_response(f32, x0, y0, x1 - x0, y1 - y0, parts.fx, parts.fy, parts.part)
        M = re * re + im * im
        flat = int(np.argmax(M))
        iy, ix = divmod(flat, M.shape[1])
        X, Y = ix + x0, iy + y0
        on_edge_x = (ix == 0 and X > 0) or (ix == M.shape[1] - 1 and X < W - 1)
        on_edge_y = (iy == 0 and Y > 0) or (iy == M.shape[0] - 1 and Y < H - 1)
        if not (on_edge_x or on_edge_y):
            mag = math.sqrt(float(M[iy, ix]))
            if mag <= floor:
                return None
            return _Peak(gray, re, im, iy, ix, x0, y0, parts, oriented, mag)
        cx, cy = X, Y
    return None


__all__ = [
    "NFoldConfig",
    "NFoldDetector",
    "NFoldResult",
    "coarse_plan",
    "nfold_detect_filter2d",
    "nfold_kernel",
    "nfold_response_filter2d",
    "ray_consistency",
]
