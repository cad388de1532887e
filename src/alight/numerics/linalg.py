"""Small dense linear algebra for numba kernels: one Cholesky factorisation and its solves.

Hand-written loops: the filters' matrices are at most 15 x 15, where a BLAS or LAPACK call from a kernel
costs more than the arithmetic. The ego EKF, the platform EKF and the compiled step of the Kim UKF all
factor with :func:`cholesky`, so a matrix that one filter finds not positive definite is refused by the
others for the same reason.
"""

from __future__ import annotations

import math

from numba import njit

from alight.numerics import FloatArray


@njit(cache=True)
def cholesky(A: FloatArray, L: FloatArray) -> bool:  # pragma: no cover - numba
    """Lower Cholesky factor ``L`` (n, n) of the symmetric ``A`` (n, n), ``A = L L^T``; only ``A``'s lower
    triangle is read and ``L``'s upper triangle is zeroed. Returns False (``L`` then undefined) when ``A``
    is not numerically positive definite or a pivot is not finite (an infinite or NaN entry makes one so)."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            L[i, j] = 0.0
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not (s > 0.0 and s < math.inf):  # a NaN fails both
            return False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    return True


@njit(cache=True)
def cho_solve(L: FloatArray, B: FloatArray, X: FloatArray) -> None:  # pragma: no cover - numba
    """Solve ``L L^T X = B`` for ``X`` (m, k) given the lower factor ``L`` (m, m) of :func:`cholesky` and
    ``B`` (m, k): forward ``L y = b``, then backward ``L^T x = y``, column by column. ``X`` may be ``B``."""
    m = L.shape[0]
    k = B.shape[1]
    for c in range(k):
        for i in range(m):
            s = B[i, c]
            for q in range(i):
                s -= L[i, q] * X[q, c]
            X[i, c] = s / L[i, i]
        for i in range(m - 1, -1, -1):
            s = X[i, c]
            for q in range(i + 1, m):
                s -= L[q, i] * X[q, c]
            X[i, c] = s / L[i, i]


@njit(cache=True)
def chol_solve(
    S: FloatArray, B: FloatArray, L: FloatArray, X: FloatArray
) -> bool:  # pragma: no cover - numba
    """Solve ``S X = B`` for a symmetric positive-definite ``S`` (m, m) and ``B`` (m, k) by Cholesky.

    ``L`` (m, m) receives the factor. Returns False (and leaves ``X`` undefined) when ``S`` is not
    positive definite or not finite, so callers can report it instead of producing NaNs.
    """
    if not cholesky(S, L):
        return False
    cho_solve(L, B, X)
    return True


__all__ = ["cho_solve", "chol_solve", "cholesky"]
