"""The generic UKF and its sigma-point schemes: exact moments, the Kalman filter on linear models, NIS,
rejections, and the two covariance updates."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import EstimationError
from alight.estimation.sigma_points import (
    SCHEMES,
    CubatureSigmaPoints,
    MerweScaledSigmaPoints,
    SigmaPointScheme,
    SimplexSigmaPoints,
    matrix_sqrt,
)
from alight.estimation.ukf import UnscentedKalmanFilter, ukf_update

ALL_SCHEMES = [
    MerweScaledSigmaPoints(),
    MerweScaledSigmaPoints(alpha=0.1, beta=2.0, kappa=1.0),
    MerweScaledSigmaPoints(alpha=1e-3),
    CubatureSigmaPoints(),
    SimplexSigmaPoints(),
    SimplexSigmaPoints(w0=0.3),
]
IDS = ["merwe", "merwe_small", "merwe_tiny", "cubature", "simplex", "simplex_w0"]


def random_spd(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.1 * np.eye(n)


@pytest.mark.parametrize("scheme", ALL_SCHEMES, ids=IDS)
@pytest.mark.parametrize("n", [1, 2, 4, 7])
def test_sigma_points_reproduce_mean_and_covariance(scheme: SigmaPointScheme, n: int) -> None:
    rng = np.random.default_rng(n)
    x = rng.normal(size=n)
    P = random_spd(rng, n)
    X = scheme.points(x, P)
    Wm, Wc = scheme.weights(n)
    assert isinstance(scheme, SigmaPointScheme)
    assert X.shape == (scheme.num_points(n), n) == (Wm.shape[0], n)
    # tiny alpha gives weights of +-1e6 whose sum cancels: round-off scales with sum |W|
    tol = 1e-13 * np.abs(Wc).sum()
    assert Wm.sum() == pytest.approx(1.0, abs=tol)
    assert np.allclose(Wm @ X, x, atol=tol * 10)
    D = X - x
    assert np.allclose((D.T * Wc) @ D, P, atol=tol * 100)


@pytest.mark.parametrize("scheme", ALL_SCHEMES, ids=IDS)
def test_unscented_mean_of_a_quadratic_is_exact(scheme: SigmaPointScheme) -> None:
    """E[x^T A x] = tr(A P) + m^T A m depends on the first two moments only, which every scheme matches."""
    rng = np.random.default_rng(5)
    n = 5
    m, P, A = rng.normal(size=n), random_spd(rng, n), random_spd(rng, n)
    X = scheme.points(m, P)
    Wm, _ = scheme.weights(n)
    y = np.einsum("ki,ij,kj->k", X, A, X)
    assert Wm @ y == pytest.approx(np.trace(A @ P) + m @ A @ m, rel=1e-10)


def test_merwe_weights_match_the_formulas() -> None:
    s = MerweScaledSigmaPoints(alpha=0.5, beta=2.0, kappa=1.0)
    n = 3
    lam = 0.25 * (n + 1.0) - n
    Wm, Wc = s.weights(n)
    assert Wm[0] == pytest.approx(lam / (n + lam))
    assert Wc[0] == pytest.approx(lam / (n + lam) + 1 - 0.25 + 2.0)
    assert np.allclose(Wm[1:], 0.5 / (n + lam)) and np.allclose(Wc[1:], Wm[1:])


def test_simplex_has_n_plus_2_points_on_a_sphere() -> None:
    s = SimplexSigmaPoints(w0=0.2)
    U = s.unit_points(4)
    assert U.shape == (6, 4)
    r = np.linalg.norm(U[1:], axis=1)
    assert np.allclose(r, r[0])  # all non-centre points at one radius (the "spherical" simplex)


def test_scheme_parameters_are_validated() -> None:
    for bad in (lambda: MerweScaledSigmaPoints(alpha=0.0), lambda: MerweScaledSigmaPoints(alpha=1.5)):
        with pytest.raises(ValueError):
            bad()
    with pytest.raises(ValueError):
        SimplexSigmaPoints(w0=1.0)
    with pytest.raises(ValueError):
        MerweScaledSigmaPoints(kappa=-3.0).weights(2)
    assert set(SCHEMES) == {"merwe", "cubature", "simplex"}


def test_matrix_sqrt_of_a_singular_covariance() -> None:
    v = np.array([1.0, 2.0, -1.0])
    P = np.outer(v, v)  # rank 1: Cholesky fails
    L = matrix_sqrt(P)
    assert np.allclose(L @ L.T, P, atol=1e-12)


# --------------------------------------------------------------------------------------------------
# Linear models: the UKF is the Kalman filter
# --------------------------------------------------------------------------------------------------

DT = 0.1
F = np.block([[np.eye(2), DT * np.eye(2)], [np.zeros((2, 2)), np.eye(2)]])
HM = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.5, -0.3, 0.2, 0.0]])


def fx_linear(X: np.ndarray, u: np.ndarray) -> np.ndarray:
    return X @ F.T + u


def hx_linear(X: np.ndarray) -> np.ndarray:
    return X @ HM.T


# alpha = 1e-3 is left out: its weights of -1e6 / +2.5e5 cost ~1e-7 of round-off, not a model error
WELL_CONDITIONED = [(s, i) for s, i in zip(ALL_SCHEMES, IDS, strict=True) if i != "merwe_tiny"]


@pytest.mark.parametrize("update", ["standard", "joseph"])
@pytest.mark.parametrize("scheme", [s for s, _ in WELL_CONDITIONED], ids=[i for _, i in WELL_CONDITIONED])
def test_ukf_equals_the_kalman_filter_on_a_linear_model(scheme: SigmaPointScheme, update: str) -> None:
    rng = np.random.default_rng(1)
    Q = random_spd(rng, 4) * 0.01
    R = random_spd(rng, 3) * 0.1
    x0, P0 = rng.normal(size=4), random_spd(rng, 4)
    ukf = UnscentedKalmanFilter(scheme, fx_linear, hx_linear, covariance_update=update)
    ukf.set_state(x0, P0)
    x, P = x0.copy(), P0.copy()
    for _ in range(20):
        u = rng.normal(size=4) * 0.1
        z = rng.normal(size=3)
        ukf.predict(Q, u)
        x = F @ x + u
        P = F @ P @ F.T + Q
        res = ukf.update(z, R)
        S = HM @ P @ HM.T + R
        K = P @ HM.T @ np.linalg.inv(S)
        r = z - HM @ x
        x = x + K @ r
        A = np.eye(4) - K @ HM
        P = A @ P @ A.T + K @ R @ K.T
        assert res and res.accepted and res.status == "ok"
        assert res.nis == pytest.approx(r @ np.linalg.solve(S, r), rel=1e-9)
        assert np.allclose(ukf.x, x, rtol=0, atol=1e-9)
        assert np.allclose(ukf.P, P, rtol=0, atol=1e-9)
        assert np.array_equal(ukf.P, ukf.P.T)


def test_non_finite_measurement_is_rejected_and_state_unchanged() -> None:
    ukf = UnscentedKalmanFilter(MerweScaledSigmaPoints(), fx_linear, hx_linear)
    ukf.set_state(np.ones(4), np.eye(4))
    for z, R in ((np.array([1.0, math.nan, 0.0]), np.eye(3)), (np.zeros(3), np.full((3, 3), math.inf))):
        res = ukf.update(z, R)
        assert not res and res.status == "invalid" and math.isnan(res.nis)
        assert np.array_equal(ukf.x, np.ones(4)) and np.array_equal(ukf.P, np.eye(4))


def test_measurement_model_without_image_is_rejected() -> None:
    def hx_nan(X: np.ndarray) -> np.ndarray:
        Z = X[:, :2].copy()
        Z[-1, 0] = math.nan  # one sigma point has no image
        return Z

    x, P, res = ukf_update(np.zeros(4), np.eye(4), np.zeros(2), np.eye(2), CubatureSigmaPoints(), hx_nan)
    assert not res and res.status == "invalid"
    assert np.array_equal(x, np.zeros(4)) and np.array_equal(P, np.eye(4))


def test_gate_rejects_by_nis_and_keeps_the_state() -> None:
    ukf = UnscentedKalmanFilter(MerweScaledSigmaPoints(), fx_linear, hx_linear)
    ukf.set_state(np.zeros(4), np.eye(4))
    R = np.eye(3)
    S = HM @ HM.T + R
    z = np.array([3.0, -2.0, 1.0])
    nis = z @ np.linalg.solve(S, z)
    res = ukf.update(z, R, gate=nis - 1e-6)
    assert not res and res.status == "gated" and res.nis == pytest.approx(nis)
    assert np.array_equal(ukf.x, np.zeros(4)) and np.array_equal(ukf.P, np.eye(4))
    assert ukf.update(z, R, gate=nis + 1e-6)


def test_not_positive_definite_innovation_is_refused() -> None:
    x, P, res = ukf_update(
        np.zeros(2), np.zeros((2, 2)), np.zeros(2), np.zeros((2, 2)), CubatureSigmaPoints(), lambda X: X
    )
    assert not res and res.status == "not_positive_definite"


def test_joseph_is_never_less_confident_than_standard_on_a_nonlinear_model() -> None:
    """P_standard - P_joseph = K (S - H P H^T - R) K^T >= 0 with the statistical linearisation H: the
    Joseph form drops the linearisation error that S carries (ukf.py's docstring)."""
    rng = np.random.default_rng(3)

    def hx(X: np.ndarray) -> np.ndarray:
        return np.stack([np.hypot(X[:, 0], X[:, 1]), np.arctan2(X[:, 1], X[:, 0])], axis=1)

    x0, P0 = np.array([2.0, 1.0, 0.0, 0.0]), random_spd(rng, 4)
    z = hx(x0[None])[0] + 0.05
    R = np.diag([0.01, 0.001])
    s = MerweScaledSigmaPoints()
    _, Ps, _ = ukf_update(x0, P0, z, R, s, hx, covariance_update="standard")
    _, Pj, _ = ukf_update(x0, P0, z, R, s, hx, covariance_update="joseph")
    assert np.linalg.eigvalsh(Ps - Pj).min() > -1e-12
    assert np.abs(Ps - Pj).max() > 1e-6  # and they do differ
    assert np.linalg.eigvalsh(Pj).min() > 0


def test_filter_input_validation() -> None:
    with pytest.raises(ValueError):
        UnscentedKalmanFilter(CubatureSigmaPoints(), fx_linear, covariance_update="sqrt")
    ukf = UnscentedKalmanFilter(CubatureSigmaPoints(), fx_linear)
    with pytest.raises(EstimationError):
        ukf.set_state(np.zeros(3), np.eye(4))
    ukf.set_state(np.zeros(4), np.eye(4))
    with pytest.raises(EstimationError):
        ukf.update(np.zeros(3), np.eye(3))  # no measurement model
    with pytest.raises(EstimationError):
        ukf.update(np.zeros(3), np.eye(2), hx=hx_linear)
