"""A generic unscented Kalman filter (Julier & Uhlmann 1997; Wan & van der Merwe 2000) with an injected
sigma-point scheme (:mod:`alight.estimation.sigma_points`).

Functional core, thin class (filterpy's layout): :func:`unscented_transform`, :func:`ukf_predict` and
:func:`ukf_update` are plain functions of ``(x, P)``; :class:`UnscentedKalmanFilter` holds ``x, P`` and
the models. The process model ``fx(X, *args) -> Y`` and the measurement model ``hx(X, *args) -> Z`` take
*all* sigma points at once, ``X`` (m, n) -> (m, n) or (m, k), so a model is written with whole-array
numpy (or one numba call) instead of a Python loop over points.

Predict: ``X = sigma(x, P)``, ``Y = fx(X)``, ``x- = sum Wm Y``, ``P- = sum Wc (Y - x-)(Y - x-)^T + Q``.
Update: sigma points are drawn again from ``(x-, P-)`` (so the process noise reaches the measurement
prediction), ``Z = hx(X)``, ``z^ = sum Wm Z``, ``S = sum Wc (Z - z^)(Z - z^)^T + R``,
``P_xz = sum Wc (X - x-)(Z - z^)^T``, ``K = P_xz S^-1``, ``x+ = x- + K (z - z^)`` and

- ``standard``: ``P+ = P- - K S K^T``, then symmetrised ``(P + P^T) / 2``;
- ``joseph``: ``P+ = (I - K H) P- (I - K H)^T + K R K^T`` with the statistical linearisation
  ``H = P_xz^T P-^-1``: positive semi-definite by construction whatever the round-off. On a linear model
  it equals the standard form; on a non-linear one it drops the part of ``S`` that ``H`` does not explain
  (``S - H P- H^T - R``), so it is slightly more confident. Hence ``standard`` is the default.

The normalised innovation squared ``NIS = r^T S^-1 r`` (``r = z - z^``) comes back from every update; a
chi-square gate (``gate``, the NIS threshold) rejects a measurement and leaves the state unchanged, as does
a non-finite measurement, a non-finite predicted measurement (a sigma point with no image) or an ``S``
that is not positive definite. On a linear model the filter is the Kalman filter exactly (a test checks
1e-9 for every scheme).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from alight.errors import EstimationError
from alight.estimation.sigma_points import SigmaPointScheme
from alight.numerics.linalg import cho_solve, cholesky
from alight.types import FloatArray

COVARIANCE_UPDATES = ("standard", "joseph")
"""Values of the ``covariance_update`` option."""

OK = "ok"
GATED = "gated"
INVALID = "invalid"
NOT_POSITIVE_DEFINITE = "not_positive_definite"


@dataclass(frozen=True, slots=True)
class UpdateResult:
    """What :meth:`UnscentedKalmanFilter.update` did; truthy when the measurement was used."""

    accepted: bool
    """True when the state was updated."""
    nis: float
    """Normalised innovation squared ``r^T S^-1 r`` (NaN when it could not be formed)."""
    status: str
    """``ok``, ``gated`` (NIS above the gate), ``invalid`` (non-finite measurement or prediction) or
    ``not_positive_definite`` (S)."""

    def __bool__(self) -> bool:
        return self.accepted


def unscented_transform(
    Y: FloatArray,
    Wm: FloatArray,
    Wc: FloatArray,
    noise: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mean (k,), covariance (k, k) (plus ``noise``) and deviations ``Y - mean`` (m, k) of transformed
    sigma points ``Y`` (m, k) with weights ``Wm``, ``Wc`` (m,)."""
    mean = Wm @ Y
    D = Y - mean
    cov = (D.T * Wc) @ D
    if noise is not None:
        cov += noise
    return mean, 0.5 * (cov + cov.T), D


def ukf_predict(
    x: FloatArray,
    P: FloatArray,
    scheme: SigmaPointScheme,
    fx: Callable[..., FloatArray],
    Q: FloatArray,
    *args: Any,
) -> tuple[FloatArray, FloatArray]:
    """Prior mean (n,) and covariance (n, n): ``fx(X, *args)`` on the sigma points of ``x, P``, plus ``Q``."""
    n = x.shape[0]
    X = scheme.points(x, P)
    Y = fx(X, *args)
    Wm, Wc = scheme.weights(n)
    xm, Pm, _ = unscented_transform(Y, Wm, Wc, Q)
    return xm, Pm


# --------------------------------------------------------------------------------------------------
# The measurement update, compiled: the generic filter's and the Kim UKF's compiled step's
# --------------------------------------------------------------------------------------------------

CORRECT_OK, CORRECT_GATED, CORRECT_NOT_PD = 0, 1, 3
"""Return codes of :func:`ukf_correct`."""


@njit(cache=True)
def _inverse_spd(S: FloatArray, Si: FloatArray) -> bool:  # pragma: no cover - numba
    """``Si = S^-1`` for the symmetric ``S`` (k, k); False when ``S`` is not positive definite. ``k <= 2``
    in closed form (every update alight makes: a pixel or a horizontal position), larger by Cholesky."""
    k = S.shape[0]
    if k == 1:
        if not S[0, 0] > 0.0:
            return False
        Si[0, 0] = 1.0 / S[0, 0]
        return True
    if k == 2:
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[0, 1]
        if not (S[0, 0] > 0.0 and det > 0.0):
            return False
        Si[0, 0] = S[1, 1] / det
        Si[0, 1] = -S[0, 1] / det
        Si[1, 0] = Si[0, 1]
        Si[1, 1] = S[0, 0] / det
        return True
    Ls = np.empty((k, k))
    if not cholesky(S, Ls):
        return False
    cho_solve(Ls, np.eye(k), Si)
    return True


@njit(cache=True)
def _row_times(A: FloatArray, j: int, B: FloatArray, out: FloatArray) -> None:  # pragma: no cover - numba
    """``out = A[j] @ B`` (row j of A times B), each sum started from its first term."""
    k = A.shape[1]
    for a in range(B.shape[1]):
        s = A[j, 0] * B[0, a]
        for b in range(1, k):
            s += A[j, b] * B[b, a]
        out[a] = s


@njit(cache=True)
def _dot_row(v: FloatArray, A: FloatArray, c: int) -> float:  # pragma: no cover - numba
    """``v . A[c]``, the sum started from its first term."""
    s = v[0] * A[c, 0]
    for a in range(1, v.shape[0]):
        s += v[a] * A[c, a]
    return float(s)


@njit(cache=True)
def _innovation_moments(
    X: FloatArray,
    Z: FloatArray,
    Wm: FloatArray,
    Wc: FloatArray,
    x: FloatArray,
    R: FloatArray,
    zh: FloatArray,
    S: FloatArray,
    Pxz: FloatArray,
) -> None:  # pragma: no cover - numba
    """The predicted measurement ``zh`` (k,), its covariance plus the noise, ``S`` (k, k), and the
    cross-covariance ``Pxz`` (n, k) of the sigma points, accumulated into the given zeros."""
    m, n = X.shape
    k = Z.shape[1]
    for i in range(m):
        for a in range(k):
            zh[a] += Wm[i] * Z[i, a]
    d = np.empty(k)
    for i in range(m):
        for a in range(k):
            d[a] = Z[i, a] - zh[a]
        w = Wc[i]
        for a in range(k):
            for b in range(a, k):
                S[a, b] += w * d[a] * d[b]
        for j in range(n):
            dx = w * (X[i, j] - x[j])
            for a in range(k):
                Pxz[j, a] += dx * d[a]
    for a in range(k):
        for b in range(a, k):
            S[a, b] += R[a, b]
            S[b, a] = S[a, b]


@njit(cache=True)
def _posterior_covariance(
    P: FloatArray,
    L: FloatArray,
    K: FloatArray,
    S: FloatArray,
    R: FloatArray,
    Pxz: FloatArray,
    joseph: bool,
    Po: FloatArray,
) -> None:  # pragma: no cover - numba
    """``Po`` (n, n): ``P - K S K^T`` or, ``joseph``, ``(I - K H) P (I - K H)^T + K R K^T`` with
    ``H^T = P^-1 Pxz`` (``L`` the factor of ``P``); symmetrised."""
    n, k = K.shape
    kr = np.empty(k)
    if joseph:
        Ht = np.empty((n, k))  # H^T = P^-1 Pxz, the statistical linearisation
        cho_solve(L, Pxz, Ht)
        A = np.eye(n)
        for j in range(n):
            for c in range(n):
                A[j, c] -= _dot_row(K[j], Ht, c)
        AP = A @ P
        Pn = AP @ A.T
        for j in range(n):
            _row_times(K, j, R, kr)
            for c in range(n):
                Pn[j, c] += _dot_row(kr, K, c)
    else:
        Pn = np.empty((n, n))
        for j in range(n):
            _row_times(K, j, S, kr)
            for c in range(n):
                Pn[j, c] = P[j, c] - _dot_row(kr, K, c)
    for j in range(n):
        for c in range(n):
            Po[j, c] = 0.5 * (Pn[j, c] + Pn[c, j])


@njit(cache=True)
def ukf_correct(
    X: FloatArray,
    Z: FloatArray,
    Wm: FloatArray,
    Wc: FloatArray,
    x: FloatArray,
    P: FloatArray,
    L: FloatArray,
    z: FloatArray,
    R: FloatArray,
    gate: float,
    joseph: bool,
    xo: FloatArray,
    Po: FloatArray,
    info: FloatArray,
) -> int:  # pragma: no cover - numba
    """The UKF measurement update (module docstring) from the sigma points ``X`` (m, n) of the prior
    ``(x, P)``, their predicted measurements ``Z`` (m, k), the weights ``Wm``, ``Wc`` (m,), the measurement
    ``z`` (k,) and its symmetric noise ``R`` (k, k). ``L`` is the lower Cholesky factor of ``P``, read by
    the Joseph form only. The posterior goes to ``xo`` (n,), ``Po`` (n, n) and the NIS to ``info[0]``.
    Returns ``CORRECT_OK``, ``CORRECT_GATED`` (NIS above ``gate``) or ``CORRECT_NOT_PD`` (``S``)."""
    n = X.shape[1]
    k = Z.shape[1]
    zh = np.zeros(k)
    S = np.zeros((k, k))
    Pxz = np.zeros((n, k))
    _innovation_moments(X, Z, Wm, Wc, x, R, zh, S, Pxz)
    Si = np.empty((k, k))
    if not _inverse_spd(S, Si):
        return CORRECT_NOT_PD
    r = np.empty(k)
    for a in range(k):
        r[a] = z[a] - zh[a]
    nis = r[0] * _dot_row(r, Si, 0)
    for a in range(1, k):
        nis += r[a] * _dot_row(r, Si, a)
    info[0] = nis
    if not nis <= gate:
        return CORRECT_GATED
    K = np.empty((n, k))  # K = Pxz S^-1
    for j in range(n):
        _row_times(Pxz, j, Si, K[j])
        s = x[j]
        for a in range(k):
            s += K[j, a] * r[a]
        xo[j] = s
    _posterior_covariance(P, L, K, S, R, Pxz, joseph, Po)
    return CORRECT_OK


def ukf_update(
    x: FloatArray,
    P: FloatArray,
    z: FloatArray,
    R: FloatArray,
    scheme: SigmaPointScheme,
    hx: Callable[..., FloatArray],
    *args: Any,
    gate: float = math.inf,
    covariance_update: str = "standard",
) -> tuple[FloatArray, FloatArray, UpdateResult]:
    """Posterior ``(x, P, result)`` for the measurement ``z`` (k,) with noise covariance ``R`` (k, k) and
    the model ``hx(X, *args) -> Z`` (m, k). When ``result`` is not accepted, ``x, P`` are the inputs.
    The update itself is :func:`ukf_correct`, the kernel the compiled filters call."""
    n = x.shape[0]
    if not (np.isfinite(z).all() and np.isfinite(R).all()):
        return x, P, UpdateResult(False, math.nan, INVALID)
    X = scheme.points(x, P)
    Z = hx(X, *args)
    if not np.isfinite(Z).all():
        return x, P, UpdateResult(False, math.nan, INVALID)
    Wm, Wc = scheme.weights(n)
    joseph = covariance_update == "joseph"
    L = np.zeros((n, n))
    if joseph and not cholesky(_c(P), L):  # the statistical linearisation solves with P
        return x, P, UpdateResult(False, math.nan, NOT_POSITIVE_DEFINITE)
    xo, Po, info = np.empty(n), np.empty((n, n)), np.full(1, math.nan)
    code = ukf_correct(
        _c(X), _c(Z), _c(Wm), _c(Wc), _c(x), _c(P), L, _c(z), _c(R), float(gate), joseph, xo, Po, info
    )
    nis = float(info[0])
    if code == CORRECT_OK:
        return xo, Po, UpdateResult(True, nis, OK)
    return x, P, UpdateResult(False, nis, GATED if code == CORRECT_GATED else NOT_POSITIVE_DEFINITE)


def _c(a: FloatArray) -> FloatArray:
    # one array type for the kernel (C order, writable float64), so that it compiles once
    return np.require(a, np.float64, ["C", "W"])


class UnscentedKalmanFilter:
    """State ``x`` (n,), covariance ``P`` (n, n), an injected sigma-point scheme and vectorised models.

    Parameters
    ----------
    scheme:
        A :class:`~alight.estimation.sigma_points.SigmaPointScheme`.
    fx:
        Process model ``fx(X (m, n), *args) -> (m, n)`` (``args`` from :meth:`predict`).
    hx:
        Default measurement model ``hx(X (m, n), *args) -> (m, k)``; :meth:`update` can pass another.
    covariance_update:
        ``standard`` or ``joseph`` (module docstring).
    """

    def __init__(
        self,
        scheme: SigmaPointScheme,
        fx: Callable[..., FloatArray],
        hx: Callable[..., FloatArray] | None = None,
        *,
        covariance_update: str = "standard",
    ) -> None:
        if covariance_update not in COVARIANCE_UPDATES:
            raise ValueError(
                f"covariance_update must be one of {COVARIANCE_UPDATES}, got {covariance_update!r}"
            )
        self.scheme = scheme
        self.fx = fx
        self.hx = hx
        self.covariance_update = covariance_update
        self.x: FloatArray = np.zeros(0)
        """State (n,)."""
        self.P: FloatArray = np.zeros((0, 0))
        """Covariance (n, n)."""
        self.last_nis = math.nan
        """NIS of the last update attempt."""

    def set_state(self, x: FloatArray, P: FloatArray) -> None:
        """Set the state ``x`` (n,) and covariance ``P`` (n, n) (copied, P symmetrised)."""
        xa = np.array(x, dtype=np.float64)
        Pa = np.array(P, dtype=np.float64)
        n = xa.shape[0] if xa.ndim == 1 else -1
        if xa.ndim != 1 or Pa.shape != (n, n) or not (np.isfinite(xa).all() and np.isfinite(Pa).all()):
            raise EstimationError(f"set_state needs a finite x (n,) and P (n, n), got {xa.shape}, {Pa.shape}")
        self.x = xa
        self.P = 0.5 * (Pa + Pa.T)

    def predict(self, Q: FloatArray, *args: Any) -> None:
        """Propagate through ``fx(X, *args)`` and add the process noise ``Q`` (n, n)."""
        self.x, self.P = ukf_predict(self.x, self.P, self.scheme, self.fx, Q, *args)

    def update(
        self,
        z: FloatArray,
        R: FloatArray,
        *args: Any,
        hx: Callable[..., FloatArray] | None = None,
        gate: float = math.inf,
    ) -> UpdateResult:
        """Fuse ``z`` (k,) with noise ``R`` (k, k) through ``hx(X, *args)`` (the default model when None).
        Returns an :class:`UpdateResult` (truthy when used; the state is unchanged otherwise)."""
        h = hx if hx is not None else self.hx
        if h is None:
            raise EstimationError("UnscentedKalmanFilter.update: no measurement model")
        z = np.asarray(z, dtype=np.float64).ravel()
        R = np.asarray(R, dtype=np.float64)
        if R.shape != (z.shape[0], z.shape[0]):
            raise EstimationError(f"R must be ({z.shape[0]}, {z.shape[0]}), got {R.shape}")
        x, P, res = ukf_update(
            self.x, self.P, z, R, self.scheme, h, *args, gate=gate, covariance_update=self.covariance_update
        )
        self.last_nis = res.nis
        if res.accepted:
            self.x, self.P = x, P
        return res


__all__ = [
    "COVARIANCE_UPDATES",
    "CORRECT_GATED",
    "CORRECT_NOT_PD",
    "CORRECT_OK",
    "UnscentedKalmanFilter",
    "UpdateResult",
    "ukf_correct",
    "ukf_predict",
    "ukf_update",
    "unscented_transform",
]
