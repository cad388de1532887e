"""The shared polynomial routines against closed forms: known roots (simple, multiple, complex pairs,
at very different scales), the interval limits, the cancellation-free quadratic and Fujiwara's bound."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.numerics.poly import (
    bracketed_root,
    horner,
    horner_d,
    positive_real_roots,
    quadratic_roots,
    real_roots_in,
    root_bound,
)


def ascending(roots: list[complex] | list[float], scale: float = 1.0) -> np.ndarray:
    """Coefficients (ascending) of scale * prod (x - r)."""
    return np.real(np.poly(roots))[::-1] * scale


def test_horner_value_and_derivative_match_the_closed_form() -> None:
    c = ascending([1.0, -2.0, 3.0])  # (x - 1)(x + 2)(x - 3) = x^3 - 2 x^2 - 5 x + 6
    np.testing.assert_array_equal(c, [6.0, -5.0, -2.0, 1.0])
    for x in (-1.5, 0.0, 0.25, 4.0):
        y, dy = horner_d(c, 3, x)
        assert y == pytest.approx(x**3 - 2 * x**2 - 5 * x + 6, abs=1e-12)
        assert dy == pytest.approx(3 * x**2 - 4 * x - 5, abs=1e-12)
        assert horner(c, 3, x) == y
    assert horner(c, 1, 2.0) == 6.0 - 5.0 * 2.0  # only the first deg + 1 coefficients count


@pytest.mark.parametrize(
    ("roots", "expected"),
    [
        ([2.0, 5.0, 9.0], [2.0, 5.0, 9.0]),  # simple
        ([2.0, 2.0, 9.0], [2.0, 9.0]),  # a double root, counted once
        ([3.0, 3.0, 3.0], [3.0]),  # a triple root
        ([-1.0, 4.0], [4.0]),  # negative roots are left out
        ([complex(1, 2), complex(1, -2), 7.0], [7.0]),  # a complex pair is never produced
        ([complex(1, 2), complex(1, -2)], []),
        ([1e-3, 1.0, 1e3], [1e-3, 1.0, 1e3]),  # six orders of magnitude
    ],
)
def test_positive_real_roots_of_known_polynomials(roots: list[complex], expected: list[float]) -> None:
    # scales that keep the coefficients exact: a rounded coefficient moves a multiple root apart (by
    # ~sqrt(eps) for a double one) and the rounded polynomial then really has two roots there
    for scale in (1.0, -0.25, 2.0**20):
        got = real_roots_in(ascending(roots, scale))
        np.testing.assert_allclose(got, expected, rtol=1e-7)


@pytest.mark.parametrize("seed", range(40))
def test_positive_real_roots_match_numpy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    deg = int(rng.integers(1, 7))
    # roots of every kind: positive, negative, complex pairs, at very different scales
    roots: list[complex] = []
    while len(roots) < deg:
        kind = rng.integers(0, 3)
        if kind == 2 and len(roots) <= deg - 2:
            z = complex(rng.normal() * 300, abs(rng.normal()) * 300 + 1)
            roots += [z, z.conjugate()]
        else:
            roots.append(float(rng.choice([-1, 1]) * 10 ** rng.uniform(-1, 3)))
    c = np.real(np.poly(roots))[::-1] * 10 ** rng.uniform(-9, 2)  # ascending, random scale
    out = np.empty(deg + 1)
    n = positive_real_roots(c, math.inf, out)
    ref = np.roots(c[::-1])
    ref = np.sort(ref[(np.abs(ref.imag) < 1e-7 * np.abs(ref)) & (ref.real > 0)].real)
    assert n == ref.size
    assert np.allclose(out[:n], ref, rtol=1e-9)
    expected = np.sort([r.real for r in roots if isinstance(r, float) and r > 0])
    assert np.allclose(out[:n], expected, rtol=1e-8)


def test_roots_are_limited_to_the_interval() -> None:
    c = ascending([2.0, 5.0, 9.0])
    out = np.empty(4)
    assert positive_real_roots(c, 6.0, out) == 2 and np.allclose(out[:2], [2.0, 5.0])
    assert positive_real_roots(c, 5.0, out) == 2  # a root on the bound counts
    assert positive_real_roots(c, 0.0, out) == 0
    assert positive_real_roots(np.array([1.0, 0.0, 1.0]), math.inf, out) == 0  # x^2 + 1
    assert positive_real_roots(np.array([-3.0, 0.0, 0.0]), math.inf, out) == 0  # a constant
    assert positive_real_roots(np.array([0.0, 1.0]), math.inf, out) == 0  # x: the root 0 is outside
    with pytest.raises(ValueError):
        real_roots_in([1.0, math.nan])


@pytest.mark.parametrize(
    ("a", "b", "c", "expected"),
    [
        (1.0, -3.0, 2.0, (2, 1.0, 2.0)),
        (2.0, 0.0, -8.0, (2, -2.0, 2.0)),
        (1.0, -2.0, 1.0, (2, 1.0, 1.0)),  # double root
        (1.0, 0.0, 0.0, (2, 0.0, 0.0)),  # double root at 0
        (1.0, 0.0, 1.0, (0, math.nan, math.nan)),  # complex pair
        (0.0, 2.0, -3.0, (1, 1.5, math.nan)),  # linear
        (0.0, 0.0, 1.0, (0, math.nan, math.nan)),
    ],
)
def test_quadratic_roots_closed_form(
    a: float, b: float, c: float, expected: tuple[int, float, float]
) -> None:
    n, r1, r2 = quadratic_roots(a, b, c)
    assert n == expected[0]
    np.testing.assert_allclose([r1, r2], expected[1:], rtol=1e-15)


def test_quadratic_roots_do_not_cancel() -> None:
    # x^2 - 1e8 x + 1: roots 1e8 and 1e-8; the textbook formula loses the small one entirely
    n, r1, r2 = quadratic_roots(1.0, -1e8, 1.0)
    assert n == 2
    assert r1 == pytest.approx(1e-8, rel=1e-15) and r2 == pytest.approx(1e8, rel=1e-15)


def test_bracketed_root_and_fujiwara_bound() -> None:
    c = ascending([1.0, 2.0, 3.0])
    x = bracketed_root(c, 3, 1.5, 2.5, horner(c, 3, 1.5))
    assert x == pytest.approx(2.0, abs=1e-15)
    # Fujiwara's bound holds every root, complex ones included
    rng = np.random.default_rng(3)
    for _ in range(200):
        deg = int(rng.integers(1, 7))
        c = rng.normal(size=deg + 1) * 10.0 ** rng.uniform(-3, 3, deg + 1)
        assert np.max(np.abs(np.roots(c[::-1]))) <= root_bound(c, deg) * (1 + 1e-12)
