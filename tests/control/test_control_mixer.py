"""Body-rate loop and mixer: closed forms, exact allocation, the saturation priority order."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from alight.airframe import Airframe
from alight.control import (
    BodyRateController,
    Mixer,
    PriorityMixer,
    RateController,
    RateControllerGains,
    low_level,
    mix,
    pack_low_level_params,
    rate_torque,
)

AF = Airframe()
A = AF.allocation
F_MIN, F_MAX = AF.motor_thrust_min_N, AF.motor_thrust_max_N
P = pack_low_level_params(AF)


def _achieved(f: np.ndarray) -> np.ndarray:
    return A @ f


def test_rate_loop_closed_form() -> None:
    J = np.diag(AF.inertia_diag)
    k = np.array(RateControllerGains().k_rate)
    w_cmd = np.array([0.3, -1.0, 0.5])
    # at rest: pure proportional torque J K (w_cmd - w)
    np.testing.assert_allclose(rate_torque(w_cmd, np.zeros(3), P), J @ (k * w_cmd), rtol=1e-15)
    # on the command: only the gyroscopic term w x J w
    w = np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(rate_torque(w, w, P), np.cross(w, J @ w), rtol=1e-14)
    np.testing.assert_allclose(
        rate_torque(w_cmd, w, P), J @ (k * (w_cmd - w)) + np.cross(w, J @ w), rtol=1e-14
    )
    ctl = BodyRateController(AF)
    assert isinstance(ctl, RateController)
    np.testing.assert_array_equal(ctl.torque(w_cmd, w), rate_torque(w_cmd, w, P))


def test_unsaturated_mix_is_the_inverse_allocation() -> None:
    rng = np.random.default_rng(21)
    n = 0
    for _ in range(600):
        u = np.array([rng.uniform(2.0, 16.0), *rng.normal(0, 0.1, 2), rng.normal(0, 0.02)])
        f_exact = np.linalg.solve(A, u)
        if f_exact.min() < F_MIN or f_exact.max() > F_MAX:
            continue
        n += 1
        f = mix(u[0], u[1:], P)
        np.testing.assert_allclose(f, f_exact, atol=1e-13)
        np.testing.assert_allclose(A @ f, u, atol=1e-13)
    assert n > 300  # the sample really covers the unsaturated set


def test_outputs_always_within_rotor_limits() -> None:
    rng = np.random.default_rng(22)
    for _ in range(5000):
        T = rng.uniform(-10.0, 40.0)
        tau = rng.normal(0, 1, 3) * rng.choice([0.01, 0.3, 3.0], size=3)
        f = mix(T, tau, P)
        assert F_MIN <= f.min() and f.max() <= F_MAX


@pytest.mark.parametrize("T", [30.0, 18.0])
def test_roll_pitch_kept_when_collective_thrust_saturates_high(T: float) -> None:
    tau = np.array([0.08, -0.05, 0.0])
    f = mix(T, tau, P)
    u = _achieved(f)
    np.testing.assert_allclose(u[1:3], tau[:2], atol=1e-13)  # roll/pitch untouched
    assert u[3] == pytest.approx(0.0, abs=1e-13)
    assert f.max() == pytest.approx(F_MAX)  # the thrust is the largest that fits
    assert u[0] < T


def test_roll_pitch_kept_when_collective_thrust_saturates_low() -> None:
    tau = np.array([-0.1, 0.04, 0.0])
    f = mix(0.5, tau, P)
    u = _achieved(f)
    np.testing.assert_allclose(u[1:3], tau[:2], atol=1e-13)
    assert f.min() == pytest.approx(F_MIN, abs=1e-13)
    assert u[0] > 0.5


def test_yaw_is_given_up_before_thrust_and_roll_pitch() -> None:
    # Hover thrust, some roll/pitch and far more yaw than the drag torque can give. Keeping the whole yaw
    # torque would need a thrust change (and some of it is infeasible anyway): the mixer must instead keep
    # thrust and roll/pitch exactly and give the largest yaw torque that fits.
    T = AF.weight_N
    for tau_z in (0.5, -0.5, 0.12, -0.135):  # all beyond what fits (0.118 and -0.128 here)
        tau = np.array([0.1, 0.05, tau_z])
        f = mix(T, tau, P)
        u = _achieved(f)
        np.testing.assert_allclose(u[:3], [T, 0.1, 0.05], atol=1e-13)
        alpha = u[3] / tau_z
        assert 0.0 < alpha < 1.0 - 1e-6
        # alpha is the largest: one more bit of yaw (along A^-1 e_z) leaves the limits
        f_more = f + 1e-9 * np.linalg.solve(A, [0, 0, 0, tau_z])
        assert f_more.max() > F_MAX or f_more.min() < F_MIN


def test_thrust_is_reduced_only_when_roll_pitch_alone_does_not_fit() -> None:
    # thrust close to the maximum: roll/pitch fit with a lower thrust only; then yaw gets what is left
    tau = np.array([0.15, 0.0, 0.05])
    T = 17.5
    f = mix(T, tau, P)
    u = _achieved(f)
    np.testing.assert_allclose(u[1:3], tau[:2], atol=1e-13)
    f_rp = np.linalg.solve(A, [0, tau[0], tau[1], 0])
    T_fit = 4 * (F_MAX - f_rp.max())  # largest thrust with this roll/pitch (A^-1 e_T = 1/4 each)
    assert u[0] == pytest.approx(T_fit, rel=1e-12)
    assert abs(u[3]) <= abs(tau[2])


def test_infeasible_roll_pitch_is_scaled_with_its_direction_kept() -> None:
    tau = np.array([2.0, -1.0, 0.3])
    f = mix(AF.weight_N, tau, P)
    u = _achieved(f)
    assert u[1] / u[2] == pytest.approx(tau[0] / tau[1], rel=1e-12)
    assert 0.0 < u[1] / tau[0] < 1.0
    assert f.max() == pytest.approx(F_MAX) and f.min() == pytest.approx(F_MIN, abs=1e-12)
    assert u[3] == pytest.approx(0.0, abs=1e-12)


def test_low_level_is_rate_loop_then_mixer_and_callable_from_numba() -> None:
    @njit(cache=False)
    def fused(T: float, w_cmd: np.ndarray, w: np.ndarray, params: np.ndarray) -> np.ndarray:
        return low_level(T, w_cmd, w, params)

    w_cmd = np.array([0.5, -0.2, 0.1])
    w = np.array([0.1, 0.3, -0.4])
    expected = mix(9.0, rate_torque(w_cmd, w, P), P)
    np.testing.assert_array_equal(low_level(9.0, w_cmd, w, P), expected)
    np.testing.assert_array_equal(fused(9.0, w_cmd, w, P), expected)


def test_mixer_shell_and_bad_inputs() -> None:
    m = PriorityMixer(AF)
    assert isinstance(m, Mixer)
    np.testing.assert_allclose(m.mix(AF.weight_N, np.zeros(3)), AF.weight_N / 4)
    with pytest.raises(ValueError):
        m.mix(np.nan, np.zeros(3))
    with pytest.raises(ValueError):
        m.mix(1.0, np.zeros(4))
    with pytest.raises(ValueError):  # no yaw authority: the allocation is singular
        pack_low_level_params(Airframe(torque_coefficient=0.0))
