"""Quadrotor dynamics: hover, free fall, torque-free invariants, torque signs, motors, integration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME, Airframe
from alight.sim import quadrotor as Q
from alight.types import GRAVITY_MPS2, quat_to_rotmat

Z3 = np.zeros(3)


def _state(p=(0.0, 0.0, 0.0), yaw=0.0, thrust=0.0, v=(0.0, 0.0, 0.0), w=(0.0, 0.0, 0.0)):
    x = Q.initial_state(np.array(p), yaw, thrust)
    x[Q.SL_V] = v
    x[Q.SL_W] = w
    return x


def test_layout_constants_are_consistent():
    assert (Q.IX_P, Q.IX_V, Q.IX_Q, Q.IX_W, Q.IX_F, Q.NX) == (0, 3, 6, 10, 13, 17)
    par = Q.pack_params(DEFAULT_AIRFRAME)
    assert par.shape == (Q.NPAR,)
    assert par[Q.PAR_F_MAX] == pytest.approx(DEFAULT_AIRFRAME.motor_thrust_max_N)
    # the packed rotor geometry reproduces the airframe's allocation matrix
    f = np.array([1.0, 2.0, 3.0, 4.0])
    A = DEFAULT_AIRFRAME.allocation
    tau = (
        par[Q.PAR_ROTOR_Y : Q.PAR_ROTOR_Y + 4] @ f,
        -par[Q.PAR_ROTOR_X : Q.PAR_ROTOR_X + 4] @ f,
        -par[Q.PAR_C_TAU] * par[Q.PAR_SPIN : Q.PAR_SPIN + 4] @ f,
    )
    np.testing.assert_allclose(tau, (A @ f)[1:], atol=1e-15)


def test_hover_equilibrium_holds_still():
    par = Q.pack_params()
    f_hover = DEFAULT_AIRFRAME.weight_N / 4
    x0 = _state((1.0, -2.0, 5.0), yaw=0.7, thrust=f_hover)
    x = Q.step_many(x0, np.full(4, f_hover), Z3, Z3, par, 0.001, 1000)
    np.testing.assert_allclose(x[Q.SL_P], x0[Q.SL_P], atol=1e-9)
    np.testing.assert_allclose(x[Q.SL_V], 0.0, atol=1e-9)
    np.testing.assert_allclose(x[Q.SL_W], 0.0, atol=1e-9)
    np.testing.assert_allclose(x[Q.SL_Q], x0[Q.SL_Q], atol=1e-12)
    np.testing.assert_allclose(x[Q.SL_F], f_hover, atol=1e-12)


def test_free_fall_without_drag_is_parabolic():
    par = Q.pack_params(Airframe(rotor_drag=(0.0, 0.0, 0.0)))
    x0 = _state((0.0, 0.0, 10.0), yaw=0.3)
    x = Q.step_many(x0, np.zeros(4), Z3, Z3, par, 0.001, 1000)
    assert x[2] == pytest.approx(10.0 - 0.5 * GRAVITY_MPS2, abs=1e-9)
    assert x[5] == pytest.approx(-GRAVITY_MPS2, abs=1e-9)
    np.testing.assert_allclose(x[0:2], 0.0, atol=1e-12)
    np.testing.assert_allclose(x[Q.SL_W], 0.0, atol=1e-12)
    np.testing.assert_allclose(x[Q.SL_Q], x0[Q.SL_Q], atol=1e-12)


def test_stopped_rotors_have_no_rotor_drag():
    # the drag follows the rotors' speed (Faessler et al.'s sum over the rotors): a free fall with the
    # rotors stopped is parabolic whatever the airframe's rotor drag
    par = Q.pack_params()
    x = Q.step_many(_state((0.0, 0.0, 50.0), v=(3.0, 0.0, 0.0)), np.zeros(4), Z3, Z3, par, 0.001, 1000)
    assert x[5] == pytest.approx(-GRAVITY_MPS2, abs=1e-9)
    assert x[3] == pytest.approx(3.0, abs=1e-12)


def test_linear_rotor_drag_at_hover_thrust_matches_closed_form():
    # level body holding its weight, moving along x: m v' = -m d_x v  =>  v(t) = v0 exp(-d t)
    d = DEFAULT_AIRFRAME.rotor_drag[0]
    par = Q.pack_params()
    f_hover = DEFAULT_AIRFRAME.weight_N / 4
    x0 = _state((0.0, 0.0, 50.0), thrust=f_hover, v=(2.0, 0.0, 0.0))
    x = Q.step_many(x0, np.full(4, f_hover), Z3, Z3, par, 0.001, 2000)
    t = 2.0
    assert x[3] == pytest.approx(2.0 * math.exp(-d * t), abs=1e-10)
    assert x[0] == pytest.approx(2.0 * (1 - math.exp(-d * t)) / d, abs=1e-10)
    assert x[5] == pytest.approx(0.0, abs=1e-10)


def test_rotor_drag_follows_the_rotor_speed():
    # rotor speed goes as the root of the thrust: at 4x the hover thrust (every rotor) the drag doubles,
    # with one rotor stopped and three at hover it is 3/4 of the hover drag
    par = Q.pack_params()
    f_hover = DEFAULT_AIRFRAME.weight_N / 4
    d = DEFAULT_AIRFRAME.rotor_drag[0]
    for thrusts, scale in (((4.0,) * 4, 2.0), ((0.0, 1.0, 1.0, 1.0), 0.75), ((1.0,) * 4, 1.0)):
        f = f_hover * np.array(thrusts)
        x = _state(v=(1.0, 0.0, 0.0))
        x[Q.SL_F] = f
        a = Q.derivatives(x, f, Z3, Z3, par)[Q.SL_V]
        assert a[0] == pytest.approx(-scale * d, abs=1e-12), thrusts


def test_rotor_drag_acts_on_air_relative_velocity():
    par = Q.pack_params()
    f_hover = DEFAULT_AIRFRAME.weight_N / 4
    x = _state(thrust=f_hover, v=(1.0, 0.0, 0.0), yaw=0.4)
    u = np.full(4, f_hover)
    a = Q.derivatives(x, u, Z3, Z3, par)[Q.SL_V]
    # yawed level body: the drag along x_B and y_B is the same, so the force is -m d_xy v in W
    np.testing.assert_allclose(a, [-DEFAULT_AIRFRAME.rotor_drag[0], 0.0, 0.0], atol=1e-14)
    a_wind = Q.derivatives(x, u, Z3, np.array([1.0, 0.0, 0.0]), par)[Q.SL_V]
    np.testing.assert_allclose(a_wind, 0.0, atol=1e-14)
    f_ext = np.array([0.5, -0.2, 0.1])
    a_ext = Q.derivatives(x, u, f_ext, np.array([1.0, 0.0, 0.0]), par)[Q.SL_V]
    np.testing.assert_allclose(a_ext, f_ext / DEFAULT_AIRFRAME.mass, atol=1e-14)


def test_torque_free_rotation_conserves_momentum_and_energy():
    J = np.array([0.010, 0.015, 0.021])
    par = Q.pack_params(Airframe(inertia_diag=tuple(J), rotor_drag=(0.0, 0.0, 0.0)))
    x0 = _state(w=(1.5, -0.4, 2.5))

    def invariants(x):
        R = quat_to_rotmat(x[Q.SL_Q])
        w = x[Q.SL_W]
        return R @ (J * w), 0.5 * w @ (J * w)

    L0, E0 = invariants(x0)
    x = Q.step_many(x0, np.zeros(4), Z3, Z3, par, 0.001, 3000)
    L, E = invariants(x)
    assert not np.allclose(x[Q.SL_W], x0[Q.SL_W], atol=1e-2)  # the rates do change (J asymmetric)
    np.testing.assert_allclose(L, L0, atol=1e-9 * np.linalg.norm(L0))
    assert E == pytest.approx(E0, rel=1e-9)


@pytest.mark.parametrize(
    ("delta", "axis", "sign"),
    [
        ((1.0, -1.0, 1.0, -1.0), 2, -1.0),  # counter-clockwise rotors faster: body yaws clockwise
        ((1.0, 1.0, -1.0, -1.0), 0, +1.0),  # left rotors faster: roll right (+x rotation)
        ((1.0, -1.0, -1.0, 1.0), 1, -1.0),  # front rotors faster: nose up (-y rotation in FLU)
    ],
)
def test_differential_thrust_turns_the_right_way(delta, axis, sign):
    af = DEFAULT_AIRFRAME
    par = Q.pack_params()
    f = af.weight_N / 4 + 0.1 * np.array(delta)
    x0 = _state((0.0, 0.0, 5.0), thrust=0.0)
    x0[Q.SL_F] = f  # rotors already at their command, so the torque is constant
    t = 0.05
    x = Q.step_many(x0, f, Z3, Z3, par, 0.001, 50)
    tau = (af.allocation @ f)[1 + axis]
    assert np.sign(tau) == sign
    # single-axis rotation about a principal axis: w = tau / J t exactly (w x Jw = 0)
    assert x[Q.IX_W + axis] == pytest.approx(tau / af.inertia_diag[axis] * t, rel=1e-12)
    others = [i for i in range(3) if i != axis]
    np.testing.assert_allclose(x[Q.IX_W + np.array(others)], 0.0, atol=1e-12)


def test_motor_first_order_response_up_and_down():
    af = DEFAULT_AIRFRAME
    par = Q.pack_params()
    f_max = af.motor_thrust_max_N
    dt = 0.0005
    x = Q.step_many(_state(), np.full(4, 100.0), Z3, Z3, par, dt, round(af.motor_tau_up / dt))
    np.testing.assert_allclose(x[Q.SL_F], (1 - math.exp(-1)) * f_max, rtol=1e-12)  # saturated at f_max
    x = _state(thrust=f_max)
    x = Q.step_many(x, np.zeros(4), Z3, Z3, par, dt, round(af.motor_tau_down / dt))
    np.testing.assert_allclose(x[Q.SL_F], math.exp(-1) * f_max, rtol=1e-12)
    # the derivative agrees with the exact response
    xd = Q.derivatives(_state(thrust=1.0), np.full(4, 3.0), Z3, Z3, par)
    np.testing.assert_allclose(xd[Q.SL_F], 2.0 / af.motor_tau_up)


def _random_commands(rng, n_hold):
    f_hover = DEFAULT_AIRFRAME.weight_N / 4
    return f_hover * (1 + 0.6 * rng.uniform(-1, 1, (n_hold, 4)))


def test_quaternion_stays_unit_under_aggressive_commands():
    par = Q.pack_params()
    x = _state((0, 0, 10), thrust=2.0, w=(3.0, -2.0, 1.0))
    for u in _random_commands(np.random.default_rng(3), 400):
        x = Q.step_many(x, u, Z3, Z3, par, 0.001, 5)
        assert abs(np.linalg.norm(x[Q.SL_Q]) - 1.0) < 1e-14
    assert np.linalg.norm(x[Q.SL_W]) > 1.0  # it was really spinning


def test_integration_converges_with_fourth_order():
    par = Q.pack_params()
    cmds = _random_commands(np.random.default_rng(7), 50)  # held 10 ms each
    fe = np.array([0.8, -0.3, 0.0])
    vw = np.array([2.0, 1.0, 0.0])

    def run(dt):
        x = _state((0, 0, 10), thrust=2.0, w=(1.0, -0.5, 0.3))
        for u in cmds:
            x = Q.step_many(x, u, fe, vw, par, dt, round(0.01 / dt))
        return x

    x_ref = run(0.00025)
    e1 = np.abs(run(0.001) - x_ref).max()
    e2 = np.abs(run(0.002) - x_ref).max()
    assert e1 < 1e-8
    assert e2 / e1 > 10.0  # fourth order would give 16 (the reference has 1/256 of the dt=1 ms error)


def test_step_many_equals_repeated_step_and_input_is_untouched():
    par = Q.pack_params()
    x0 = _state((0, 0, 3), thrust=2.0, w=(0.1, 0.2, 0.3))
    keep = x0.copy()
    u = np.array([2.0, 3.0, 2.5, 2.2])
    x = x0
    for _ in range(7):
        x = Q.step(x, u, Z3, Z3, par, 0.001)
    np.testing.assert_array_equal(Q.step_many(x0, u, Z3, Z3, par, 0.001, 7), x)
    np.testing.assert_array_equal(x0, keep)


def test_ground_contact_holds_below_weight_and_lets_go_with_enough_thrust():
    af = DEFAULT_AIRFRAME
    par = Q.pack_params()
    cp = Q.pack_contact_params(af)
    deck = Q.no_deck()
    x = _state((0, 0, af.gear_height), yaw=1.0)
    u_low = np.full(4, 0.8 * af.weight_N / 4)
    for _ in range(2000):
        x = Q.step_contact(x, u_low, Z3, Z3, par, 0.001, deck, 0.0, cp)
    # the feet carry the fifth of the weight the rotors do not: 0.2 m g / (4 k) of compression
    assert x[2] == pytest.approx(af.gear_height - 0.2 * af.weight_N / (4 * cp[Q.CP_K]), abs=1e-5)
    np.testing.assert_allclose(x[Q.SL_V], 0.0, atol=1e-6)
    assert quat_to_rotmat(x[Q.SL_Q])[1, 0] == pytest.approx(math.sin(1.0))  # heading kept
    u_high = np.full(4, 1.3 * af.weight_N / 4)
    for _ in range(300):
        x = Q.step_contact(x, u_high, Z3, Z3, par, 0.001, deck, 0.0, cp)
    assert x[2] > af.gear_height + 0.01 and x[5] > 0.0


def test_step_contact_equals_step_away_from_every_surface():
    par = Q.pack_params()
    x0 = _state((0, 0, 3), thrust=2.0, w=(0.1, 0.2, 0.3))
    u = np.array([2.0, 3.0, 2.5, 2.2])
    np.testing.assert_array_equal(
        Q.step_contact(x0, u, Z3, Z3, par, 0.001, Q.no_deck(), 0.0, Q.pack_contact_params()),
        Q.step(x0, u, Z3, Z3, par, 0.001),
    )


def test_quadrotor_sim_shell():
    sim = Q.QuadrotorSim(dt=0.001)
    sim.reset(np.array([1.0, 2.0, 3.0]), yaw=0.5, hover=True)
    f = np.full(4, DEFAULT_AIRFRAME.weight_N / 4)
    sim.step(f, n=100)
    sim.step(f)
    assert sim.t == pytest.approx(0.101)
    np.testing.assert_allclose(sim.p_WB, [1.0, 2.0, 3.0], atol=1e-9)
    np.testing.assert_allclose(sim.accel_W(), 0.0, atol=1e-12)
    assert sim.R_WB[1, 0] == pytest.approx(math.sin(0.5))
    with pytest.raises(ValueError):
        Q.QuadrotorSim(dt=0.01)
