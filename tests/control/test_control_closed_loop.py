"""Closed loop: the high-level controller at 100 Hz, the fused rate loop + mixer at 1 kHz, flying the
simulator's rigid-body quadrotor (first-order rotors, rotor drag) from ``alight.sim.quadrotor``.

The low level and the dynamics run in one numba loop, as the evaluation runner will run them, which also
checks that ``low_level`` composes with other compiled code.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from numba import njit

from alight.airframe import Airframe
from alight.control import (
    HighLevelController,
    HighLevelGains,
    attitude_from_accel_yaw,
    low_level,
    pack_low_level_params,
)
from alight.sim.quadrotor import IX_W, initial_state, pack_params, step
from alight.types import EgoState, Reference, quat_to_rotmat, yaw_of

AF = Airframe()
DT_SIM = 0.001
N_LOW = 10  # low-level steps per high-level step: 1 kHz under 100 Hz


@njit(cache=True)
def _fly(x, thrust_N, w_cmd, f_ext_W, ll_params, sim_params, dt, n):  # type: ignore[no-untyped-def]
    v_wind = np.zeros(3)
    for _ in range(n):
        f_cmd = low_level(thrust_N, w_cmd, x[IX_W : IX_W + 3], ll_params)
        x = step(x, f_cmd, f_ext_W, v_wind, sim_params, dt)
    return x


def _run(
    ref_fn: Callable[[float], Reference],
    duration: float,
    gains: HighLevelGains | None = None,
    x0: np.ndarray | None = None,
    f_ext_W=(0.0, 0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fly ``duration`` s from x0 (hover at the origin by default); returns times, positions, final state."""
    ctl = HighLevelController(AF, gains)
    ll = pack_low_level_params(AF)
    sp = pack_params(AF)
    fe = np.asarray(f_ext_W, dtype=float)
    x = initial_state(np.zeros(3), 0.0, AF.weight_N / 4) if x0 is None else x0.copy()
    n = int(round(duration / (N_LOW * DT_SIM)))
    ts = np.arange(n) * N_LOW * DT_SIM
    log = np.zeros((n, 6))
    for i, t in enumerate(ts):
        ego = EgoState(t=t, p_WB=x[0:3], v_WB=x[3:6], q_WB=x[6:10], w_WB_B=x[10:13])
        ref = ref_fn(t)
        cmd = ctl.command(ego, ref)
        log[i, :3] = x[0:3]
        log[i, 3:] = ref.p
        x = _fly(x, cmd.thrust_N, np.array(cmd.w_WB_B_cmd), fe, ll, sp, DT_SIM, N_LOW)
    return ts, log, x


def _hold(p: tuple[float, float, float], yaw: float) -> Callable[[float], Reference]:
    z = np.zeros(3)
    return lambda t: Reference(t=t, p=np.array(p), v=z, a=z, j=z, yaw=yaw)


def test_position_step_settles_without_steady_state_error_or_overshoot() -> None:
    target = (1.0, -1.0, 0.5)
    ts, log, x = _run(_hold(target, 0.5), 8.0)
    err = log[:, :3] - np.array(target)
    # critically damped design: the approach is monotone (no overshoot beyond 2 % of the step)
    assert (log[:, 0] <= 1.0 + 0.02).all() and (log[:, 1] >= -1.0 - 0.02).all() and (log[:, 2] <= 0.52).all()
    # ... and it gets there: no steady-state error
    np.testing.assert_allclose(x[0:3], target, atol=1e-3)
    np.testing.assert_allclose(x[3:6], 0.0, atol=2e-3)
    assert abs(math.remainder(yaw_of(quat_to_rotmat(x[6:10])) - 0.5, 2 * math.pi)) < 1e-3
    assert np.linalg.norm(err[int(2.0 / 0.01)]) < 0.5 * np.linalg.norm(err[0])


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
            yaw=w * t + math.pi / 2,  # facing along the path
            yaw_rate=w,
        )

    return ref


def _circle_start(ref: Reference) -> np.ndarray:
    x = initial_state(ref.p, ref.yaw, AF.weight_N / 4)
    x[3:6] = ref.v
    return x


def test_circle_at_2_mps_is_tracked_with_bounded_error() -> None:
    ref = _circle(2.0, 2.0, 1.0)
    ts, log, _ = _run(ref, 15.0, x0=_circle_start(ref(0.0)))
    err = np.linalg.norm(log[:, :3] - log[:, 3:], axis=1)
    assert err.max() < 0.15  # the start (level, not yet tilted into the turn)
    assert err[ts >= 5.0].max() < 0.01  # feed-forward and drag compensation: millimetres in the turn


def test_without_drag_compensation_the_circle_lags_by_the_linear_prediction() -> None:
    # The uncompensated rotor drag a_d = -R D R^T v rotates with the vehicle at w = v / r; the error of
    # e'' + kv e' + kp e = a_d is then |a_d| / |kp - w^2 + i kv w| in the horizontal plane.
    radius, speed = 2.0, 2.0
    w = speed / radius
    g = HighLevelGains(rotor_drag_compensation=False)
    ref = _circle(radius, speed, 1.0)
    ts, log, _ = _run(ref, 15.0, gains=g, x0=_circle_start(ref(0.0)))
    r0 = ref(0.0)
    R, _ = attitude_from_accel_yaw(r0.a, r0.yaw, v_W=r0.v, rotor_drag=AF.rotor_drag)
    a_d = R @ np.diag(AF.rotor_drag) @ R.T @ r0.v
    predicted = np.linalg.norm(a_d[:2]) / abs(complex(g.kp[0] - w * w, g.kv[0] * w))
    err_xy = np.linalg.norm(log[ts >= 8.0, :2] - log[ts >= 8.0, 3:5], axis=1)
    assert err_xy.mean() == pytest.approx(predicted, rel=0.1)


def test_constant_force_offset_matches_closed_form_and_the_integral_removes_it() -> None:
    # A steady force F (wind, a heavier payload) at hover: m (g + kp e) balances it, so p - p_ref = F / (m kp)
    # without the integral; with it (ki < kp kv) the offset goes to zero.
    F = np.array([0.4, -0.2, -0.981])
    target = (0.0, 0.0, 1.0)
    x0 = initial_state(np.array(target), 0.0, AF.weight_N / 4)
    g = HighLevelGains()
    _, _, x = _run(_hold(target, 0.0), 10.0, gains=g, x0=x0, f_ext_W=F)
    np.testing.assert_allclose(x[0:3] - target, F / (AF.mass * np.array(g.kp)), atol=1e-4)
    gi = HighLevelGains(ki=(2.0, 2.0, 2.0))
    _, _, x = _run(_hold(target, 0.0), 20.0, gains=gi, x0=x0, f_ext_W=F)
    np.testing.assert_allclose(x[0:3], target, atol=1e-4)
