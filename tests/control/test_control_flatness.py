"""Differential-flatness relations of the high-level controller: closed forms and finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.control import attitude_from_accel_yaw, body_rates_from_jerk
from alight.types import G_W, rot_z, yaw_of

DRAG = (0.3, 0.3, 0.05)


def _vee(M: np.ndarray) -> np.ndarray:
    S = 0.5 * (M - M.T)
    return np.array([S[2, 1], S[0, 2], S[1, 0]])


class SmoothTrajectory:
    """p(t) = sum_k A_k sin(w_k t + phi_k) per axis and yaw(t) likewise, with exact derivatives."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.A = rng.uniform(0.3, 1.5, size=(3, 3))
        self.w = rng.uniform(0.3, 1.5, size=(3, 3))
        self.phi = rng.uniform(0, 2 * np.pi, size=(3, 3))
        self.yA = rng.uniform(0.3, 1.5, size=2)
        self.yw = rng.uniform(0.3, 1.2, size=2)
        self.yphi = rng.uniform(0, 2 * np.pi, size=2)

    def deriv(self, t: float, n: int) -> np.ndarray:
        # d^n/dt^n sin(w t + phi) = w^n sin(w t + phi + n pi / 2)
        return (self.A * self.w**n * np.sin(self.w * t + self.phi + n * np.pi / 2)).sum(axis=1)

    def yaw(self, t: float, n: int = 0) -> float:
        return float(
            (self.yA * self.yw**n * np.sin(self.yw * t + self.yphi + n * np.pi / 2)).sum() + (n == 0)
        )


def test_hover_is_level_with_gravity_thrust_and_no_rates() -> None:
    R, c = attitude_from_accel_yaw(np.zeros(3), 0.0)
    np.testing.assert_allclose(R, np.eye(3), atol=1e-15)
    assert c == pytest.approx(9.81, abs=1e-14)
    np.testing.assert_allclose(body_rates_from_jerk(np.zeros(3), np.zeros(3), 0.0, 0.0), 0.0, atol=1e-15)


@pytest.mark.parametrize("yaw", [-3.0, -1.2, 0.4, 2.9])
def test_hover_with_yaw_is_a_pure_heading_rotation(yaw: float) -> None:
    R, c = attitude_from_accel_yaw(np.zeros(3), yaw)
    np.testing.assert_allclose(R, rot_z(yaw), atol=1e-14)
    assert c == pytest.approx(9.81)
    # a yaw rate alone at hover is a body z rate of the same size
    np.testing.assert_allclose(
        body_rates_from_jerk(np.zeros(3), np.zeros(3), yaw, 0.7), [0, 0, 0.7], atol=1e-14
    )


def test_attitude_is_a_rotation_with_thrust_along_a_minus_g_and_zyx_yaw() -> None:
    rng = np.random.default_rng(1)
    for _ in range(200):
        a = rng.normal(0.0, 4.0, 3)
        yaw = rng.uniform(-np.pi, np.pi)
        R, c = attitude_from_accel_yaw(a, yaw)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
        np.testing.assert_allclose(c * R[:, 2], a - G_W, atol=1e-12)
        # the heading every other block reads (types.yaw_of, ZYX) is the one commanded
        if R[2, 2] > 0:
            assert math.remainder(yaw_of(R) - yaw, 2 * np.pi) == pytest.approx(0.0, abs=1e-12)


def test_attitude_with_rotor_drag_satisfies_the_translational_dynamics() -> None:
    # Faessler 2018 eq. 2: a = g + c z_B - R D R^T v
    rng = np.random.default_rng(2)
    D = np.diag(DRAG)
    for _ in range(100):
        a = rng.normal(0.0, 3.0, 3)
        v = rng.normal(0.0, 4.0, 3)
        yaw = rng.uniform(-np.pi, np.pi)
        R, c = attitude_from_accel_yaw(a, yaw, v_W=v, rotor_drag=DRAG)
        np.testing.assert_allclose(G_W + c * R[:, 2] - R @ D @ R.T @ v, a, atol=1e-11)
        assert math.remainder(yaw_of(R) - yaw, 2 * np.pi) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("drag", [None, DRAG])
@pytest.mark.parametrize("seed", [3, 4, 5])
def test_body_rates_match_finite_differences_of_the_attitude(seed: int, drag: tuple | None) -> None:
    traj = SmoothTrajectory(np.random.default_rng(seed))
    h = 1e-5
    worst = 0.0
    worst_c = 0.0
    for t in np.linspace(0.0, 12.0, 60):

        def att(tt: float) -> tuple[np.ndarray, float]:
            return attitude_from_accel_yaw(
                traj.deriv(tt, 2), traj.yaw(tt), v_W=traj.deriv(tt, 1), rotor_drag=drag
            )

        R, c = att(t)
        Rp, cp = att(t + h)
        Rm, cm = att(t - h)
        w_fd = _vee(R.T @ (Rp - Rm) / (2 * h))
        w = body_rates_from_jerk(
            traj.deriv(t, 2),
            traj.deriv(t, 3),
            traj.yaw(t),
            traj.yaw(t, 1),
            v_W=traj.deriv(t, 1),
            rotor_drag=drag,
        )
        worst = max(worst, float(np.abs(w - w_fd).max()))
        if drag is None:  # c_dot = z_B . j (reference sheet)
            worst_c = max(worst_c, abs(R[:, 2] @ traj.deriv(t, 3) - (cp - cm) / (2 * h)))
    assert worst < 1e-6
    assert worst_c < 1e-6


def test_bad_inputs_raise() -> None:
    with pytest.raises(ValueError):
        attitude_from_accel_yaw(G_W, 0.0)  # free fall: no thrust direction
    with pytest.raises(ValueError):
        attitude_from_accel_yaw(np.zeros(2), 0.0)
    with pytest.raises(ValueError):
        attitude_from_accel_yaw(np.zeros(3), math.nan)
    with pytest.raises(ValueError):
        body_rates_from_jerk(np.zeros(3), [0.0, np.inf, 0.0], 0.0, 0.0)
