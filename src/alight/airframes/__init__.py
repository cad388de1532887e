"""Airframes as data: the packaged vehicles (``*.yaml`` beside this file) and user files.

A scenario's ``airframe:`` names a packaged airframe (``f450``, the default, or ``matrice100``) or a
YAML file. A file states every physical field of :class:`alight.airframe.Airframe`, each either as a
bare number in the unit of the table below or as ``{value, unit, source}``; the packaged files use the
second form, with a source on every number. Any problem (an unknown key, a wrong unit, a non-physical
value, a thrust-to-weight ratio below 1.2) is one :class:`alight.errors.ConfigError` line.

| key | unit | rule |
|---|---|---|
| ``mass`` | kg | > 0 |
| ``inertia_diag`` | kg m^2 | three > 0, each at most the sum of the other two (a rigid body's) |
| ``arm_length`` | m | > 0 |
| ``thrust_to_weight`` | 1 | >= 1.2: below that nothing is left to manoeuvre or to hold against wind |
| ``motor_thrust_min_N`` | N | >= 0 and below the largest rotor thrust |
| ``motor_tau_up``, ``motor_tau_down`` | s | > 0 |
| ``torque_coefficient`` | m | > 0 |
| ``rotor_drag`` | 1/s | three >= 0 (mass-normalised, along the body axes) |
| ``body_drag_area_m2`` | m^2 | >= 0 |
| ``gear_height`` | m | >= 0 |
| ``gear_half_width`` | m | > 0 |
| ``max_body_rate`` | rad/s | > 0 |
| ``max_tilt_deg`` | deg | in [10, 80]: the controller's tilt limit (in degrees, as spec sheets give it) |

``name`` and ``description`` (text) are optional.
"""

from __future__ import annotations

import functools
import math
from importlib import resources
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from alight.airframe import Airframe
from alight.errors import ConfigError
from alight.types import GRAVITY_MPS2
from alight.yaml_io import data_file_error, read_yaml_file, unwrap_quantities

__all__ = ["MIN_THRUST_TO_WEIGHT", "UNITS", "load_airframe", "packaged_airframes", "read_airframe_file"]

MIN_THRUST_TO_WEIGHT = 1.2
"""Lowest thrust-to-weight ratio accepted: at 1.2 the vehicle tilts at most 34 deg at full thrust while
holding altitude, already too little for an 8 m/s wind on a small vehicle."""

UNITS: dict[str, str] = {
    "mass": "kg",
    "inertia_diag": "kg m^2",
    "arm_length": "m",
    "thrust_to_weight": "1",
    "motor_thrust_min_N": "N",
    "motor_tau_up": "s",
    "motor_tau_down": "s",
    "torque_coefficient": "m",
    "rotor_drag": "1/s",
    "body_drag_area_m2": "m^2",
    "gear_height": "m",
    "gear_half_width": "m",
    "max_body_rate": "rad/s",
    "max_tilt_deg": "deg",
}
"""The unit of each physical key of an airframe file."""

_Pos = Annotated[float, Field(gt=0, allow_inf_nan=False)]
_NonNeg = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class AirframeFile(BaseModel):
    """An airframe file after the ``{value, unit, source}`` wrappers are checked and removed."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str | None = None
    description: str | None = None
    mass: _Pos
    inertia_diag: tuple[_Pos, _Pos, _Pos]
    arm_length: _Pos
    thrust_to_weight: Annotated[float, Field(ge=MIN_THRUST_TO_WEIGHT, allow_inf_nan=False)]
    motor_thrust_min_N: _NonNeg
    motor_tau_up: _Pos
    motor_tau_down: _Pos
    torque_coefficient: _Pos
    rotor_drag: tuple[_NonNeg, _NonNeg, _NonNeg]
    body_drag_area_m2: _NonNeg
    gear_height: _NonNeg
    gear_half_width: _Pos
    max_body_rate: _Pos
    max_tilt_deg: Annotated[float, Field(ge=10, le=80, allow_inf_nan=False)]

    @model_validator(mode="before")
    @classmethod
    def _unwrap(cls, data: Any) -> Any:
        """``key: {value: V, unit: U, source: S}`` -> ``key: V`` once U is the key's unit."""
        return unwrap_quantities(data, UNITS)

    @model_validator(mode="after")
    def _physical(self) -> AirframeFile:
        j = sorted(self.inertia_diag)
        if j[2] > j[0] + j[1]:
            raise ValueError(
                f"inertia_diag {self.inertia_diag}: the largest moment exceeds the sum of the others "
                "(no rigid body has that)"
            )
        f_max = self.thrust_to_weight * self.mass * GRAVITY_MPS2 / 4.0
        if self.motor_thrust_min_N >= f_max:
            raise ValueError(
                f"motor_thrust_min_N {self.motor_thrust_min_N} must be below the largest rotor thrust "
                f"{f_max:.3f} N"
            )
        return self

    def airframe(self) -> Airframe:
        fields = self.model_dump(exclude={"name", "description", "max_tilt_deg"})
        # 45 deg is stored as radians(45) exactly, so the f450 file equals Airframe() bit for bit.
        return Airframe(**fields, max_tilt_rad=math.radians(self.max_tilt_deg))


def read_airframe_file(path: str | Path) -> AirframeFile:
    """Read and validate an airframe YAML file (the checked contents, before building the Airframe)."""
    p = Path(path)
    data, _ = read_yaml_file(p, "airframe", source=f"airframe {p}", allow_empty=True)
    if not isinstance(data, dict):
        raise ConfigError(f"airframe {p}: expected a mapping of airframe keys, got {type(data).__name__}")
    try:
        return AirframeFile.model_validate(data)
    except ValidationError as err:
        raise ConfigError(data_file_error(f"airframe {p}", err)) from None


def _package_dir() -> Path:
    return Path(str(resources.files(__name__)))


def packaged_airframes() -> list[str]:
    """Names of the airframes shipped with alight."""
    return sorted(p.stem for p in _package_dir().glob("*.yaml"))


@functools.lru_cache(maxsize=16)
def _packaged(name: str) -> Airframe:
    return read_airframe_file(_package_dir() / f"{name}.yaml").airframe()


def load_airframe(ref: str | Path) -> Airframe:
    """The Airframe that ``ref`` names: a packaged airframe (``f450``, ``matrice100``) or a YAML file.

    A packaged name wins over a file of the same name in the working directory; anything with a path
    separator or a ``.yaml``/``.yml`` suffix is a file (relative to the working directory)."""
    text = str(ref)
    if isinstance(ref, str) and text in packaged_airframes():
        return _packaged(text)
    if isinstance(ref, Path) or "/" in text or "\\" in text or text.endswith((".yaml", ".yml")):
        return read_airframe_file(text).airframe()
    raise ConfigError(
        f"unknown airframe '{text}': expected one of {packaged_airframes()} or a YAML file (*.yaml)"
    )
