"""Contract tests over every registered estimator, and meta-tests of the configs."""

from __future__ import annotations

import ast
import inspect
import math

import numpy as np
import pytest

from alight.cameras import CameraMount, MountedCamera
from alight.estimation import (
    PLATFORM_ESTIMATORS,
    EgoEkf,
    EgoEkfConfig,
    EgoEstimator,
    PlatformEkfConfig,
    PlatformEstimator,
)
from alight.estimation.kim_ukf import KimUkfConfig
from alight.estimation.platform_velocity import PlatformVelocityConfig
from alight.estimation.sdu_kf import SduKfConfig
from alight.types import GRAVITY_MPS2, PlatformEstimate, PlatformMeasurement


def assert_spd(P: np.ndarray) -> None:
    assert np.all(np.isfinite(P))
    assert np.allclose(P, P.T, atol=1e-12 * max(1.0, np.abs(P).max()))
    assert np.linalg.eigvalsh(P).min() > 0


def platform_estimator(name: str) -> PlatformEstimator:
    """The registry's block ``name`` at the parameters it flies with, without a camera."""
    return PLATFORM_ESTIMATORS[name].build_default(MountedCamera(camera=None, mount=CameraMount.downward()))


@pytest.mark.parametrize("name", sorted(PLATFORM_ESTIMATORS))
def test_platform_estimator_contract(name: str) -> None:
    est = platform_estimator(name)
    assert isinstance(est, PlatformEstimator)
    assert not est.initialized
    rng = np.random.default_rng(0)
    times = np.linspace(0.0, 3.0, 61)
    for t in times:  # a gentle arc at 2 m/s
        p = np.array([5 * math.sin(0.4 * t), 5 * (1 - math.cos(0.4 * t)), 0.4]) + rng.normal(0, 0.05, 3)
        est.predict(t + 0.1)
        est.update(PlatformMeasurement(t=float(t), p_WP=p, cov_p_WP=np.eye(3) * 0.05**2))
        s = est.state(t + 0.1)
        assert isinstance(s, PlatformEstimate)
        for a in (s.p_WP, s.v_WP, s.a_WP, s.cov_p_WP):
            assert np.all(np.isfinite(a))
        assert math.isfinite(s.yaw)
        assert_spd(s.cov_p_WP)
    assert est.initialized
    ahead = times[-1] + np.linspace(0.0, 2.0, 20)
    p, v, a, yaw = est.predict_ahead(ahead)
    assert p.shape == v.shape == a.shape == (20, 3) and yaw.shape == (20,)
    assert all(np.all(np.isfinite(x)) for x in (p, v, a, yaw))
    assert np.linalg.norm(v[0]) == pytest.approx(2.0, abs=0.3)
    est.reset()
    assert not est.initialized


@pytest.mark.parametrize("name", sorted(PLATFORM_ESTIMATORS))
def test_platform_blocks_refuse_unknown_parameters(name: str) -> None:
    with pytest.raises(ValueError, match="no_such_parameter: unknown parameter"):
        PLATFORM_ESTIMATORS[name].make_params({"no_such_parameter": 1.0}, {}, "blocks.platform_estimator")


def test_ego_estimator_contract() -> None:
    est: EgoEstimator = EgoEkf(EgoEkfConfig())
    assert isinstance(est, EgoEstimator)
    est.initialize(0.0, np.array([0.0, 0.0, 1.0]), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    for k in range(1, 201):
        t = k * 0.005
        est.predict_imu(t, np.array([0.0, 0.0, GRAVITY_MPS2]), np.zeros(3))
        if k % 5 == 0:
            assert est.update_odometry(t, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 0.0, 1.0]))
        assert_spd(est.covariance)
    s = est.state()
    assert s.is_finite() and s.t == pytest.approx(1.0)
    assert np.allclose(s.p_WB, [0, 0, 1], atol=1e-6)


def test_ego_config_refuses_unknown_parameters() -> None:
    with pytest.raises(TypeError):
        EgoEkfConfig(no_such_parameter=1.0)  # type: ignore[call-arg]


@pytest.mark.parametrize(
    "cls", [EgoEkfConfig, PlatformEkfConfig, SduKfConfig, PlatformVelocityConfig, KimUkfConfig]
)
def test_every_config_field_is_documented(cls: type) -> None:
    """Each field is followed by its docstring (unit and meaning), as the style asks."""
    tree = ast.parse(inspect.getsource(cls))
    body = tree.body[0].body  # type: ignore[attr-defined]
    undocumented = []
    for i, node in enumerate(body):
        if isinstance(node, ast.AnnAssign):
            nxt = body[i + 1] if i + 1 < len(body) else None
            if not (
                isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant)
                and isinstance(nxt.value.value, str)
            ):
                undocumented.append(node.target.id)  # type: ignore[union-attr]
    assert not undocumented


@pytest.mark.parametrize(
    ("cls", "bad"),
    [
        (EgoEkfConfig, {"gyro_noise_density": -1.0}),
        (EgoEkfConfig, {"odometry_position_std": 0.0}),
        (EgoEkfConfig, {"max_step": math.nan}),
        (PlatformEkfConfig, {"accel_noise": -0.1}),
        (PlatformEkfConfig, {"gate_probability": 1.0}),
        (PlatformEkfConfig, {"yaw_symmetry": 0}),
        (PlatformEkfConfig, {"init_min_span": 2.0, "init_max_span": 1.0}),
    ],
)
def test_configs_reject_invalid_values(cls: type, bad: dict) -> None:
    with pytest.raises(ValueError):
        cls(**bad)
