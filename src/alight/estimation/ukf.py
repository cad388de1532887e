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

from alight.errors import EstimationError
from alight.estimation.sigma_points import SigmaPointScheme
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
    the model ``hx(X, *args) -> Z`` (m, k). When ``result`` is not accepted, ``x, P`` are the inputs."""
    n = x.shape[0]
    if not (np.isfinite(z).all() and np.isfinite(R).all()):
        return x, P, UpdateResult(False, math.nan, INVALID)
    X = scheme.points(x, P)
    Z = hx(X, *args)
    if not np.isfinite(Z).all():
        return x, P, UpdateResult(False, math.nan, INVALID)
    Wm, Wc = scheme.weights(n)
    zhat, S, dZ = unscented_transform(Z, Wm, Wc, R)
    dX = X - x
    Pxz = (dX.T * Wc) @ dZ
    r = z - zhat
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return x, P, UpdateResult(False, math.nan, NOT_POSITIVE_DEFINITE)
    w = np.linalg.solve(L, r)
    nis = float(w @ w)
    if not nis <= gate:
        return x, P, UpdateResult(False, nis, GATED)
    # K = Pxz S^-1 = ((L L^T)^-1 Pxz^T)^T
    K = np.linalg.solve(L.T, np.linalg.solve(L, Pxz.T)).T
    x_new = x + K @ r
    if covariance_update == "joseph":
        H = np.linalg.solve(P, Pxz).T  # statistical linearisation, P symmetric
        A = np.eye(n) - K @ H
        P_new = A @ P @ A.T + K @ R @ K.T
    else:
        P_new = P - K @ S @ K.T
    return x_new, 0.5 * (P_new + P_new.T), UpdateResult(True, nis, OK)


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
    "UnscentedKalmanFilter",
    "UpdateResult",
    "ukf_predict",
    "ukf_update",
    "unscented_transform",
]
