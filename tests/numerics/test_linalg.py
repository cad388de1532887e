"""alight.numerics.linalg: the Cholesky factor and solves against numpy on random SPD matrices, and the
refusal of matrices that are not positive definite."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.numerics.linalg import cho_solve, chol_solve, cholesky


def random_spd(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.1 * np.eye(n)


@pytest.mark.parametrize("n", [1, 2, 3, 7, 15])
def test_the_factor_is_numpys(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(20):
        S = random_spd(rng, n)
        L = np.full((n, n), np.nan)
        assert cholesky(S, L)
        np.testing.assert_allclose(L, np.linalg.cholesky(S), rtol=1e-12, atol=1e-13)
        assert (np.triu(L, 1) == 0.0).all()  # the upper triangle is zeroed
        np.testing.assert_allclose(L @ L.T, S, rtol=1e-13, atol=1e-13)


def test_only_the_lower_triangle_is_read() -> None:
    S = random_spd(np.random.default_rng(1), 5)
    junk = S + np.triu(np.full((5, 5), 1e3), 1)
    L1, L2 = np.empty((5, 5)), np.empty((5, 5))
    assert cholesky(S, L1) and cholesky(junk, L2)
    assert np.array_equal(L1, L2)


@pytest.mark.parametrize("n", [1, 4, 15])
def test_solves_are_numpys(n: int) -> None:
    rng = np.random.default_rng(10 + n)
    S = random_spd(rng, n)
    B = rng.normal(size=(n, 3))
    L, X = np.empty((n, n)), np.empty((n, 3))
    assert chol_solve(S, B, L, X)
    np.testing.assert_allclose(X, np.linalg.solve(S, B), rtol=1e-10, atol=1e-12)
    # the solve with a given factor, in place
    Y = B.copy()
    cho_solve(L, Y, Y)
    assert np.array_equal(X, Y)


@pytest.mark.parametrize(
    "S",
    [
        np.array([[1.0, 2.0], [2.0, 1.0]]),  # indefinite (eigenvalues 3 and -1)
        np.array([[1.0, 1.0], [1.0, 1.0]]),  # singular
        np.zeros((3, 3)),
        -np.eye(2),
        np.array([[1.0, math.nan], [math.nan, 1.0]]),
        np.array([[math.inf, 0.0], [0.0, 1.0]]),
    ],
    ids=["indefinite", "singular", "zero", "negative", "nan", "inf"],
)
def test_a_matrix_that_is_not_positive_definite_is_refused(S: np.ndarray) -> None:
    n = S.shape[0]
    assert not cholesky(S, np.empty((n, n)))
    assert not chol_solve(S, np.ones((n, 1)), np.empty((n, n)), np.empty((n, 1)))
