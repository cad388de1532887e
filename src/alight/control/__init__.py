"""Control: reference -> collective thrust + body rates (high level) -> torques (rate loop) -> rotor
thrusts (mixer). See ``README.md`` in this folder.

:data:`CONTROLLERS` (``control/registry.py``) is the controller stage's registry: name ->
:class:`alight.blockspec.BlockSpec` (parameters, factory from them and the airframe).
The low level (``low_level``) is a numba kernel on arrays that the simulator calls inside its physics
loop.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from alight.control.high_level import (
    HighLevelController,
    HighLevelGains,
    attitude_from_accel_yaw,
    body_rates_from_jerk,
    high_level_kernel,
    pack_high_level_params,
)
from alight.control.l1_adaptive import L1AugmentedController, L1Config
from alight.control.mixer import PriorityMixer, low_level, mix
from alight.control.rate import (
    BodyRateController,
    RateControllerGains,
    pack_low_level_params,
    rate_torque,
    tilt_time_constant_s,
)
from alight.control.registry import CONTROLLERS, ControllerParams, ControllerSpec
from alight.types import Command, EgoState, FloatArray, Reference


@runtime_checkable
class Controller(Protocol):
    """High level: ``command(ego, reference) -> Command`` (collective thrust in N, body rates in B)."""

    def command(self, ego: EgoState, ref: Reference) -> Command: ...

    def reset(self) -> None:
        """Forget internal state (integrators, adaptive estimates), e.g. at a mode change."""
        ...


@runtime_checkable
class TiltLimited(Protocol):
    """A controller whose tilt limit can be lowered in flight (PX4 does during its take-off ramp)."""

    def set_tilt_limit(self, max_tilt_rad: float | None) -> None:
        """Limit the commanded tilt to ``max_tilt_rad`` (rad, in (0, pi/2)); None: back to the
        controller's own limit."""
        ...


@runtime_checkable
class RateController(Protocol):
    """Body-rate loop: ``torque(w_cmd, w) -> torque_B`` (N m, shape (3,))."""

    def torque(self, w_cmd: FloatArray, w: FloatArray) -> FloatArray: ...


@runtime_checkable
class Mixer(Protocol):
    """Allocation with saturation: ``mix(thrust_N, torque_B) -> rotor thrusts`` (N, shape (4,))."""

    def mix(self, thrust_N: float, torque_B: FloatArray) -> FloatArray: ...


__all__ = [
    "CONTROLLERS",
    "BodyRateController",
    "Controller",
    "ControllerParams",
    "ControllerSpec",
    "HighLevelController",
    "HighLevelGains",
    "L1AugmentedController",
    "L1Config",
    "Mixer",
    "PriorityMixer",
    "RateController",
    "RateControllerGains",
    "attitude_from_accel_yaw",
    "body_rates_from_jerk",
    "high_level_kernel",
    "low_level",
    "mix",
    "pack_high_level_params",
    "pack_low_level_params",
    "rate_torque",
    "tilt_time_constant_s",
]
