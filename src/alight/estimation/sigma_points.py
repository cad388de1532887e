"""Sigma-point schemes for the unscented Kalman filter (:mod:`alight.estimation.ukf`).

A scheme turns a mean ``x`` (n,) and covariance ``P`` (n, n) into ``m`` points ``X`` (m, n) and two weight
vectors ``Wm``, ``Wc`` (m,) such that ``sum Wm_i X_i = x`` and ``sum Wc_i (X_i - x)(X_i - x)^T = P``
exactly. The filter never looks inside: it takes any object with :meth:`SigmaPointScheme.points` and
:meth:`SigmaPointScheme.weights` (filterpy's habit: the strategy is injected, not hard-wired).

- :class:`MerweScaledSigmaPoints`: Julier's scaled unscented transform in van der Merwe's parametrisation
  (alpha, beta, kappa), 2n + 1 points ``x``, ``x +- sqrt((n + lambda) P)_i``,
  ``lambda = alpha^2 (n + kappa) - n``, ``Wm_0 = lambda / (n + lambda)``,
  ``Wc_0 = Wm_0 + 1 - alpha^2 + beta``, ``W_i = 1 / (2 (n + lambda))``. ``beta = 2`` is optimal for a
  Gaussian prior (it adds the fourth-order term of the covariance).
- :class:`CubatureSigmaPoints`: the third-degree spherical-radial cubature rule (Arasaratnam & Haykin
  2009), 2n points ``x +- sqrt(n P)_i`` with equal weights ``1 / (2n)``; no centre point and no negative
  weight, so the predicted covariance is always positive semi-definite.
- :class:`SimplexSigmaPoints`: Julier's spherical simplex (Julier 2003, "The spherical simplex unscented
  transformation"), n + 2 points: the fewest that match the first two moments with a centre point.

``sqrt(P)`` is the lower Cholesky factor (columns ``L[:, i]``); a covariance that is not numerically
positive definite falls back to the symmetric square root with negative eigenvalues clipped to 0.
"""

from __future__ import annotations

import math
from typing import Protocol, cast, runtime_checkable

import numpy as np

from alight.types import FloatArray


@runtime_checkable
class SigmaPointScheme(Protocol):
    """Where to put sigma points and how to weigh them."""

    def num_points(self, n: int) -> int:
        """Number of sigma points for a state of dimension ``n``."""
        ...

    def weights(self, n: int) -> tuple[FloatArray, FloatArray]:
        """Mean weights ``Wm`` (m,) and covariance weights ``Wc`` (m,) for dimension ``n``."""
        ...

    def points(self, x: FloatArray, P: FloatArray) -> FloatArray:
        """Sigma points (m, n) of mean ``x`` (n,) and covariance ``P`` (n, n)."""
        ...

    def unit_points(self, n: int) -> FloatArray:
        """The points of zero mean and identity covariance, (m, n): ``points(x, P)`` is
        ``x + unit_points(n) @ sqrt(P)^T`` (compiled filters take these and the weights as arrays)."""
        ...


def matrix_sqrt(P: FloatArray) -> FloatArray:
    """A factor ``L`` with ``L L^T = P`` (n, n): lower Cholesky, or the symmetric square root with negative
    eigenvalues clipped when ``P`` is not numerically positive definite (then ``L L^T`` is the nearest
    positive semi-definite matrix)."""
    # LAPACK's Cholesky (numpy) on this Python path; numerics.linalg.cholesky is the kernels' own (a call
    # from Python would add a kernel signature to every first run's compile). Both refuse the same
    # matrices up to round-off, and a refusal here falls back to the clipped symmetric root.
    try:
        # float64 for a float64 P; numpy's stubs type cholesky's result floating[Any]
        return cast(FloatArray, np.linalg.cholesky(P))
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (P + P.T))
        L: FloatArray = V * np.sqrt(np.clip(w, 0.0, None))  # typed Any (np.sqrt's stub drops the dtype)
        return L


class _CachedWeights:
    """Weights depend only on ``n``: computed once per dimension."""

    def __init__(self) -> None:
        self._cache: dict[int, tuple[FloatArray, FloatArray]] = {}

    def weights(self, n: int) -> tuple[FloatArray, FloatArray]:
        w = self._cache.get(n)
        if w is None:
            if int(n) != n or n < 1:
                raise ValueError(f"state dimension must be a positive integer, got {n}")
            Wm, Wc = self._compute_weights(int(n))
            Wm.setflags(write=False)
            Wc.setflags(write=False)
            w = (Wm, Wc)
            self._cache[n] = w
        return w

    def _compute_weights(self, n: int) -> tuple[FloatArray, FloatArray]:  # pragma: no cover - abstract
        raise NotImplementedError


class MerweScaledSigmaPoints(_CachedWeights):
    """Scaled unscented transform, 2n + 1 points (see the module docstring).

    Parameters
    ----------
    alpha:
        Spread of the points around the mean, in (0, 1]; small values keep the points close (and make
        ``Wm_0`` strongly negative).
    beta:
        Prior knowledge of the distribution (2: Gaussian).
    kappa:
        Secondary scaling; ``n + kappa > 0`` is required (0 is the usual choice, ``3 - n`` Julier's
        heuristic for n <= 3).
    """

    def __init__(self, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0) -> None:
        super().__init__()
        if not (math.isfinite(alpha) and 0.0 < alpha <= 1.0):
            raise ValueError(f"alpha must be in (0, 1], got {alpha}")
        if not (math.isfinite(beta) and math.isfinite(kappa)):
            raise ValueError(f"beta and kappa must be finite, got {beta}, {kappa}")
        self.alpha = float(alpha)
        self.beta = float(beta)
        self.kappa = float(kappa)

    def num_points(self, n: int) -> int:
        return 2 * n + 1

    def _lambda(self, n: int) -> float:
        if not n + self.kappa > 0:
            raise ValueError(f"n + kappa must be > 0, got n={n}, kappa={self.kappa}")
        return self.alpha**2 * (n + self.kappa) - n

    def _compute_weights(self, n: int) -> tuple[FloatArray, FloatArray]:
        lam = self._lambda(n)
        Wm = np.full(2 * n + 1, 0.5 / (n + lam))
        Wc = Wm.copy()
        Wm[0] = lam / (n + lam)
        Wc[0] = Wm[0] + 1.0 - self.alpha**2 + self.beta
        return Wm, Wc

    def unit_points(self, n: int) -> FloatArray:
        c = math.sqrt(n + self._lambda(n))
        return np.concatenate([np.zeros((1, n)), c * np.eye(n), -c * np.eye(n)])

    def points(self, x: FloatArray, P: FloatArray) -> FloatArray:
        n = x.shape[0]
        L = matrix_sqrt(P) * math.sqrt(n + self._lambda(n))
        X = np.empty((2 * n + 1, n))
        X[0] = x
        X[1 : n + 1] = x + L.T
        X[n + 1 :] = x - L.T
        return X


class CubatureSigmaPoints(_CachedWeights):
    """Third-degree spherical-radial cubature rule: 2n points, equal positive weights."""

    def num_points(self, n: int) -> int:
        return 2 * n

    def _compute_weights(self, n: int) -> tuple[FloatArray, FloatArray]:
        W = np.full(2 * n, 0.5 / n)
        return W, W.copy()

    def unit_points(self, n: int) -> FloatArray:
        c = math.sqrt(n)
        return np.concatenate([c * np.eye(n), -c * np.eye(n)])

    def points(self, x: FloatArray, P: FloatArray) -> FloatArray:
        n = x.shape[0]
        L = matrix_sqrt(P) * math.sqrt(n)
        X = np.empty((2 * n, n))
        X[:n] = x + L.T
        X[n:] = x - L.T
        return X


class SimplexSigmaPoints(_CachedWeights):
    """Julier's spherical simplex, n + 2 points.

    ``w0`` (in [0, 1)) is the weight of the centre point; the others share ``1 - w0`` equally. The unit
    points are built dimension by dimension (Julier 2003, eq. 14-16): for j = 1,
    ``(0), (-1/sqrt(2 W1)), (1/sqrt(2 W1))``; each further dimension j appends 0 to the centre,
    ``-1/sqrt(j (j + 1) W1)`` to points 1..j and adds point j + 1 = ``(0, ..., 0, j/sqrt(j (j + 1) W1))``.
    """

    def __init__(self, w0: float = 0.0) -> None:
        super().__init__()
        if not (math.isfinite(w0) and 0.0 <= w0 < 1.0):
            raise ValueError(f"w0 must be in [0, 1), got {w0}")
        self.w0 = float(w0)
        self._unit: dict[int, FloatArray] = {}

    def num_points(self, n: int) -> int:
        return n + 2

    def _compute_weights(self, n: int) -> tuple[FloatArray, FloatArray]:
        W = np.full(n + 2, (1.0 - self.w0) / (n + 1))
        W[0] = self.w0
        return W, W.copy()

    def unit_points(self, n: int) -> FloatArray:
        """The points for zero mean and identity covariance, (n + 2, n)."""
        U = self._unit.get(n)
        if U is None:
            W1 = (1.0 - self.w0) / (n + 1)
            U = np.zeros((n + 2, n))
            U[1, 0] = -1.0 / math.sqrt(2.0 * W1)
            U[2, 0] = 1.0 / math.sqrt(2.0 * W1)
            for j in range(2, n + 1):
                s = 1.0 / math.sqrt(j * (j + 1) * W1)
                U[1 : j + 1, j - 1] = -s
                U[j + 1, j - 1] = j * s
            U.setflags(write=False)
            self._unit[n] = U
        return U

    def points(self, x: FloatArray, P: FloatArray) -> FloatArray:
        n = x.shape[0]
        return x + self.unit_points(n) @ matrix_sqrt(P).T


SCHEMES = {
    "merwe": MerweScaledSigmaPoints,
    "cubature": CubatureSigmaPoints,
    "simplex": SimplexSigmaPoints,
}
"""Sigma-point schemes by name; each constructor takes its own keyword parameters."""

__all__ = [
    "SCHEMES",
    "CubatureSigmaPoints",
    "MerweScaledSigmaPoints",
    "SigmaPointScheme",
    "SimplexSigmaPoints",
    "matrix_sqrt",
]
