"""L1 adaptive augmentation (``alight.control.l1_adaptive``): the adaptation law against its closed form on
an exactly integrated plant, and closed-loop flights of the simulator (rigid body, first-order rotors,
rotor drag; rate loop + mixer at 1 kHz, high level at 100 Hz) with the SAME disturbance and reference
for the baseline and the baseline + L1.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache

import numpy as np
import pytest
from numba import njit

from alight.airframe import Airframe
from alight.control import (
    Controller,
    HighLevelController,
    HighLevelGains,
    attitude_from_accel_yaw,
    low_level,
    pack_low_level_params,
)
from alight.control.l1_adaptive import (
    S_THRUST,
    L1AugmentedController,
    L1Config,
    faessler2017_l1,
    l1_kernel,
    new_l1_state,
    pack_l1_params,
)
from alight.sim.quadrotor import IX_W, initial_state, pack_params, step
from alight.sim.wind import GustWind, SteadyWind
from alight.types import EgoState, Reference, rotmat_to_quat

AF = Airframe()
DT_SIM = 0.001
N_LOW = 10  # 1 kHz low level under the 100 Hz high level
T_CTRL = N_LOW * DT_SIM
G_W = np.array([0.0, 0.0, -9.81])


# --------------------------------------------------------------------------------------------------
# The adaptation law on an exactly integrated plant dv/dt = u + sigma (no simulator)
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("call_period", [0.01, 0.0025, 0.02])
def test_piecewise_constant_law_matches_its_closed_form(call_period: float) -> None:
    # Plant with a constant tilted attitude and no drag in the known model: over an interval with the
    # thrust T held, v gains dt ((T/m) z_B + g + sigma) exactly. The exact discretisation then gives,
    # at every adaptation, sigma_hat = e^{-a_s T} sigma_bar of the last adaptation interval T (derived in
    # the module docstring), whatever the call period (T = max(T_s, elapsed)). C(s) is the exact ZOH filter.
    cfg = L1Config(sample_time=0.01, predictor_pole=3.0, filter_bandwidth=4.0)
    params = pack_l1_params(cfg, AF.mass, (0.0, 0.0, 0.0))
    state = new_l1_state()
    rng = np.random.default_rng(11)
    R, _ = attitude_from_accel_yaw(np.array([1.0, -0.5, 0.3]), 0.4)
    q = rotmat_to_quat(R)
    z_B = R[:, 2]
    T_adapt = max(cfg.sample_time, call_period)
    calls_per_adapt = round(T_adapt / call_period)
    a_ref = np.array([0.2, -0.1, 0.05])
    j_ref = np.array([0.5, 0.2, -0.3])
    out = np.empty(6)
    v = np.array([0.3, -0.2, 0.1])
    sigma_seq = rng.normal(0.0, 2.0, (40, 3))  # one value per adaptation interval
    sig_hat_prev = np.zeros(3)
    sig_f = np.zeros(3)
    t = 0.0
    n_checked = 0
    for i in range(40):
        for c in range(calls_per_adapt):
            assert l1_kernel(t, v, q, a_ref, j_ref, params, state, out)
            if c == 0 and i >= 1:  # an adaptation just happened, after a full interval of sigma_seq[i-1]
                np.testing.assert_allclose(
                    state[3:6], math.exp(-cfg.predictor_pole * T_adapt) * sigma_seq[i - 1], atol=1e-9
                )
                n_checked += 1
            if i >= 1 or c > 0:
                # C(s) advanced over the last call with the previous sigma_hat held
                ec = math.exp(-cfg.filter_bandwidth * call_period)
                sig_f = sig_hat_prev + (sig_f - sig_hat_prev) * ec
                np.testing.assert_allclose(state[6:9], sig_f, atol=1e-9)
                np.testing.assert_allclose(out[:3], a_ref - sig_f, atol=1e-9)
                np.testing.assert_allclose(out[3:], j_ref, atol=0.0)  # no drag in the known model
            sig_hat_prev = state[3:6].copy()
            thrust = rng.uniform(5.0, 15.0)
            state[S_THRUST] = thrust
            v = v + call_period * (thrust / AF.mass * z_B + G_W + sigma_seq[i])
            t += call_period
    assert n_checked == 39


def test_constant_disturbance_fixed_point_is_exp_minus_as_ts() -> None:
    # The bias of the law with a Hurwitz predictor pole: sigma_hat -> e^{-a_s T_s} sigma, exactly.
    for a_s in (0.5, 1.0, 10.0):
        cfg = L1Config(predictor_pole=a_s)
        params = pack_l1_params(cfg, AF.mass, (0.0, 0.0, 0.0))
        state = new_l1_state()
        sigma = np.array([2.0, -1.0, 0.5])
        q = np.array([0.0, 0.0, 0.0, 1.0])
        v = np.zeros(3)
        out = np.empty(6)
        for k in range(400):
            assert l1_kernel(k * cfg.sample_time, v, q, np.zeros(3), np.zeros(3), params, state, out)
            state[S_THRUST] = AF.weight_N
            v = v + cfg.sample_time * sigma  # hover thrust cancels gravity
        factor = math.exp(-a_s * cfg.sample_time)
        np.testing.assert_allclose(state[3:6], factor * sigma, atol=1e-9)
        np.testing.assert_allclose(state[6:9], factor * sigma, atol=1e-6)  # C(s) settled (400 x 10 ms)


# --------------------------------------------------------------------------------------------------
# Closed loop in the simulator
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _fly(x, thrust_N, w_cmd, f_ext_W, v_wind_W, ll_params, sim_params, dt, n):  # type: ignore[no-untyped-def]
    for _ in range(n):
        f_cmd = low_level(thrust_N, w_cmd, x[IX_W : IX_W + 3], ll_params)
        x = step(x, f_cmd, f_ext_W, v_wind_W, sim_params, dt)
    return x


class _ConstantForce:
    def __init__(self, f_W: tuple[float, float, float]) -> None:
        self.f_W = np.array(f_W, dtype=float)

    def force_W(self, t: float, p_WB: np.ndarray, v_WB: np.ndarray) -> np.ndarray:
        return self.f_W.copy()

    def air_velocity_W(self, t: float) -> np.ndarray:
        return np.zeros(3)


def _hold(p: tuple[float, float, float]) -> Callable[[float], Reference]:
    z = np.zeros(3)
    return lambda t: Reference(t=t, p=np.array(p, float), v=z, a=z, j=z)


def _line(speed: float, height: float) -> Callable[[float], Reference]:
    # a platform driving along x at constant speed: what the landing tracks
    z = np.zeros(3)
    v = np.array([speed, 0.0, 0.0])
    return lambda t: Reference(t=t, p=np.array([speed * t, 0.0, height]), v=v, a=z, j=z)


def _circle(radius: float, speed: float, height: float) -> Callable[[float], Reference]:
    w = speed / radius

    def ref(t: float) -> Reference:
        c, s = math.cos(w * t), math.sin(w * t)
        return Reference(
            t=t,
            p=np.array([radius * c, radius * s, height]),
            v=np.array([-speed * s, speed * c, 0.0]),
            a=np.array([-speed * w * c, -speed * w * s, 0.0]),
            j=np.array([speed * w * w * s, -speed * w * w * c, 0.0]),
            yaw=w * t + math.pi / 2,
            yaw_rate=w,
        )

    return ref


REFERENCES: dict[str, Callable[[float], Reference]] = {
    "hover": _hold((0.0, 0.0, 1.0)),
    "line2": _line(2.0, 1.0),
    "hover8": _hold((0.0, 0.0, 8.0)),  # above 6 m the gust model blows at full power
    "line2_8": _line(2.0, 8.0),
    "circle2": _circle(2.0, 2.0, 1.0),
}
F_CONST = (3.0, -2.0, -1.0)  # N on the 1 kg vehicle: a side wind and a 0.1 kg payload's weight
KI = 2.0  # baseline integral gain for the comparison (1/s^3; < kp kv = 16, poles at -0.83, -1.6+-0.6j)


def _disturbance(name: str):  # type: ignore[no-untyped-def]
    if name == "const":
        return _ConstantForce(F_CONST)
    if name == "steady":
        return SteadyWind(np.array([-6.0, 3.0, 0.0]))  # ~2.4 N bluff body + ~2 N rotor drag on the air
    if name == "gust":
        return GustWind(np.random.default_rng(2024))  # paper 004 defaults: 7 N, 5.5 s cycles
    if name == "none":
        return _ConstantForce((0.0, 0.0, 0.0))
    raise KeyError(name)


def _controller(name: str) -> Controller:
    if name == "base":
        return HighLevelController(AF)
    if name == "base_i":
        return HighLevelController(AF, HighLevelGains(ki=(KI, KI, KI)))
    if name == "l1":
        return L1AugmentedController(HighLevelController(AF))
    if name == "l1_off":
        return L1AugmentedController(HighLevelController(AF), L1Config(enabled=False))
    raise KeyError(name)


@cache
def _flight(ctl_name: str, ref_name: str, dist_name: str, duration: float) -> dict[str, np.ndarray]:
    """Fly from rest on the reference (disturbance on from t = 0); positions errors, commands, estimates."""
    ctl = _controller(ctl_name)
    ref_fn = REFERENCES[ref_name]
    wind = _disturbance(dist_name)
    ll = pack_low_level_params(AF)
    sp = pack_params(AF)
    r0 = ref_fn(0.0)
    x = initial_state(r0.p, r0.yaw, AF.weight_N / 4)
    x[3:6] = r0.v
    n = int(round(duration / T_CTRL))
    err = np.zeros((n, 3))
    cmds = np.zeros((n, 4))
    sig = np.zeros((n, 3))
    for i in range(n):
        t = i * T_CTRL
        ego = EgoState.trusted(t, x[0:3], x[3:6], x[6:10], x[10:13])
        ref = ref_fn(t)
        cmd = ctl.command(ego, ref)
        err[i] = x[0:3] - ref.p
        cmds[i, 0] = cmd.thrust_N
        cmds[i, 1:] = cmd.w_WB_B_cmd
        if isinstance(ctl, L1AugmentedController):
            sig[i] = ctl.sigma_filtered
        f_ext = wind.force_W(t, x[0:3], x[3:6])
        v_air = wind.air_velocity_W(t)
        x = _fly(x, cmd.thrust_N, np.array(cmd.w_WB_B_cmd), f_ext, v_air, ll, sp, DT_SIM, N_LOW)
    return {"err": err, "cmds": cmds, "sigma_f": sig, "x": x}


def _rms(err: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(err * err, axis=1))))


@pytest.mark.parametrize(
    ("ref_name", "dist_name", "duration", "max_ratio"),
    [
        # measured ratios L1 / baseline: see the report (all well below the asserted 0.3)
        ("hover", "const", 12.0, 0.3),
        ("line2", "const", 12.0, 0.3),
        ("hover", "steady", 12.0, 0.3),
        ("hover8", "gust", 22.0, 0.3),
        ("line2_8", "gust", 22.0, 0.3),
    ],
)
def test_l1_cuts_the_rms_position_error_under_wind(
    ref_name: str, dist_name: str, duration: float, max_ratio: float
) -> None:
    # Same seeded disturbance, same reference, same start; the gains are the defaults (design rule in
    # the module docstring), not tuned here. The baseline balances a steady force with a position offset
    # F / (m kp) (0.9 m for 3.7 N); L1 cancels it within C(s)'s bandwidth.
    base = _rms(_flight("base", ref_name, dist_name, duration)["err"])
    base_i = _rms(_flight("base_i", ref_name, dist_name, duration)["err"])
    l1 = _rms(_flight("l1", ref_name, dist_name, duration)["err"])
    assert l1 < max_ratio * base  # at least 70 % less RMS position error (measured: > 90 %)
    # the baseline's own integrator also removes a steady offset, but at its slower pace
    assert l1 < 0.5 * base_i  # measured L1 / (base + integral): 0.10-0.20


def test_constant_force_estimate_and_offset_match_the_closed_form() -> None:
    # At steady hover the motors' thrust equals the command and the attitude is still, so the lumped
    # disturbance is exactly F / m, its estimate e^{-a_s T_s} F / m (1.0 % short with the defaults), and
    # the baseline sees only the remainder: offset (1 - e^{-a_s T_s}) F / (m kp) instead of F / (m kp).
    cfg = L1Config()
    factor = math.exp(-cfg.predictor_pole * cfg.sample_time)
    f = _flight("l1", "hover", "const", 12.0)
    sigma_true = np.array(F_CONST) / AF.mass
    np.testing.assert_allclose(f["sigma_f"][-1], factor * sigma_true, atol=1e-4 * np.linalg.norm(sigma_true))
    # ... i.e. within 1 % of the true F / m (1 - e^{-0.01} = 0.995 %)
    assert np.linalg.norm(f["sigma_f"][-1] - sigma_true) < 0.01 * np.linalg.norm(sigma_true)
    kp = np.array(HighLevelGains().kp)
    np.testing.assert_allclose(f["x"][0:3] - (0.0, 0.0, 1.0), (1 - factor) * sigma_true / kp, atol=1e-4)
    fb = _flight("base", "hover", "const", 12.0)
    np.testing.assert_allclose(fb["x"][0:3] - (0.0, 0.0, 1.0), sigma_true / kp, atol=1e-4)


@pytest.mark.parametrize(("ref_name", "duration"), [("hover", 6.0), ("circle2", 12.0)])
def test_without_disturbance_l1_does_not_degrade_tracking(ref_name: str, duration: float) -> None:
    # Rotor drag is in the predictor's known model (the baseline feeds it forward): nothing left to adapt
    # to but the motors' lag, so the circle at 2 m/s is tracked as well as without L1 (measured ratio 0.95).
    base = _flight("base", ref_name, "none", duration)
    l1 = _flight("l1", ref_name, "none", duration)
    assert _rms(l1["err"]) <= 1.05 * _rms(base["err"]) + 1e-4
    late = slice(int(5.0 / T_CTRL), None)
    assert np.abs(l1["err"][late]).max() < 0.01
    # the estimate stays small: no spurious compensation from the known dynamics
    assert np.abs(l1["sigma_f"][late]).max() < 0.05


def test_disabled_l1_gives_exactly_the_baseline_commands_while_estimating() -> None:
    base = _flight("base", "hover", "const", 6.0)
    off = _flight("l1_off", "hover", "const", 6.0)
    np.testing.assert_array_equal(off["cmds"], base["cmds"])
    # the estimator ran on the same flight: it sees F / m (the baseline's offset does not change that)
    sigma_true = np.array(F_CONST) / AF.mass
    assert np.linalg.norm(off["sigma_f"][-1] - sigma_true) < 0.01 * np.linalg.norm(sigma_true)


# --------------------------------------------------------------------------------------------------
# State handling, guards, configuration, registry
# --------------------------------------------------------------------------------------------------


def _ego(t: float, v=(0.0, 0.0, 0.0), p=(0.0, 0.0, 1.0)) -> EgoState:
    return EgoState.trusted(
        t, np.array(p, float), np.array(v, float), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)
    )


def _hover_ref(t: float) -> Reference:
    return _hold((0.0, 0.0, 1.0))(t)


def _drive(ctl: L1AugmentedController, n: int, dv: float = 0.02) -> None:
    # velocity creeping up at 2 m/s^2 in x while hovering: a disturbance the estimator must pick up
    for k in range(n):
        ctl.command(_ego(k * 0.01, v=(dv * k, 0.0, 0.0)), _hover_ref(k * 0.01))


def test_reset_clears_the_estimate_and_restarts_from_the_baseline() -> None:
    ctl = L1AugmentedController(HighLevelController(AF))
    _drive(ctl, 50)
    assert ctl.sigma_hat[0] > 1.5 and ctl.sigma_filtered[0] > 1.0
    ctl.reset()
    np.testing.assert_array_equal(ctl.sigma_hat, 0.0)
    np.testing.assert_array_equal(ctl.sigma_filtered, 0.0)
    np.testing.assert_array_equal(ctl.compensation, 0.0)
    ego, ref = _ego(5.0, v=(0.3, 0.0, 0.0)), _hover_ref(5.0)
    cmd = ctl.command(ego, ref)
    fresh = HighLevelController(AF).command(ego, ref)
    assert cmd.thrust_N == fresh.thrust_N
    np.testing.assert_array_equal(cmd.w_WB_B_cmd, fresh.w_WB_B_cmd)


def test_non_finite_time_falls_back_to_the_baseline_and_resets() -> None:
    ctl = L1AugmentedController(HighLevelController(AF))
    _drive(ctl, 50)
    ego, ref = _ego(math.nan, v=(0.3, 0.0, 0.0)), _hover_ref(0.5)
    cmd = ctl.command(ego, ref)
    fresh = HighLevelController(AF).command(ego, ref)
    assert math.isfinite(cmd.thrust_N) and np.isfinite(cmd.w_WB_B_cmd).all()
    assert cmd.thrust_N == fresh.thrust_N
    np.testing.assert_array_equal(cmd.w_WB_B_cmd, fresh.w_WB_B_cmd)
    np.testing.assert_array_equal(ctl.sigma_hat, 0.0)
    np.testing.assert_array_equal(ctl.sigma_filtered, 0.0)


def test_non_finite_velocity_never_gives_a_nan_command() -> None:
    # The baseline cannot command from a NaN velocity and says so (ValueError); L1 must not turn that
    # into a NaN command, and it resets and starts again on the next good sample.
    ctl = L1AugmentedController(HighLevelController(AF))
    _drive(ctl, 50)
    with pytest.raises(ValueError):
        ctl.command(_ego(0.5, v=(math.nan, 0.0, 0.0)), _hover_ref(0.5))
    np.testing.assert_array_equal(ctl.sigma_filtered, 0.0)
    cmd = ctl.command(_ego(0.51, v=(0.1, 0.0, 0.0)), _hover_ref(0.51))
    assert math.isfinite(cmd.thrust_N) and np.isfinite(cmd.w_WB_B_cmd).all()
    _drive(ctl, 60)
    assert np.isfinite(ctl.sigma_filtered).all() and ctl.sigma_hat[0] > 1.5


def test_estimate_is_projected_onto_the_limit_ball() -> None:
    cfg = L1Config(sigma_limit=1.0)
    ctl = L1AugmentedController(HighLevelController(AF), cfg)
    _drive(ctl, 50, dv=0.2)  # 20 m/s^2 of unexplained acceleration
    assert np.linalg.norm(ctl.sigma_hat) == pytest.approx(1.0, abs=1e-12)
    assert np.linalg.norm(ctl.compensation) <= 1.0 + 1e-12


def test_gap_restarts_the_predictor_and_keeps_the_estimate() -> None:
    ctl = L1AugmentedController(HighLevelController(AF))
    _drive(ctl, 50)
    sig_f = ctl.sigma_filtered
    # 1 s later, at a velocity that would mean 100 m/s^2 if integrated: ignored
    ctl.command(_ego(1.49, v=(100.0, 0.0, 0.0)), _hover_ref(1.49))
    np.testing.assert_array_equal(ctl.sigma_filtered, sig_f)
    np.testing.assert_array_equal(ctl.v_hat, (100.0, 0.0, 0.0))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"sample_time": 0.0},
        {"filter_bandwidth": -1.0},
        {"predictor_pole": 0.0},
        {"sigma_limit": math.inf},
        {"max_gap": 0.005},
        {"enabled": 1},
    ],
)
def test_bad_config_raises(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        L1Config(**kwargs)


def test_registry_factory_routes_options_and_keeps_the_contract() -> None:
    ctl = faessler2017_l1(AF, kp=(9.0, 9.0, 9.0), filter_bandwidth=3.0, enabled=False)
    assert isinstance(ctl, Controller)
    assert ctl.base.gains.kp == (9.0, 9.0, 9.0)
    assert ctl.config.filter_bandwidth == 3.0 and not ctl.enabled
    ctl = faessler2017_l1(AF)
    rng = np.random.default_rng(7)
    for k in range(50):
        R, _ = attitude_from_accel_yaw(rng.normal(0, 2, 3), rng.uniform(-3, 3))
        p, v, a, j = rng.normal(0, 1, (4, 3))
        ego = EgoState(t=0.01 * k, p_WB=p, v_WB=v, q_WB=rotmat_to_quat(R), w_WB_B=np.zeros(3))
        ref = Reference(t=0.01 * k, p=p + rng.normal(0, 1, 3), v=v, a=a, j=j, yaw=rng.uniform(-3, 3))
        cmd = ctl.command(ego, ref)
        assert math.isfinite(cmd.thrust_N) and np.isfinite(cmd.w_WB_B_cmd).all()
        assert 4 * AF.motor_thrust_min_N <= cmd.thrust_N <= 4 * AF.motor_thrust_max_N
        assert np.linalg.norm(ctl.compensation) <= ctl.config.sigma_limit + 1e-9
