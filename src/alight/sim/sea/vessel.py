"""Vessels as data: the packaged classes (``vessels/*.yaml`` beside this file) and user files.

A vessel is the handful of numbers the parametric response of :mod:`alight.sim.sea.response` needs:
the hull's footprint and draft (they filter the waves the hull averages over), the natural period and
damping ratio of heave, roll and pitch (each a second-order resonance), the share of the hull's kinematic
yaw its heading control leaves, and where its landing pad is by default. A file states each key either
as a bare number in the unit of the table or as ``{value, unit, source}``; the packaged files use the
second form with a source or a reason on every number. Any problem is one ConfigError line.

| key | unit | rule |
|---|---|---|
| ``length_m``, ``beam_m`` | m | > 0, beam <= length |
| ``draft_m`` | m | > 0, below the beam |
| ``heave_period_s``, ``roll_period_s``, ``pitch_period_s`` | s | in (0, 60] |
| ``heave_damping``, ``roll_damping``, ``pitch_damping`` | 1 | in (0, 2] (ratio to critical) |
| ``yaw_fraction`` | 1 | in [0, 1] |
| ``pad_offset_m`` | m | three numbers, FLU from the centre of motion, on the hull's footprint |

``name`` and ``description`` (text) are optional.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from alight.errors import ConfigError
from alight.yaml_io import data_file_error, read_yaml_file, unwrap_quantities

__all__ = ["UNITS", "Vessel", "load_vessel", "packaged_vessels", "read_vessel_file"]

UNITS: dict[str, str] = {
    "length_m": "m",
    "beam_m": "m",
    "draft_m": "m",
    "heave_period_s": "s",
    "roll_period_s": "s",
    "pitch_period_s": "s",
    "heave_damping": "1",
    "roll_damping": "1",
    "pitch_damping": "1",
    "yaw_fraction": "1",
    "pad_offset_m": "m",
}
"""The unit of each physical key of a vessel file."""


@dataclass(frozen=True, kw_only=True)
class Vessel:
    """A vessel's parameters for the parametric deck-motion model (SI units, FLU body axes)."""

    name: str
    length_m: float
    """Waterline length (m): the hull averages the waves over it."""
    beam_m: float
    """Waterline beam (m)."""
    draft_m: float
    """Mean draft (m): the wave pressure decays as exp(-k d) down to it."""
    heave_period_s: float
    roll_period_s: float
    pitch_period_s: float
    heave_damping: float
    """Damping ratio of the heave resonance (1)."""
    roll_damping: float
    pitch_damping: float
    yaw_fraction: float
    """Share of the hull's kinematic yaw (the wave's sideways displacement sloping along the hull) that
    the heading control leaves (1)."""
    pad_offset_m: tuple[float, float, float]
    """Default pad position, FLU from the centre of motion (m)."""


_Pos = Annotated[float, Field(gt=0, allow_inf_nan=False)]
_Period = Annotated[float, Field(gt=0, le=60, allow_inf_nan=False)]
_Damping = Annotated[float, Field(gt=0, le=2, allow_inf_nan=False)]
_Finite = Annotated[float, Field(allow_inf_nan=False)]


class VesselFile(BaseModel):
    """A vessel file after the ``{value, unit, source}`` wrappers are checked and removed."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str | None = None
    description: str | None = None
    length_m: _Pos
    beam_m: _Pos
    draft_m: _Pos
    heave_period_s: _Period
    roll_period_s: _Period
    pitch_period_s: _Period
    heave_damping: _Damping
    roll_damping: _Damping
    pitch_damping: _Damping
    yaw_fraction: Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]
    pad_offset_m: tuple[_Finite, _Finite, _Finite]

    @model_validator(mode="before")
    @classmethod
    def _unwrap(cls, data: Any) -> Any:
        """``key: {value: V, unit: U, source: S}`` -> ``key: V`` once U is the key's unit."""
        return unwrap_quantities(data, UNITS)

    @model_validator(mode="after")
    def _physical(self) -> VesselFile:
        if self.beam_m > self.length_m:
            raise ValueError(f"beam_m {self.beam_m} exceeds length_m {self.length_m}")
        if self.draft_m >= self.beam_m:
            raise ValueError(f"draft_m {self.draft_m} must be below beam_m {self.beam_m}")
        x, y, _ = self.pad_offset_m
        if abs(x) > self.length_m / 2 or abs(y) > self.beam_m / 2:
            raise ValueError(
                f"pad_offset_m {list(self.pad_offset_m)} is off the hull "
                f"(|x| <= {self.length_m / 2:g}, |y| <= {self.beam_m / 2:g})"
            )
        return self

    def vessel(self, name: str) -> Vessel:
        fields = self.model_dump(exclude={"name", "description"})
        return Vessel(name=self.name or name, **fields)


def read_vessel_file(path: str | Path) -> Vessel:
    """Read and validate a vessel YAML file."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"vessel {p}: no such file")
    data, _ = read_yaml_file(p, "vessel", source=f"vessel {p}")
    if not isinstance(data, dict):
        raise ConfigError(f"vessel {p}: expected a mapping of vessel keys, got {type(data).__name__}")
    try:
        return VesselFile.model_validate(data).vessel(p.stem)
    except ValidationError as err:
        raise ConfigError(data_file_error(f"vessel {p}", err)) from None


def _package_dir() -> Path:
    return Path(str(resources.files("alight.sim.sea") / "vessels"))


def packaged_vessels() -> list[str]:
    """Names of the vessel classes shipped with alight."""
    return sorted(p.stem for p in _package_dir().glob("*.yaml"))


@functools.lru_cache(maxsize=16)
def _packaged(name: str) -> Vessel:
    return read_vessel_file(_package_dir() / f"{name}.yaml")


def load_vessel(ref: str | Path) -> Vessel:
    """The Vessel that ``ref`` names: a packaged class (``small_usv``, ``patrol_boat``, ``frigate``) or a
    YAML file (anything with a path separator or a ``.yaml``/``.yml`` suffix)."""
    text = str(ref)
    if isinstance(ref, str) and text in packaged_vessels():
        return _packaged(text)
    if isinstance(ref, Path) or "/" in text or "\\" in text or text.endswith((".yaml", ".yml")):
        return read_vessel_file(text)
    raise ConfigError(
        f"unknown vessel '{text}': expected one of {packaged_vessels()} or a YAML file (*.yaml)"
    )
