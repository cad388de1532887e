"""High-level controller: feed-forward consistency, closed-form feedback, limits, integral, configuration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.airframe import Airframe
from alight.control import (
    CONTROLLERS,
    Controller,
    HighLevelController,
    HighLevelGains,
    RateControllerGains,
    attitude_from_accel_yaw,
    body_rates_from_jerk,
    pack_high_level_params,
)
from alight.types import EgoState, Reference, rot_z, rotmat_to_quat

AF = Airframe()
G = 9.81


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ego(p=(0.0, 0.0, 0.0), v=(0.0, 0.0, 0.0), R=None, t: float = 0.0) -> EgoState:
    q = rotmat_to_quat(np.eye(3) if R is None else R)
    return EgoState(t=t, p_WB=np.array(p, float), v_WB=np.array(v, float), q_WB=q, w_WB_B=np.zeros(3))


def _ref(
    p=(0.0, 0.0, 0.0),
    v=(0.0, 0.0, 0.0),
    a=(0.0, 0.0, 0.0),
    j=(0.0, 0.0, 0.0),
    yaw=0.0,
    yaw_rate=0.0,
    t: float = 0.0,
) -> Reference:
    return Reference(
        t=t,
        p=np.array(p, float),
        v=np.array(v, float),
        a=np.array(a, float),
        j=np.array(j, float),
        yaw=yaw,
        yaw_rate=yaw_rate,
    )


def test_hover_at_the_reference_gives_weight_and_zero_rates() -> None:
    cmd = HighLevelController(AF).command(_ego(p=(1, 2, 3)), _ref(p=(1, 2, 3)))
    assert cmd.thrust_N == pytest.approx(AF.weight_N, abs=1e-12)
    np.testing.assert_allclose(cmd.w_WB_B_cmd, 0.0, atol=1e-15)


@pytest.mark.parametrize("drag_comp", [True, False])
def test_zero_tracking_error_gives_exactly_the_feed_forward(drag_comp: bool) -> None:
    rng = np.random.default_rng(11)
    ctl = HighLevelController(AF, HighLevelGains(rotor_drag_compensation=drag_comp))
    drag = AF.rotor_drag if drag_comp else None
    for _ in range(50):
        p, v = rng.normal(0, 3, 3), rng.normal(0, 2, 3)
        a, j = rng.normal(0, 2, 3), rng.normal(0, 3, 3)
        yaw, yaw_rate = rng.uniform(-np.pi, np.pi), rng.normal(0, 1)
        R, c = attitude_from_accel_yaw(a, yaw, v_W=v, rotor_drag=drag)
        w = body_rates_from_jerk(a, j, yaw, yaw_rate, v_W=v, rotor_drag=drag)
        cmd = ctl.command(_ego(p, v, R), _ref(p, v, a, j, yaw, yaw_rate))
        assert cmd.thrust_N == pytest.approx(AF.mass * c, rel=1e-12)
        np.testing.assert_allclose(cmd.w_WB_B_cmd, w, atol=1e-9)
        np.testing.assert_allclose(np.abs(ctl.q_WB_des @ rotmat_to_quat(R)), 1.0, atol=1e-12)


@pytest.mark.parametrize("tilt", [0.1, 0.4, 0.7])
def test_thrust_is_projected_on_the_current_body_z_axis(tilt: float) -> None:
    cmd = HighLevelController(AF).command(_ego(R=_rx(tilt)), _ref())
    assert cmd.thrust_N == pytest.approx(AF.weight_N * math.cos(tilt), rel=1e-12)


@pytest.mark.parametrize(("tilt", "yaw_err"), [(0.3, 0.5), (-0.6, 2.0), (1.0, -2.5)])
def test_attitude_feedback_splits_tilt_and_yaw(tilt: float, yaw_err: float) -> None:
    g = HighLevelGains()
    kt, ky = 1.0 / g.tau_tilt, 1.0 / g.tau_yaw
    ctl = HighLevelController(AF, g)
    # R = Rz(yaw_err) Rx(tilt) and R_des = I: R_e = R^T = Rx(-tilt) Rz(-yaw_err), tilt part first
    cmd = ctl.command(_ego(R=rot_z(yaw_err) @ _rx(tilt)), _ref())
    expected = [-2 * kt * math.sin(tilt / 2), 0.0, -2 * ky * math.sin(yaw_err / 2)]
    np.testing.assert_allclose(cmd.w_WB_B_cmd, expected, atol=1e-12)
    # R = Rx(tilt) Rz(yaw_err): the tilt axis is x rotated by -yaw_err in the current body frame
    cmd = ctl.command(_ego(R=_rx(tilt) @ rot_z(yaw_err)), _ref())
    s = -2 * kt * math.sin(tilt / 2)
    expected = [s * math.cos(yaw_err), -s * math.sin(yaw_err), -2 * ky * math.sin(yaw_err / 2)]
    np.testing.assert_allclose(cmd.w_WB_B_cmd, expected, atol=1e-12)


def test_yaw_error_takes_the_short_way_round() -> None:
    # from yaw 3.0 to -3.0 is +0.28 rad through pi, not -6 rad (the long way would turn negative)
    cmd = HighLevelController(AF).command(_ego(R=rot_z(3.0)), _ref(yaw=-3.0))
    assert cmd.w_WB_B_cmd[2] == pytest.approx(2 / 0.3 * math.sin((2 * math.pi - 6.0) / 2), rel=1e-9)


def test_tilt_limit_keeps_the_vertical_part() -> None:
    max_tilt = math.radians(30)
    ctl = HighLevelController(AF, HighLevelGains(max_tilt=max_tilt))
    cmd = ctl.command(_ego(), _ref(p=(10.0, -5.0, 0.0)))
    q = ctl.q_WB_des
    z_des = np.array(
        [2 * (q[0] * q[2] + q[1] * q[3]), 2 * (q[1] * q[2] - q[0] * q[3]), 1 - 2 * (q[0] ** 2 + q[1] ** 2)]
    )
    assert math.acos(z_des[2]) == pytest.approx(max_tilt, abs=1e-12)
    np.testing.assert_allclose(
        z_des[:2] / np.linalg.norm(z_des[:2]), np.array([10.0, -5.0]) / math.hypot(10, 5)
    )
    assert cmd.thrust_N == pytest.approx(AF.weight_N, rel=1e-12)  # level vehicle: the vertical part only


def test_feed_forward_rates_follow_the_commanded_thrust_at_the_vertical_floor() -> None:
    """A reference in near free fall (c_ref = 0.1 m/s^2) with a sideways jerk: its own attitude turns at
    |j| / c_ref = 40 rad/s. The vertical floor holds the commanded thrust at 2 m/s^2 (level vehicle on
    the reference), whose direction turns at |j| / 2 for the same jerk: the feed-forward is the
    reference's scaled by c_ref / |f| = 0.05. With no clip the jerk is fed forward exactly; when the floor
    binds through the feedback (the reference 50 m below) with c_ref = g it is not scaled up, and a
    tilt-cone clip keeps it whole."""
    ctl = HighLevelController(AF)
    j = np.array([0.0, 4.0, 0.0])
    a_free = np.array([0.0, 0.0, -G + 0.1])
    fz_min = HighLevelGains().min_vertical_accel
    cmd = ctl.command(_ego(), _ref(a=a_free, j=j))
    w_free = body_rates_from_jerk(a_free, j, 0.0, 0.0, v_W=np.zeros(3), rotor_drag=AF.rotor_drag)
    assert abs(w_free[0]) == pytest.approx(40.0, rel=1e-9)
    np.testing.assert_allclose(cmd.w_WB_B_cmd, w_free * 0.1 / fz_min, atol=1e-9)
    assert cmd.thrust_N == pytest.approx(AF.mass * fz_min, rel=1e-12)
    # not clipped: the jerk is fed forward exactly
    w = body_rates_from_jerk(np.zeros(3), j, 0.0, 0.0, v_W=np.zeros(3), rotor_drag=AF.rotor_drag)
    np.testing.assert_allclose(ctl.command(_ego(), _ref(j=j)).w_WB_B_cmd, w, atol=1e-12)
    assert abs(w[0]) > 0.3
    # floored by the feedback, c_ref = g > |f| = 2: fed forward whole, not amplified
    low = ctl.command(_ego(), _ref(p=(0.0, 0.0, -50.0), j=j)).w_WB_B_cmd
    low0 = ctl.command(_ego(), _ref(p=(0.0, 0.0, -50.0))).w_WB_B_cmd
    np.testing.assert_allclose(low - low0, w, atol=1e-12)
    # the tilt cone clipping (20 m off the reference sideways): whole as well
    far_jerk = ctl.command(_ego(), _ref(p=(20.0, 0.0, 0.0), j=j)).w_WB_B_cmd
    far = ctl.command(_ego(), _ref(p=(20.0, 0.0, 0.0))).w_WB_B_cmd
    np.testing.assert_allclose(far_jerk - far, w, atol=1e-12)


def test_thrust_limits() -> None:
    ctl = HighLevelController(AF)
    assert ctl.command(_ego(), _ref(p=(0, 0, 50.0))).thrust_N == pytest.approx(4 * AF.motor_thrust_max_N)
    low = ctl.command(_ego(), _ref(p=(0, 0, -50.0))).thrust_N
    assert low == pytest.approx(AF.mass * HighLevelGains().min_vertical_accel)
    # upside down the projection is negative: clamp at the rotors' minimum
    assert ctl.command(_ego(R=_rx(math.pi * 0.9)), _ref()).thrust_N == pytest.approx(
        4 * AF.motor_thrust_min_N
    )


def test_body_rate_command_is_limited() -> None:
    cmd = HighLevelController(AF, HighLevelGains(body_rate_limit=2.0)).command(_ego(R=_rx(2.0)), _ref())
    assert np.abs(cmd.w_WB_B_cmd).max() == pytest.approx(2.0)


def test_integral_is_off_by_default_and_integrates_when_on() -> None:
    ctl = HighLevelController(AF)
    for k in range(5):
        ctl.command(_ego(t=0.01 * k), _ref(p=(0, 0, 0.1)))
    np.testing.assert_array_equal(ctl.integral, 0.0)
    ctl = HighLevelController(AF, HighLevelGains(ki=(1.0, 1.0, 1.0)))
    for k in range(5):
        ctl.command(_ego(t=0.01 * k), _ref(p=(0.2, 0, 0.1)))
    np.testing.assert_allclose(ctl.integral, [0.2 * 0.04, 0.0, 0.1 * 0.04], rtol=1e-12)  # first call: no dt
    ctl.command(_ego(t=5.0), _ref(p=(0.2, 0, 0.1)))  # a gap longer than integral_dt_max is not integrated
    np.testing.assert_allclose(ctl.integral, [0.2 * 0.04, 0.0, 0.1 * 0.04], rtol=1e-12)
    ctl.reset()
    np.testing.assert_array_equal(ctl.integral, 0.0)


def test_integral_anti_windup() -> None:
    ki = 2.0
    g = HighLevelGains(ki=(ki, ki, ki), integral_limit=0.5)
    # saturated (tilt limit): the integral is frozen
    ctl = HighLevelController(AF, g)
    for k in range(100):
        ctl.command(_ego(t=0.01 * k), _ref(p=(20.0, 0, 0)))
    np.testing.assert_array_equal(ctl.integral, 0.0)
    # not saturated: it grows, but its contribution stays within the limit
    ctl = HighLevelController(AF, g)
    for k in range(1000):
        ctl.command(_ego(t=0.01 * k), _ref(p=(0.5, 0, 0)))
    assert ki * ctl.integral[0] == pytest.approx(0.5)


def test_non_finite_state_raises() -> None:
    with pytest.raises(ValueError):
        HighLevelController(AF).command(_ego(p=(math.nan, 0, 0)), _ref())


def test_gains_from_bandwidth() -> None:
    g = HighLevelGains.from_bandwidth(1.5, zeta=0.8)
    assert g.kp == (2.25, 2.25, 2.25)
    assert g.kv == pytest.approx((2.4, 2.4, 2.4))
    # defaults: critically damped, omega_n = 2 rad/s
    d = HighLevelGains()
    for kp, kv in zip(d.kp, d.kv, strict=True):
        assert kv / (2 * math.sqrt(kp)) == pytest.approx(1.0)
        assert math.sqrt(kp) == pytest.approx(2.0)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"kp": (4.0, 0.0, 4.0)},
        {"kv": (4.0, 4.0, -1.0)},
        {"kp": (4.0, 4.0, math.nan)},
        {"ki": (-0.1, 0.0, 0.0)},
        {"ki": (16.0, 0.0, 0.0)},  # = kp kv: marginally stable (Routh-Hurwitz)
        {"tau_tilt": 0.0},
        {"tau_yaw": -0.3},
        {"max_tilt": math.pi / 2},
        {"max_tilt": 0.0},
        {"min_vertical_accel": 0.0},
        {"body_rate_limit": math.inf},
        {"integral_limit": -1.0},
    ],
)
def test_bad_gains_raise(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        HighLevelGains(**kwargs)


def test_bad_rate_gains_and_airframe_mismatch_raise() -> None:
    for k in [(25.0, 0.0, 10.0), (25.0, 25.0, -1.0), (math.nan, 1.0, 1.0)]:
        with pytest.raises(ValueError):
            RateControllerGains(k_rate=k)
    with pytest.raises(ValueError):  # above the airframe's largest collective acceleration (18.1 m/s^2)
        pack_high_level_params(AF, HighLevelGains(min_vertical_accel=19.0))


@pytest.mark.parametrize("name", sorted(CONTROLLERS))
def test_registry_contract(name: str) -> None:
    ctl = CONTROLLERS[name].build_default(AF)
    assert isinstance(ctl, Controller)
    rng = np.random.default_rng(7)
    for k in range(20):
        R, _ = attitude_from_accel_yaw(rng.normal(0, 2, 3), rng.uniform(-3, 3))
        cmd = ctl.command(
            _ego(rng.normal(0, 1, 3), rng.normal(0, 1, 3), R, t=0.01 * k),
            _ref(
                rng.normal(0, 1, 3),
                rng.normal(0, 1, 3),
                rng.normal(0, 1, 3),
                rng.normal(0, 1, 3),
                rng.uniform(-3, 3),
                rng.normal(),
                t=0.01 * k,
            ),
        )
        assert math.isfinite(cmd.thrust_N) and np.isfinite(cmd.w_WB_B_cmd).all()
        assert 4 * AF.motor_thrust_min_N <= cmd.thrust_N <= 4 * AF.motor_thrust_max_N
    ctl.reset()


@pytest.mark.parametrize("limit_deg", [5.0, 12.0, 30.0])
def test_a_lowered_tilt_limit_bounds_the_desired_attitude_and_is_undone(limit_deg: float) -> None:
    """``set_tilt_limit`` (the take-off's limit near the ground): a far horizontal reference asks for more
    tilt than the limit; the desired attitude's tilt equals the limit exactly, and None restores the
    controller's own limit (a command identical to a fresh controller's)."""
    from alight.control import L1AugmentedController, TiltLimited
    from alight.types import quat_to_rotmat

    ego, ref = _ego(p=(0, 0, 2)), _ref(p=(20, 0, 2))
    for ctl in (HighLevelController(AF), L1AugmentedController(HighLevelController(AF))):
        assert isinstance(ctl, TiltLimited)
        ctl.set_tilt_limit(math.radians(limit_deg))
        ctl.command(ego, ref)
        base = ctl.base if isinstance(ctl, L1AugmentedController) else ctl
        R_des = quat_to_rotmat(base.q_WB_des)
        assert math.degrees(math.acos(R_des[2, 2])) == pytest.approx(limit_deg, abs=1e-9)
        ctl.set_tilt_limit(None)
        ctl.reset()
        assert (
            ctl.command(ego, ref).w_WB_B_cmd.tolist()
            == type(ctl)(*([HighLevelController(AF)] if isinstance(ctl, L1AugmentedController) else [AF]))
            .command(ego, ref)
            .w_WB_B_cmd.tolist()
        )
    with pytest.raises(ValueError, match="max_tilt_rad"):
        HighLevelController(AF).set_tilt_limit(math.pi / 2)
