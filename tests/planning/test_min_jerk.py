"""The minimum-jerk primitive: boundary conditions, optimality conditions, derivatives, cost."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from alight.planning.min_jerk import (
    EndConstraint,
    MinJerkTrajectory,
    evaluate_candidates,
    floor_feasibility,
    input_feasibility,
    min_jerk_coefficients,
    min_jerk_cost,
)


def _random_problem(rng: np.random.Generator, n: int):
    p0 = rng.normal(0.0, 3.0, 3)
    v0 = rng.normal(0.0, 2.0, 3)
    a0 = rng.normal(0.0, 2.0, 3)
    T = rng.uniform(0.3, 6.0, n)
    pf = rng.normal(0.0, 8.0, (n, 3))
    vf = rng.normal(0.0, 3.0, (n, 3))
    af = rng.normal(0.0, 3.0, (n, 3))
    return p0, v0, a0, T, pf, vf, af


def _trajectories(p0, v0, a0, T, alpha, beta, gamma, t0=0.0):
    return [MinJerkTrajectory(t0, T[i], p0, v0, a0, alpha[i], beta[i], gamma[i]) for i in range(T.size)]


@pytest.mark.parametrize("mode", list(EndConstraint))
def test_boundary_conditions(mode: EndConstraint) -> None:
    rng = np.random.default_rng(1)
    p0, v0, a0, T, pf, vf, af = _random_problem(rng, 200)
    al, be, ga = min_jerk_coefficients(p0, v0, a0, T, pf, vf, af, mode)
    for i, tr in enumerate(_trajectories(p0, v0, a0, T, al, be, ga, t0=3.0)):
        p, v, a, _ = tr.sample(3.0)
        np.testing.assert_allclose(np.r_[p, v, a], np.r_[p0, v0, a0], rtol=0, atol=1e-12)
        pe, ve, ae = tr.end_state()
        scale = 1.0 + np.abs(pf[i]).max()
        np.testing.assert_allclose(pe, pf[i], rtol=0, atol=1e-9 * scale)
        pt, vt, at, jt = tr.sample(3.0 + T[i])
        np.testing.assert_allclose(pt, pf[i], rtol=0, atol=1e-9 * scale)
        if mode != EndConstraint.POS:
            np.testing.assert_allclose(ve, vf[i], rtol=0, atol=1e-9 * scale)
            np.testing.assert_allclose(vt, vf[i], rtol=0, atol=1e-9 * scale)
        else:  # free final velocity: natural condition, snap(T) = beta + alpha T = 0
            np.testing.assert_allclose(be[i] + al[i] * T[i], 0.0, atol=1e-9 * np.abs(be[i]).max())
        if mode == EndConstraint.POS_VEL_ACC:
            np.testing.assert_allclose(ae, af[i], rtol=0, atol=1e-9 * scale)
            np.testing.assert_allclose(at, af[i], rtol=0, atol=1e-9 * scale)
        else:  # free final acceleration: natural condition, jerk(T) = 0
            np.testing.assert_allclose(jt, 0.0, atol=1e-9 * (1.0 + np.abs(ga[i]).max()))


def test_free_end_components_are_optimal() -> None:
    """Leaving a final component free gives the least cost over every value it could be fixed to, and
    fixing it to the free optimum's value reproduces the same primitive."""
    rng = np.random.default_rng(2)
    p0, v0, a0, T, pf, vf, af = _random_problem(rng, 300)
    J = {m: min_jerk_cost(*min_jerk_coefficients(p0, v0, a0, T, pf, vf, af, m), T) for m in EndConstraint}
    assert (J[EndConstraint.POS_VEL] <= J[EndConstraint.POS_VEL_ACC] * (1 + 1e-12)).all()
    al, be, ga = min_jerk_coefficients(p0, v0, a0, T, pf, vf, None, EndConstraint.POS_VEL)
    a_end = np.array([tr.end_state()[2] for tr in _trajectories(p0, v0, a0, T, al, be, ga)])
    al2, be2, ga2 = min_jerk_coefficients(p0, v0, a0, T, pf, vf, a_end, EndConstraint.POS_VEL_ACC)
    np.testing.assert_allclose(np.c_[al2, be2, ga2], np.c_[al, be, ga], rtol=1e-8, atol=1e-8)
    # free velocity and acceleration beat any fixed velocity
    alp, bep, gap = min_jerk_coefficients(p0, v0, a0, T, pf, mode=EndConstraint.POS)
    Jp = min_jerk_cost(alp, bep, gap, T)
    assert (Jp <= J[EndConstraint.POS_VEL] * (1 + 1e-12)).all()


def test_derivatives_match_finite_differences() -> None:
    rng = np.random.default_rng(3)
    p0, v0, a0, T, pf, vf, af = _random_problem(rng, 50)
    al, be, ga = min_jerk_coefficients(p0, v0, a0, T, pf, vf, af, EndConstraint.POS_VEL_ACC)
    h = 1e-5
    for tr in _trajectories(p0, v0, a0, T, al, be, ga, t0=-1.0):
        for t in tr.t0 + tr.T * np.array([0.13, 0.5, 0.91]):
            s_plus = tr.sample(t + h)
            s_minus = tr.sample(t - h)
            s = tr.sample(t)
            for k in range(3):  # d/dt of p, v, a is v, a, j
                fd = (s_plus[k] - s_minus[k]) / (2 * h)
                np.testing.assert_allclose(fd, s[k + 1], rtol=1e-6, atol=1e-6 * (1 + np.abs(s[k + 1]).max()))


def test_sample_outside_the_interval() -> None:
    rng = np.random.default_rng(4)
    p0, v0, a0, T, pf, vf, _ = _random_problem(rng, 1)
    tr = MinJerkTrajectory.from_boundary(2.0, T[0], p0, v0, a0, pf[0], vf[0])
    before = tr.sample(1.0)
    for x, y in zip(before, tr.sample(2.0), strict=True):
        np.testing.assert_array_equal(x, y)
    pe, ve, _ = tr.end_state()
    dt = 1.7
    p, v, a, j = tr.sample(tr.t_end + dt)
    np.testing.assert_allclose(p, pe + ve * dt, rtol=1e-13, atol=1e-12)
    np.testing.assert_array_equal(v, ve)
    np.testing.assert_array_equal(a, 0.0)
    np.testing.assert_array_equal(j, 0.0)
    ts = np.linspace(1.0, tr.t_end + 2.0, 37)
    many = tr.sample_many(ts)
    for m, t in enumerate(ts):
        for x, y in zip(many, tr.sample(t), strict=True):
            np.testing.assert_allclose(x[m], y, rtol=0, atol=1e-12)


def test_cost_is_mean_squared_jerk() -> None:
    rng = np.random.default_rng(5)
    p0, v0, a0, T, pf, vf, af = _random_problem(rng, 40)
    for mode in EndConstraint:
        al, be, ga = min_jerk_coefficients(p0, v0, a0, T, pf, vf, af, mode)
        J = min_jerk_cost(al, be, ga, T)
        for i, tr in enumerate(_trajectories(p0, v0, a0, T, al, be, ga)):
            integral, _ = quad(
                lambda t, tr=tr: float(np.sum(tr.sample(t)[3] ** 2)), 0.0, tr.T, epsabs=0, epsrel=1e-12
            )
            assert J[i] == pytest.approx(integral / tr.T, rel=1e-9)
            assert tr.cost == pytest.approx(J[i], rel=1e-14)


def test_fused_evaluation_matches_the_separate_functions() -> None:
    rng = np.random.default_rng(6)
    p0, v0, a0, T, pf, vf, _ = _random_problem(rng, 500)
    p0 = p0 + np.array([0.0, 0.0, 10.0])
    pf[:, 2] = rng.uniform(-1.0, 4.0, pf.shape[0])
    lim = dict(f_min=2.8, f_max=16.3, w_max=6.0, min_section_s=0.02)
    batch = evaluate_candidates(p0, v0, a0, T, pf, vf, plane_point=[0, 0, 0.5], **lim)
    al, be, ga = min_jerk_coefficients(p0, v0, a0, T, pf, vf, mode=EndConstraint.POS_VEL)
    np.testing.assert_array_equal(batch.alpha, al)
    np.testing.assert_array_equal(batch.cost, min_jerk_cost(al, be, ga, T))
    np.testing.assert_array_equal(batch.codes, input_feasibility(a0, al, be, ga, T, **lim))
    floor = floor_feasibility(p0, v0, a0, al, be, ga, T, point=[0, 0, 0.5], normal=[0, 0, 2.0])
    np.testing.assert_array_equal(batch.floor_ok, floor)
    assert 0 < batch.feasible.sum() < batch.feasible.size


def test_rejects_bad_input() -> None:
    z = np.zeros(3)
    with pytest.raises(ValueError):
        min_jerk_coefficients(z, z, z, np.array([0.0]), z)
    with pytest.raises(ValueError):
        min_jerk_coefficients(z, z, z, np.array([1.0]), z, mode=EndConstraint.POS_VEL)
    with pytest.raises(ValueError):
        min_jerk_coefficients(z, z, np.array([np.nan, 0, 0]), np.array([1.0]), z, z, z)
    with pytest.raises(ValueError):
        MinJerkTrajectory(0.0, -1.0, z, z, z, z, z, z)
    with pytest.raises(ValueError):
        input_feasibility(
            z, z[None], z[None], z[None], np.array([1.0]), f_min=5, f_max=2, w_max=1, min_section_s=0.1
        )
    with pytest.raises(ValueError):
        floor_feasibility(z, z, z, z[None], z[None], z[None], np.array([1.0]), point=z, normal=z)
