"""Real roots of polynomials, compiled with numba so that kernels can call them per candidate or per
sigma point without allocating.

One implementation serves the three callers that used to carry their own: the omnidirectional camera's
eq. 24 (paper 003, :mod:`alight.cameras.omni`), the Kim UKF's measurement model (the same equation per
sigma point, :mod:`alight.estimation.kim_ukf`) and the min-jerk planner's floor check (the stationary
points of a quintic, :mod:`alight.planning.min_jerk`).

Coefficients are in **ascending** powers, ``p(x) = c[0] + c[1] x + ... + c[n] x^n``.

Method (root isolation by the derivative cascade, no complex arithmetic): the roots of ``p^(k+1)`` split
the interval into pieces on which ``p^(k)`` is monotone, so each piece holds at most one root of
``p^(k)``, bracketed by a sign change. Starting from the linear derivative ``p^(n-1)``, each level's roots
become the next level's breaks, down to ``p`` itself. Each bracketed root is refined by Newton's method
kept inside the shrinking bracket (bisection when a step leaves it), so it always converges. A root
where ``p`` touches zero without changing sign (a double root) is kept when ``|p|`` there is at rounding
level, ``|p(b)| <= 1e-13 sum |c_k| |b|^k``. Only real roots inside the interval are ever produced.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from alight.numerics import FloatArray

_NEWTON_MAX = 200
"""Iterations of the bracketed Newton at the most (bisection alone needs < 1100 for any float bracket;
Newton converges quadratically, so 200 is never reached in practice)."""
_X_TOL = 4e-16
"""Stop when the step or the bracket is below this times ``max(1, |x|)``: two ulps of x, absolute near 0."""
_TOUCH_TOL = 1e-13
"""A break ``b`` where ``|p(b)| <= _TOUCH_TOL * sum |c_k| |b|^k`` is a root (where ``p`` touches zero)."""
_SAME_TOL = 1e-12
"""Two roots closer than this (relative, absolute below 1) are one (a double root found twice)."""


@njit(cache=True)
def horner(c: FloatArray, deg: int, x: float) -> float:  # pragma: no cover
    """``p(x)`` for the first ``deg + 1`` ascending coefficients ``c`` (Horner's scheme)."""
    y = 0.0
    for k in range(deg, -1, -1):
        y = y * x + c[k]
    return y


@njit(cache=True)
def horner_d(c: FloatArray, deg: int, x: float) -> tuple[float, float]:  # pragma: no cover
    """``(p(x), p'(x))`` for the first ``deg + 1`` ascending coefficients ``c`` (Horner, both at once)."""
    y = 0.0
    dy = 0.0
    for k in range(deg, -1, -1):
        dy = dy * x + y
        y = y * x + c[k]
    return y, dy


@njit(cache=True)
def quadratic_roots(a: float, b: float, c: float) -> tuple[int, float, float]:  # pragma: no cover
    """Real roots of ``a x^2 + b x + c``: ``(count, r1, r2)`` with ``r1 <= r2`` (NaN where absent).

    Cancellation-free form (Press et al., *Numerical Recipes* 3rd ed. eq. 5.6.4-5.6.5):
    ``q = -(b + sign(b) sqrt(b^2 - 4ac)) / 2``, ``x1 = q / a``, ``x2 = c / q``; the subtraction of two
    nearly equal numbers in the textbook formula never happens. ``a = 0`` gives the linear root; a double
    root is counted twice (``r1 == r2``); ``a = b = 0`` gives none."""
    if a != 0.0:
        disc = b * b - 4.0 * a * c
        if disc < 0.0:
            return 0, math.nan, math.nan
        sq = math.sqrt(disc)
        q = -0.5 * (b + sq) if b >= 0.0 else -0.5 * (b - sq)
        if q == 0.0:  # b = 0 and c = 0: the double root 0
            return 2, 0.0, 0.0
        r1 = q / a
        r2 = c / q
        if r1 > r2:
            r1, r2 = r2, r1
        return 2, r1, r2
    if b != 0.0:
        return 1, -c / b, math.nan
    return 0, math.nan, math.nan


@njit(cache=True)
def bracketed_root(c: FloatArray, deg: int, a: float, b: float, fa: float) -> float:  # pragma: no cover
    """The root in ``[a, b]`` of the polynomial ``c`` (degree ``deg``), monotone there with a sign change
    (``fa = p(a)``, ``p(b)`` of the other sign): Newton's method safeguarded by the bracket (bisection
    when a step leaves it), so it always converges, quadratically once close."""
    lo, hi = (a, b) if fa < 0.0 else (b, a)  # p(lo) < 0 < p(hi)
    x = 0.5 * (a + b)
    for _ in range(_NEWTON_MAX):
        f, df = horner_d(c, deg, x)
        if f == 0.0:
            return x
        if f < 0.0:
            lo = x
        else:
            hi = x
        xn = x - f / df if df != 0.0 else 0.5 * (lo + hi)
        if not ((xn - lo) * (xn - hi) < 0.0):
            xn = 0.5 * (lo + hi)
        tol = _X_TOL * max(1.0, abs(xn))
        if abs(xn - x) <= tol or abs(hi - lo) <= tol:
            return xn
        x = xn
    return x


@njit(cache=True)
def root_bound(c: FloatArray, deg: int) -> float:  # pragma: no cover
    """Fujiwara's bound: every complex root of ``c`` (degree ``deg``, ``c[deg] != 0``) has
    ``|x| <= 2 max_k |c_(n-k) / c_n|^(1/k)``, the ``k = n`` term halved (Fujiwara 1916)."""
    bound = 0.0
    for k in range(1, deg + 1):
        v = abs(c[deg - k] / c[deg])
        if k == deg:
            v *= 0.5
        v = v ** (1.0 / k)
        if v > bound:
            bound = v
    return 2.0 * bound


@njit(cache=True)
def positive_real_roots_into(
    coef: FloatArray, hi: float, out: FloatArray, D: FloatArray, crit: FloatArray
) -> int:  # pragma: no cover
    """Real roots in ``(0, hi]`` of ``sum coef[k] x^k``, ascending, into ``out``; returns their number.
    Work arrays given so a kernel calls it in a loop without allocating: for ``len(coef) = n + 1``,
    ``out`` and ``crit`` of length >= ``n``, ``D`` of shape >= ``(n, n + 1)``. Trailing zero coefficients
    are dropped; ``hi`` may be inf (Fujiwara's bound then limits the search). See the module docstring."""
    n = coef.shape[0] - 1
    while n > 0 and coef[n] == 0.0:
        n -= 1
    if n == 0 or not hi > 0.0:
        return 0
    top = min(hi, root_bound(coef, n))
    if not top > 0.0:
        return 0
    for j in range(n + 1):  # D[k]: the k-th derivative's coefficients, degree n - k
        D[0, j] = coef[j]
    for k in range(1, n):
        for j in range(n - k + 1):
            D[k, j] = D[k - 1, j + 1] * (j + 1)
    nc = 0
    for k in range(n - 1, -1, -1):
        deg = n - k
        m = 0
        a = 0.0
        fa = D[k, 0]
        for j in range(nc + 1):
            b = crit[j] if j < nc else top
            if not b > a:
                continue
            fb = horner(D[k], deg, b)
            x = math.nan
            if fa != 0.0 and fb != 0.0 and (fa < 0.0) != (fb < 0.0):
                x = bracketed_root(D[k], deg, a, b, fa)
            else:  # no sign change: a root only where p touches zero at the break b
                scale = 0.0
                for i in range(deg, -1, -1):
                    scale = scale * abs(b) + abs(D[k, i])
                if abs(fb) <= _TOUCH_TOL * scale:
                    x = b
            if not np.isnan(x) and (m == 0 or abs(x - out[m - 1]) > _SAME_TOL * max(1.0, abs(x))):
                out[m] = x
                m += 1
            a = b
            fa = fb
        for j in range(m):
            crit[j] = out[j]
        nc = m
    return nc


@njit(cache=True)
def positive_real_roots(coef: FloatArray, hi: float, out: FloatArray) -> int:  # pragma: no cover
    """:func:`positive_real_roots_into` allocating its own work arrays (``out`` of length >= degree)."""
    n = max(coef.shape[0] - 1, 1)
    return positive_real_roots_into(coef, hi, out, np.empty((n, n + 1)), np.empty(n))


def real_roots_in(coef: FloatArray, hi: float = math.inf) -> FloatArray:
    """The real roots in ``(0, hi]`` of the polynomial with ascending coefficients ``coef``, ascending
    (a checked Python entry to :func:`positive_real_roots`; raises ValueError on a non-finite one)."""
    c = np.ascontiguousarray(coef, dtype=np.float64).ravel()
    if c.size == 0 or not np.isfinite(c).all():
        raise ValueError(f"coef must hold finite coefficients, got {c}")
    out = np.empty(max(c.size - 1, 1))
    m = positive_real_roots(c, float(hi), out)
    return out[:m].copy()


__all__ = [
    "bracketed_root",
    "horner",
    "horner_d",
    "positive_real_roots",
    "positive_real_roots_into",
    "quadratic_roots",
    "real_roots_in",
    "root_bound",
]
