"""The contact model of the feet with the deck and the ground (sim.quadrotor.step_contact, run through
the fused 1 kHz loop of sim.physics): rest, impact, bounce, friction, a braking deck, stability."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from alight.airframe import DEFAULT_AIRFRAME as AF
from alight.control.rate import pack_low_level_params
from alight.sim import quadrotor as Q
from alight.sim.physics import IN_DECK, IN_MOTORS_ON, IN_THRUST, N_IN, tick_batch

PAR = Q.pack_params(AF)
LL = pack_low_level_params(AF)
CP = Q.pack_contact_params(AF)
DT, N_SUB = 0.001, 5
H = 0.5  # deck height (m)
W = AF.weight_N


def _deck(v=(0.0, 0.0, 0.0), a=(0.0, 0.0, 0.0), xy=(0.0, 0.0), yaw=0.0, yaw_rate=0.0, size=1.5):
    d = np.zeros(Q.N_DK)
    d[Q.DK_ON] = 1.0
    d[Q.DK_P : Q.DK_P + 3] = (xy[0], xy[1], H)
    d[Q.DK_YAW], d[Q.DK_HALF], d[Q.DK_YAW_RATE] = yaw, 0.5 * size, yaw_rate
    d[Q.DK_V : Q.DK_V + 3] = v
    d[Q.DK_A : Q.DK_A + 3] = a
    return d


def _fly(x, seconds, deck, thrust_N=0.0, motors_on=False, deck_moves=True):
    """Run the fused loop for ``seconds``; the deck is re-stamped every tick as the runner does. Returns
    the states, specific forces and feet counts at every 5 ms tick."""
    inputs = np.zeros(N_IN)
    inputs[IN_THRUST] = thrust_N
    inputs[IN_MOTORS_ON] = 1.0 if motors_on else 0.0
    noise = np.zeros((1, 12))
    xs, fs, cs = [], [], []
    d = deck.copy()
    for _ in range(round(seconds / (DT * N_SUB))):
        inputs[IN_DECK : IN_DECK + Q.N_DK] = d
        out, imu, touch, _ = tick_batch(
            x, inputs, PAR, LL, np.zeros(6), noise, np.ones(6), DT, N_SUB, CP, 1, -math.inf, math.inf
        )
        x = out[0]
        xs.append(x.copy())
        fs.append(imu[0, 0:3].copy())
        cs.append(touch[0].copy())
        if deck_moves:
            now = np.empty(Q.N_DK)
            Q.deck_at(d, DT * N_SUB, now)
            d = now
    return np.array(xs), np.array(fs), np.array(cs)


def _above_deck(dz=0.0, xy=(0.0, 0.0), v=(0.0, 0.0, 0.0)):
    x = Q.initial_state(np.array([xy[0], xy[1], H + AF.gear_height + dz]))
    x[Q.SL_V] = v
    return x


def test_rests_on_the_ground_with_a_millimetre_of_compression_and_stays_still():
    x = Q.initial_state(np.array([0.0, 0.0, AF.gear_height]))
    xs, fs, cs = _fly(x, 10.0, Q.no_deck())
    static = W / (4 * CP[Q.CP_K])
    assert xs[-1, 2] == pytest.approx(AF.gear_height - static, abs=2e-4)
    assert np.all(np.abs(xs[-200:, Q.IX_V : Q.IX_V + 3]) < 1e-4)  # settled, no energy creeping in
    assert np.all(cs[-1] == (0, 4))
    assert fs[-1, 2] == pytest.approx(9.81, abs=0.05)  # the accelerometer reads the ground's support


def test_a_descent_onto_the_deck_stops_with_an_impact_the_accelerometer_sees():
    x = _above_deck(0.02, v=(0.0, 0.0, -0.5))
    xs, fs, cs = _fly(x, 2.0, _deck(), deck_moves=False)
    first = int(np.argmax(cs[:, 0] > 0))
    assert first > 0 and np.all(cs[first + 40 :, 0] == 4) and np.all(cs[:, 1] == 0)
    assert np.max(fs[first : first + 6, 2]) > 9.81 + 5.0  # the impact spike
    assert abs(xs[-1, Q.IX_V + 2]) < 1e-3
    assert np.max(xs[first:, 2]) < H + AF.gear_height  # motors off: no lift-off


def test_thrust_kept_after_contact_lifts_the_vehicle_off_again():
    x = _above_deck(0.01, v=(0.0, 0.0, -0.3))
    x[Q.SL_F] = 1.1 * W / 4
    xs, _, cs = _fly(x, 1.0, _deck(), thrust_N=1.1 * W, motors_on=True, deck_moves=False)
    touched = np.flatnonzero(cs[:, 0] > 0)
    assert touched.size > 0
    assert np.all(cs[touched[-1] + 1 :, 0] == 0) and xs[-1, 2] > H + AF.gear_height + 0.1


def test_the_moving_deck_carries_the_vehicle_by_friction():
    x = _above_deck(0.005, v=(0.0, 0.0, -0.2))
    xs, _, cs = _fly(x, 3.0, _deck(v=(2.0, 0.0, 0.0)))
    # it lands with zero ground speed on a deck moving at 2 m/s: friction brings it up to the deck's speed
    assert xs[-1, Q.IX_V] == pytest.approx(2.0, abs=0.01)
    assert np.all(cs[-1] == (4, 0))


def test_a_braking_deck_decelerates_the_resting_vehicle_without_sliding_it_off():
    # 3 m/s, braking at 2.5 m/s^2 (below mu g = 5.9) for 1.2 s: the vehicle sticks and brakes with it
    d = _deck(v=(3.0, 0.0, 0.0), a=(-2.5, 0.0, 0.0))
    x = _above_deck(-W / (4 * CP[Q.CP_K]), v=(3.0, 0.0, 0.0))
    xs, _, cs = _fly(x, 1.2, d)
    deck_x = 3.0 * 1.2 - 0.5 * 2.5 * 1.2**2
    # the regularised friction lets the feet creep at ~1 cm/s under that load
    assert xs[-1, Q.IX_V] == pytest.approx(3.0 - 2.5 * 1.2, abs=0.015)
    assert xs[-1, 0] == pytest.approx(deck_x, abs=0.02)
    assert np.all(cs[:, 0] == 4)


def test_a_deck_braking_harder_than_friction_holds_slides_the_vehicle_forward():
    # 4 m/s braking at 9 m/s^2 > mu g: the vehicle slides forward relative to the deck and tips over the
    # front edge or falls off it
    d = _deck(v=(4.0, 0.0, 0.0), a=(-9.0, 0.0, 0.0))
    x = _above_deck(-W / (4 * CP[Q.CP_K]), v=(4.0, 0.0, 0.0))
    xs, _, cs = _fly(x, 0.44, d)
    deck_x = 4.0 * 0.44 - 0.5 * 9.0 * 0.44**2
    assert xs[-1, 0] - deck_x > 0.1


def test_landing_beside_the_deck_touches_the_ground():
    x = Q.initial_state(np.array([3.0, 0.0, AF.gear_height + 0.01]))
    x[Q.IX_V + 2] = -0.3
    _, _, cs = _fly(x, 0.5, _deck(), deck_moves=False)
    assert np.any(cs[:, 1] == 4) and np.all(cs[:, 0] == 0)


def test_one_foot_over_the_edge_tips_the_vehicle():
    # centre 0.7 m from the deck centre on a 1.5 m deck: the two outer feet (at 0.9 m) find no deck
    x = _above_deck(0.005, xy=(0.7, 0.0), v=(0.0, 0.0, -0.2))
    xs, _, _ = _fly(x, 1.5, _deck(), deck_moves=False)
    R = Q.quat_to_rotmat(xs[-1, Q.SL_Q])
    assert math.degrees(math.acos(R[2, 2])) > 30.0


def test_the_deck_brakes_at_the_moment_of_contact():
    # descending at 0.4 m/s with the deck's 3 m/s matched, the deck starts braking at 4 m/s^2 as the feet
    # touch (platform.speed_profile brake_stop's case): friction (mu g = 5.9 m/s^2) takes the vehicle
    # along; it ends up at rest on the deck, where it touched down, upright
    lead = 0.01 / 0.4  # the feet are 1 cm above the deck: contact after 25 ms
    d = _deck(v=(3.0, 0.0, 0.0))
    x = _above_deck(0.01, v=(3.0, 0.0, -0.4))
    xs, _, cs = _fly(x, lead, d)
    deck_now = np.empty(Q.N_DK)
    Q.deck_at(d, lead, deck_now)
    deck_now[Q.DK_A] = -4.0
    xs2, fs, cs2 = _fly(xs[-1], 0.75, deck_now)
    stop = np.empty(Q.N_DK)
    Q.deck_at(deck_now, 0.75, stop)  # the deck has stopped: 3 - 4 * 0.75 = 0
    assert stop[Q.DK_V] == pytest.approx(0.0, abs=1e-9)
    assert np.all(cs2[10:, 0] == 4)  # on the deck throughout the braking
    assert xs2[-1, Q.IX_V] == pytest.approx(0.0, abs=0.03)
    assert abs(xs2[-1, 0] - stop[Q.DK_P]) < 0.05  # slid less than 5 cm on the deck
    R = Q.quat_to_rotmat(xs2[-1, Q.SL_Q])
    assert math.degrees(math.acos(min(1.0, R[2, 2]))) < 3.0
    assert np.max(np.abs(fs[:, 0])) > 3.0  # the accelerometer feels the braking through the feet


@njit(cache=False)
def _step_contact_every_stage(x, u, f_ext, v_wind, par, dt, deck, deck_tau, cp):  # type: ignore[no-untyped-def]
    """The RK4 step as it was before ``feet_clear``: the contact derivative in every stage (reference)."""
    f0 = x[Q.IX_F : Q.IX_F + 4].copy()
    c = np.empty(4)
    tau = np.empty(4)
    for i in range(4):
        c[i] = min(max(u[i], par[Q.PAR_F_MIN]), par[Q.PAR_F_MAX])
        tau[i] = par[Q.PAR_TAU_UP] if c[i] >= f0[i] else par[Q.PAR_TAU_DOWN]
    f_mid = np.empty(4)
    f_end = np.empty(4)
    Q._motor_thrust_at(f0, c, tau, 0.5 * dt, f_mid)
    Q._motor_thrust_at(f0, c, tau, dt, f_end)
    d0 = np.empty(Q.N_DK)
    dm = np.empty(Q.N_DK)
    d1 = np.empty(Q.N_DK)
    Q.deck_at(deck, deck_tau, d0)
    Q.deck_at(deck, deck_tau + 0.5 * dt, dm)
    Q.deck_at(deck, deck_tau + dt, d1)
    fc = np.empty(3)
    tc = np.empty(3)
    y0 = x[:13]
    k1, k2, k3, k4, tmp = np.empty(13), np.empty(13), np.empty(13), np.empty(13), np.empty(13)
    Q._contact_deriv(y0, f0, f_ext, v_wind, par, d0, cp, fc, tc, k1)
    for j in range(13):
        tmp[j] = y0[j] + 0.5 * dt * k1[j]
    Q._contact_deriv(tmp, f_mid, f_ext, v_wind, par, dm, cp, fc, tc, k2)
    for j in range(13):
        tmp[j] = y0[j] + 0.5 * dt * k2[j]
    Q._contact_deriv(tmp, f_mid, f_ext, v_wind, par, dm, cp, fc, tc, k3)
    for j in range(13):
        tmp[j] = y0[j] + dt * k3[j]
    Q._contact_deriv(tmp, f_end, f_ext, v_wind, par, d1, cp, fc, tc, k4)
    out = np.empty(Q.NX)
    h6 = dt / 6.0
    for j in range(13):
        out[j] = y0[j] + h6 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    nq = math.sqrt(out[6] ** 2 + out[7] ** 2 + out[8] ** 2 + out[9] ** 2)
    for j in range(6, 10):
        out[j] /= nq
    for i in range(4):
        out[Q.IX_F + i] = f_end[i]
    return out


def test_step_contact_skips_the_contact_only_where_it_is_zero():
    """``feet_clear`` lets a step leave out the contact's derivative high above every surface: the same
    numbers, bit for bit, as the contact derivative in every RK4 stage, from high above down through the
    deck's and the ground's contact (tilted, spinning, on and beside the deck)."""
    rng = np.random.default_rng(11)
    wind = np.array([1.0, -0.5, 0.0])
    for _ in range(400):
        z = rng.uniform(-0.05, 1.2) if rng.random() < 0.8 else rng.uniform(1.2, 5.0)
        q = rng.normal(size=4) * np.array([0.1, 0.1, 1.0, 1.0])
        x = Q.initial_state(np.array([rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5), z]))
        x[Q.SL_Q] = q / np.linalg.norm(q)
        x[Q.SL_V] = rng.normal(size=3)
        x[Q.SL_W] = rng.normal(size=3)
        x[Q.SL_F] = rng.uniform(0.0, 5.0, 4)
        u = rng.uniform(0.0, 6.0, 4)
        deck = _deck(v=rng.normal(size=3) * [2, 2, 0.1], a=rng.normal(size=3), yaw=rng.uniform(-3, 3),
                     yaw_rate=rng.normal() * 0.3)  # fmt: skip
        if rng.random() < 0.2:
            deck = Q.no_deck()
        tau = rng.uniform(0.0, 0.005)
        got = Q.step_contact(x, u, wind, wind, PAR, DT, deck, tau, CP)
        want = _step_contact_every_stage(x, u, wind, wind, PAR, DT, deck, tau, CP)
        np.testing.assert_array_equal(got, want)
        if Q.feet_clear(float(x[2]), deck, CP):
            f, t, counts = np.empty(3), np.empty(3), np.empty(2)
            assert Q.contact_wrench(x, deck, CP, f, t, counts) == 0
