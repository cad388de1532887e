"""``platform.sea``: the typed, validated settings of a deck at sea (every error one ConfigError line).

Both classes are settings dataclasses (``alight.settings``): the scenario's ``platform.sea`` section is
:class:`SeaConfig` itself, and its ``motion_telemetry`` is :class:`MotionTelemetryConfig`. Types are
checked by pydantic (strictly: ``"1.5"`` is no wave height); the cross-field rules below raise one
ConfigError line each.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import Field
from pydantic.dataclasses import dataclass as pydantic_dataclass

from alight.errors import ConfigError
from alight.settings import SETTINGS, NonNegFloat, RateHz
from alight.sim.sea.spectra import sea_state_hs_tp
from alight.sim.sea.vessel import Vessel, load_vessel
from alight.types import GRAVITY_MPS2

__all__ = ["MAX_STEEPNESS", "SPECTRA", "MotionTelemetryConfig", "SeaConfig"]

SPECTRA: tuple[str, ...] = ("jonswap", "pm")
MAX_STEEPNESS = 0.1
"""Largest significant steepness ``2 pi Hs / (g Tp^2)`` accepted: DNV-RP-C205 gives 1/15 as the limit of
measured seas at Tp <= 8 s, individual waves break at 1/7; beyond 1/10 a linear sea is no model at all."""


Number = Annotated[float, Field(strict=True)]
"""A float or an int, never a string or a boolean (strict: a quoted number in a scenario is a typo)."""


@pydantic_dataclass(frozen=True, kw_only=True, config=SETTINGS)
class MotionTelemetryConfig:
    """The vessel's motion reference unit (MRU) broadcast to the aircraft, as a ship's MRU sends it: the
    deck's roll and pitch and the heave rate at the pad (its monitoring point), at ``rate_hz``, after
    ``latency_s``, with white noise. [MODEL] defaults: a marine MRU's roll and pitch are good to a few
    hundredths of a degree, its heave rate to a few cm/s (``sim/sea/deck_sensors.py``)."""

    rate_hz: RateHz = 10.0
    """Messages per second (Hz)."""
    latency_s: Annotated[float, Field(ge=0, le=5.0, allow_inf_nan=False)] = 0.05
    """Delay from the sample to its arrival on the aircraft (s), at most 5."""
    attitude_noise_deg: NonNegFloat = 0.05
    """Standard deviation of the white noise on roll and pitch (deg)."""
    heave_rate_noise_mps: NonNegFloat = 0.03
    """Standard deviation of the white noise on the pad's heave rate (m/s)."""


@pydantic_dataclass(frozen=True, kw_only=True, config=SETTINGS)
class SeaConfig:
    """A deck that moves with the sea. ``sea_state`` (WMO code) gives Hs and Tp from the table of
    :mod:`alight.sim.sea.spectra` (``tp_s`` may replace its period, for fetch-limited water), or ``hs_m``
    and ``tp_s`` give them directly."""

    sea_state: Annotated[int, Field(strict=True)] | None = None
    """WMO sea-state code 0-9."""
    hs_m: Number | None = None
    """Significant wave height (m), in [0, 20]."""
    tp_s: Number | None = None
    """Modal (peak) period (s), in (0, 30]."""
    spectrum: str = "jonswap"
    """``"jonswap"`` or ``"pm"`` (Pierson-Moskowitz)."""
    gamma: Number | None = None
    """JONSWAP peak enhancement in [1, 7] (the observed range); None: 3.3."""
    wave_direction_deg: Number = 180.0
    """The waves' direction of travel relative to the vessel's heading (deg): 180 head seas, 90 beam seas
    (from starboard to port), 0 following seas."""
    vessel: str = "patrol_boat"
    """A packaged vessel class (``small_usv``, ``patrol_boat``, ``frigate``) or a vessel YAML file."""
    pad_offset_m: tuple[Number, Number, Number] | None = None
    """The pad's position on the vessel, FLU from the centre of motion (m); None: the vessel's own. The
    centre of motion is at the waterline, the sea's mean level z = 0 of the world."""
    motion_telemetry: MotionTelemetryConfig | None = None
    """The vessel broadcasts its motion reference unit's deck attitude and heave rate to the aircraft;
    None (default): no broadcast."""

    def __post_init__(self) -> None:
        if not self.vessel:
            raise ConfigError(f"platform.sea.vessel must name a vessel class or file, got {self.vessel!r}")
        if self.sea_state is None and self.hs_m is None:
            raise ConfigError("platform.sea needs sea_state or hs_m (with tp_s)")
        if self.sea_state is not None and self.hs_m is not None:
            raise ConfigError("platform.sea: give sea_state or hs_m, not both")
        if self.hs_m is not None:
            if self.tp_s is None:
                raise ConfigError("platform.sea: hs_m needs tp_s")
            if not (math.isfinite(self.hs_m) and 0.0 <= self.hs_m <= 20.0):
                raise ConfigError(f"platform.sea.hs_m must be in [0, 20] m, got {self.hs_m}")
        if self.tp_s is not None and not (math.isfinite(self.tp_s) and 0.0 < self.tp_s <= 30.0):
            raise ConfigError(f"platform.sea.tp_s must be in (0, 30] s, got {self.tp_s}")
        if self.spectrum not in SPECTRA:
            raise ConfigError(f"platform.sea.spectrum must be one of {list(SPECTRA)}, got {self.spectrum!r}")
        self._check_gamma()
        if not math.isfinite(self.wave_direction_deg):
            raise ConfigError(
                f"platform.sea.wave_direction_deg must be finite, got {self.wave_direction_deg}"
            )
        hs, tp = self.hs_tp()
        steep = 2.0 * math.pi * hs / (GRAVITY_MPS2 * tp**2)
        if steep > MAX_STEEPNESS:
            tp_min = math.sqrt(2.0 * math.pi * hs / (GRAVITY_MPS2 * MAX_STEEPNESS))
            raise ConfigError(
                f"platform.sea: Hs {hs:g} m at Tp {tp:g} s is steeper (2 pi Hs/(g Tp^2) = {steep:.3f}) than "
                f"any sea ({MAX_STEEPNESS}); give tp_s >= {tp_min:.2f} s"
            )
        self._check_pad(self.load_vessel())

    def _check_gamma(self) -> None:
        if self.gamma is None:
            return
        if self.spectrum == "pm" and self.gamma != 1.0:
            raise ConfigError(f"platform.sea: gamma {self.gamma} is JONSWAP's; Pierson-Moskowitz has none")
        if not (math.isfinite(self.gamma) and 1.0 <= self.gamma <= 7.0):
            raise ConfigError(f"platform.sea.gamma must be in [1, 7], got {self.gamma}")

    def _check_pad(self, vessel: Vessel) -> None:
        if self.pad_offset_m is None:
            return
        r = self.pad_offset_m
        if not all(math.isfinite(float(x)) for x in r):
            raise ConfigError(f"platform.sea.pad_offset_m must be three finite numbers, got {r!r}")
        if abs(r[0]) > vessel.length_m / 2 or abs(r[1]) > vessel.beam_m / 2:
            raise ConfigError(
                f"platform.sea.pad_offset_m {list(r)} is off the {vessel.name}'s hull "
                f"(|x| <= {vessel.length_m / 2:g}, |y| <= {vessel.beam_m / 2:g})"
            )

    def hs_tp(self) -> tuple[float, float]:
        """(significant wave height in m, modal period in s)."""
        if self.sea_state is not None:
            return sea_state_hs_tp(self.sea_state, self.tp_s)
        assert self.hs_m is not None and self.tp_s is not None  # checked in __post_init__
        return float(self.hs_m), float(self.tp_s)

    def load_vessel(self) -> Vessel:
        """The vessel the config names (packaged class or file)."""
        return load_vessel(self.vessel)
