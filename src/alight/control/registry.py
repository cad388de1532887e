"""The controller stage's registry: :data:`CONTROLLERS`, the high-level controllers a scenario's
``blocks.controller`` names, with their parameters and factories (:class:`alight.blockspec.BlockSpec`).
The build context is the vehicle's :class:`alight.airframe.Airframe`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from alight.airframe import Airframe
from alight.blockspec import BlockSpec
from alight.control.high_level import HighLevelController, HighLevelGains
from alight.control.l1_adaptive import L1AugmentedController, L1Config
from alight.control.rate import tilt_time_constant_s

if TYPE_CHECKING:
    from alight.control import Controller


@dataclass(frozen=True, kw_only=True)
class ControllerParams:
    """Paper 000's high-level controller (Faessler et al.), critically damped position loop."""

    position_bandwidth_rad_s: float = 3.0
    """Natural frequency of the position loop, critically damped (rad/s)."""
    integral_gain: float = 0.0
    """Integral gain on the position error per axis (1/s^3), as an autopilot's position loop has. Must be
    below kp * kv = 2 * bandwidth^3."""
    integral_limit_mps2: float = 6.0
    """Largest acceleration the integral may command per axis (m/s^2)."""

    def __post_init__(self) -> None:
        bw, ki = self.position_bandwidth_rad_s, self.integral_gain
        if not (math.isfinite(bw) and bw > 0):
            raise ValueError(f"position_bandwidth_rad_s must be finite and > 0, got {bw}")
        if not (math.isfinite(self.integral_limit_mps2) and self.integral_limit_mps2 > 0):
            raise ValueError(f"integral_limit_mps2 must be finite and > 0, got {self.integral_limit_mps2}")
        # Routh-Hurwitz of s^3 + kv s^2 + kp s + ki with kp = bw^2, kv = 2 bw (the controller's own check)
        if not (math.isfinite(ki) and 0.0 <= ki < 2.0 * bw**3):
            raise ValueError(
                f"integral_gain must satisfy 0 <= integral_gain < 2 * position_bandwidth_rad_s^3 = "
                f"{2.0 * bw**3:.3g} (a stable loop), got {ki}"
            )


def _faessler(p: ControllerParams, airframe: Airframe) -> HighLevelController:
    ki = p.integral_gain
    gains = HighLevelGains.from_bandwidth(
        p.position_bandwidth_rad_s,
        ki=(ki, ki, ki),
        integral_limit=p.integral_limit_mps2,
        tau_tilt=tilt_time_constant_s(airframe),
    )
    return HighLevelController(airframe, gains)


def _faessler_l1(p: ControllerParams, airframe: Airframe) -> Controller:
    return L1AugmentedController(_faessler(p, airframe), L1Config())


ControllerSpec = BlockSpec[Airframe, "Controller"]
"""A controller block: parameters and the airframe -> a high-level controller."""

CONTROLLERS: dict[str, ControllerSpec] = {
    "faessler": BlockSpec(
        "controller",
        "faessler",
        "paper 000's high-level controller (Faessler et al.)",
        ControllerParams,
        build=_faessler,
    ),
    "faessler_l1": BlockSpec(
        "controller",
        "faessler_l1",
        "the Faessler controller with paper 003's L1 adaptive augmentation of the outer loop",
        ControllerParams,
        build=_faessler_l1,
    ),
}
"""The controller stage's blocks by name."""

__all__ = ["CONTROLLERS", "ControllerParams", "ControllerSpec"]
