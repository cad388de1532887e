"""The rate loop's gain comes from the airframe's motor lag: the F450 keeps the defaults, a vehicle with
slower motors gets a gain whose loop through the motors keeps a damping of 0.6, and the tilt loop stays
three times slower than it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.airframes import load_airframe
from alight.control.rate import RATE_LOOP_DAMPING, RateControllerGains, rate_gain_limit, tilt_time_constant_s
from alight.mission.presets import build_preset
from alight.scenario import scenario_from_dict


def _damping(k: float, tau: float) -> float:
    """Damping of the closed loop w' = k (w_cmd - w) through a first-order motor of time constant tau:
    the roots of tau s^2 + s + k."""
    root = np.roots([tau, 1.0, k])[0]
    return float(-root.real / abs(root))


def test_the_f450_keeps_the_default_gains() -> None:
    f450 = load_airframe("f450")
    assert RateControllerGains.for_airframe(f450).k_rate == RateControllerGains().k_rate == (25.0, 25.0, 10.0)
    assert tilt_time_constant_s(f450) == 0.12
    # by hand: tau = (0.0125 + 0.025) / 2 = 0.01875 s allows 1 / (4 0.36 0.01875) = 37.0 1/s
    assert rate_gain_limit(f450) == pytest.approx(37.037, abs=1e-3)
    assert _damping(25.0, 0.01875) > RATE_LOOP_DAMPING


def test_slower_motors_get_a_gain_at_the_damping_limit() -> None:
    m100 = load_airframe("matrice100")
    tau = 0.5 * (m100.motor_tau_up + m100.motor_tau_down)
    assert tau == pytest.approx(0.0375)
    k = RateControllerGains.for_airframe(m100).k_rate
    # by hand: 1 / (4 0.36 0.0375) = 18.52 1/s, the yaw gain scaled alike: 10 x 18.52 / 25 = 7.41
    assert k == pytest.approx((18.5185, 18.5185, 7.4074), abs=1e-4)
    assert _damping(k[0], tau) == pytest.approx(RATE_LOOP_DAMPING, abs=1e-9)
    assert _damping(25.0, tau) < 0.55  # what the defaults gave: a ringing loop
    assert tilt_time_constant_s(m100) == pytest.approx(3.0 / k[0])


def test_the_preset_flies_the_airframes_gains() -> None:
    m100 = load_airframe("matrice100")
    s = scenario_from_dict({"preset": "alight", "seed": 1, "airframe": "matrice100"})
    preset = build_preset(s, m100, np.random.default_rng(0))
    assert preset.rate_gains == RateControllerGains.for_airframe(m100)
    controller = preset.pipeline.controller
    base = getattr(controller, "base", controller)
    assert base.gains.tau_tilt == pytest.approx(tilt_time_constant_s(m100))
    assert math.isfinite(base.gains.tau_tilt)
