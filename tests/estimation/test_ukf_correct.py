"""The one UKF measurement update, ukf_correct (the generic filter's and the Kim UKF's compiled step's):
the Kalman update on linear models up to rounding, for every scheme, both covariance forms and 1-3
measurement dimensions; the 2-D case bit for bit the closed form the compiled step always used."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.estimation.sigma_points import CubatureSigmaPoints, MerweScaledSigmaPoints, SimplexSigmaPoints
from alight.estimation.ukf import (
    CORRECT_GATED,
    CORRECT_NOT_PD,
    CORRECT_OK,
    GATED,
    NOT_POSITIVE_DEFINITE,
    ukf_correct,
    ukf_update,
)

SCHEMES = [
    MerweScaledSigmaPoints(),
    MerweScaledSigmaPoints(alpha=0.3),
    CubatureSigmaPoints(),
    SimplexSigmaPoints(),
]


def random_spd(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.1 * np.eye(n)


def kalman(x, P, H, R, z):  # type: ignore[no-untyped-def]
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    r = z - H @ x
    return x + K @ r, P - K @ S @ K.T, float(r @ np.linalg.solve(S, r))


@pytest.mark.parametrize("scheme", SCHEMES, ids=["merwe", "merwe_a03", "cubature", "simplex"])
@pytest.mark.parametrize("k", [1, 2, 3])
@pytest.mark.parametrize("form", ["standard", "joseph"])
def test_on_a_linear_model_it_is_the_kalman_update(scheme, k: int, form: str) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(10 * k + len(form))
    n = 5
    for _ in range(10):
        x, P = rng.normal(size=n), random_spd(rng, n)
        H, R, z = rng.normal(size=(k, n)), random_spd(rng, k), rng.normal(size=k)
        xo, Po, res = ukf_update(x, P, z, R, scheme, lambda X, H=H: X @ H.T, covariance_update=form)
        xk, Pk, nis = kalman(x, P, H, R, z)
        assert res.accepted
        scale = 1e-12 * (1.0 + np.abs(P).max()) * (1.0 + np.abs(np.asarray(scheme.weights(n)[1])).sum())
        np.testing.assert_allclose(xo, xk, rtol=0, atol=scale * (1 + np.abs(xk).max()))
        np.testing.assert_allclose(Po, Pk, rtol=0, atol=scale * (1 + np.abs(Pk).max()))
        assert res.nis == pytest.approx(nis, rel=1e-10)
        assert np.array_equal(Po, Po.T)


def _old_compiled_update(X, Z, Wm, Wc, xm, Pm, z, R00, R01, R11):  # type: ignore[no-untyped-def]
    # kim_pixel_step's update before it called ukf_correct (the standard form), transcribed
    m, n = X.shape
    zh0 = zh1 = 0.0
    for i in range(m):
        zh0 += Wm[i] * Z[i, 0]
        zh1 += Wm[i] * Z[i, 1]
    S00 = S01 = S11 = 0.0
    Pxz = np.zeros((n, 2))
    for i in range(m):
        a0, a1, w = Z[i, 0] - zh0, Z[i, 1] - zh1, Wc[i]
        S00 += w * a0 * a0
        S01 += w * a0 * a1
        S11 += w * a1 * a1
        for j in range(n):
            dx = w * (X[i, j] - xm[j])
            Pxz[j, 0] += dx * a0
            Pxz[j, 1] += dx * a1
    S00, S01, S11 = S00 + R00, S01 + R01, S11 + R11
    det = S00 * S11 - S01 * S01
    i00, i01, i11 = S11 / det, -S01 / det, S00 / det
    r0, r1 = z[0] - zh0, z[1] - zh1
    nis = r0 * (i00 * r0 + i01 * r1) + r1 * (i01 * r0 + i11 * r1)
    K = np.empty((n, 2))
    xo = np.empty(n)
    for j in range(n):
        K[j, 0] = Pxz[j, 0] * i00 + Pxz[j, 1] * i01
        K[j, 1] = Pxz[j, 0] * i01 + Pxz[j, 1] * i11
        xo[j] = xm[j] + K[j, 0] * r0 + K[j, 1] * r1
    Pn = np.empty((n, n))
    for j in range(n):
        ks0 = K[j, 0] * S00 + K[j, 1] * S01
        ks1 = K[j, 0] * S01 + K[j, 1] * S11
        for c in range(n):
            Pn[j, c] = Pm[j, c] - (ks0 * K[c, 0] + ks1 * K[c, 1])
    return xo, 0.5 * (Pn + Pn.T), nis


def test_the_2d_update_is_the_compiled_steps_closed_form_bit_for_bit() -> None:
    rng = np.random.default_rng(7)
    n, scheme = 7, MerweScaledSigmaPoints(alpha=0.7)
    Wm, Wc = (np.array(w) for w in scheme.weights(n))
    for _ in range(20):
        x, P = rng.normal(size=n), random_spd(rng, n)
        X = np.array(scheme.points(x, P))
        Z = np.sin(X[:, :2]) + X[:, 2:4] ** 2  # any non-linear model
        R00, R01, R11 = 0.5, 0.1, 0.7
        z = rng.normal(size=2)
        xo, Po, info = np.empty(n), np.empty((n, n)), np.zeros(1)
        R = np.array([[R00, R01], [R01, R11]])
        code = ukf_correct(X, Z, Wm, Wc, x, P, np.eye(n), z, R, math.inf, False, xo, Po, info)
        assert code == CORRECT_OK
        xe, Pe, nis = _old_compiled_update(X, Z, Wm, Wc, x, P, z, R00, R01, R11)
        assert np.array_equal(xo, xe) and np.array_equal(Po, Pe) and info[0] == nis


def test_a_measurement_beyond_the_gate_or_an_indefinite_s_changes_nothing() -> None:
    n = 3
    x, P, H = np.zeros(n), np.eye(n), np.eye(2, n)
    far = np.array([100.0, 0.0])
    xo, Po, res = ukf_update(x, P, far, np.eye(2), CubatureSigmaPoints(), lambda X: X @ H.T, gate=9.0)
    assert res.status == GATED and res.nis == pytest.approx(100.0**2 / 2.0) and xo is x and Po is P
    # a negative noise covariance that makes S indefinite
    xo, Po, res = ukf_update(x, P, far, -3.0 * np.eye(2), CubatureSigmaPoints(), lambda X: X @ H.T)
    assert res.status == NOT_POSITIVE_DEFINITE and xo is x and Po is P
    X = np.array(CubatureSigmaPoints().points(x, P))
    Wm, Wc = (np.array(w) for w in CubatureSigmaPoints().weights(n))
    out = (np.empty(n), np.empty((n, n)), np.zeros(1))
    Z = X @ H.T
    assert ukf_correct(X, Z, Wm, Wc, x, P, np.eye(n), far, np.eye(2), 9.0, False, *out) == CORRECT_GATED
    assert ukf_correct(X, Z, Wm, Wc, x, P, np.eye(n), far, -3 * np.eye(2), 9.0, False, *out) == CORRECT_NOT_PD
