"""The typed mission result: the one list of what a mission reports in a campaign's ``results.csv``.

:class:`MissionResult` is the single source of the results.csv result columns (``alight.campaign.store``
derives its header from :meth:`MissionResult.columns`), of the column list in ``docs/campaigns.md`` (a
test checks they agree) and of the keys ``result.json`` must carry (the runner's result is read back
through :meth:`MissionResult.from_result`, which fails on a missing key).
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from alight.types import PIPELINE_BLOCKS

OUTCOMES = ("landed", "crashed", "timeout", "aborted", "error")
"""Every value of :attr:`MissionResult.outcome`."""

_SEA_ONLY = {"only": "sea"}
"""Metadata of the fields only a mission on a vessel at sea reports (``platform.sea``): result.json
carries them then, and results.csv leaves them empty for every other mission."""


@dataclass(frozen=True, kw_only=True)
class MissionResult:
    """One mission's figures, as results.csv holds them (``None``: no value, an empty cell)."""

    outcome: str
    """``landed``, ``crashed``, ``timeout``, ``aborted`` or ``error``."""
    success: bool
    """True when landed."""
    touchdown_error_m: float | None = None
    """Horizontal distance vehicle centre - pad centre at first contact (m)."""
    touchdown_rel_speed_mps: float | None = None
    """Speed relative to the pad at first contact (m/s)."""
    touchdown_rel_vertical_speed_mps: float | None = None
    """Vertical speed relative to the pad at first contact (m/s)."""
    time_to_land_s: float | None = None
    """Simulated time of the touchdown of a landed mission (s)."""
    time_first_detection_s: float | None = None
    """Capture time of the first accepted measurement (s)."""
    energy_flight_J: float | None = None
    """Electrical energy of the rotors over the flight (J)."""
    energy_compute_J: float | None = None
    """Compute energy of the detector on its device profile (J), when the preset has a model."""
    detections: int | None = None
    """Measurements the platform estimator accepted."""
    go_arounds: int | None = None
    """Landing attempts given up and restarted."""
    platform_estimate_rmse_m: float | None = None
    """RMS error of the platform position estimate while it had one (m)."""
    false_detections: int | None = None
    """Accepted measurements farther than the false-detection radius from the pad."""
    false_lock: bool | None = None
    """The estimate followed something else than the pad for longer than the false-lock time."""
    block_time_s: Mapping[str, float | None] = field(default_factory=dict)
    """Wall time spent in each pipeline block (s), a column ``<block>_time_s`` each."""
    simulated_time_s: float | None = None
    """Simulated time at the end of the mission (s)."""
    wall_time_s: float | None = None
    """Wall time of the flight (s); for an error, the time until the error."""
    touchdown_rel_horizontal_speed_mps: float | None = None
    """Horizontal speed relative to the touched surface at first contact (m/s): the contact judge's
    ``max_horizontal_speed_mps`` (0.75) is its limit."""
    touchdown_platform_speed_mps: float | None = None
    """The platform's horizontal speed at first contact (m/s)."""
    touchdown_platform_turn_rate_rad_s: float | None = None
    """The platform's heading rate at first contact (rad/s, counter-clockwise positive): with the speed,
    its centripetal acceleration is their product."""
    error: str | None = None
    """One line saying what went wrong, for ``outcome: error``."""
    deck_touchdown_error_m: float | None = field(default=None, metadata=_SEA_ONLY)
    """At sea: distance from the pad centre at first contact in the deck's plane (m)."""
    deck_normal_speed_mps: float | None = field(default=None, metadata=_SEA_ONLY)
    """At sea: speed relative to the deck under the vehicle along the deck's normal at first contact (m/s)."""
    deck_tangential_speed_mps: float | None = field(default=None, metadata=_SEA_ONLY)
    """At sea: that relative speed across the deck's normal, in the deck's plane (m/s)."""
    deck_relative_tilt_deg: float | None = field(default=None, metadata=_SEA_ONLY)
    """At sea: angle between the vehicle's z axis and the deck's normal at first contact (deg)."""
    deck_tilt_deg: float | None = field(default=None, metadata=_SEA_ONLY)
    """At sea: the deck's own tilt from the horizontal at first contact (deg)."""

    def __post_init__(self) -> None:
        if self.outcome not in OUTCOMES:
            raise ValueError(f"outcome must be one of {OUTCOMES}, got {self.outcome!r}")

    @staticmethod
    def columns() -> tuple[str, ...]:
        """The results.csv result columns, in order (``block_time_s`` expands to one per block; ``error``
        is the campaign's last column, after ``mission_dir``, and not in here)."""
        out: list[str] = []
        for f in dataclasses.fields(MissionResult):
            if f.name == "block_time_s":
                out += [f"{b}_time_s" for b in PIPELINE_BLOCKS]
            elif f.name != "error":
                out.append(f.name)
        return tuple(out)

    @staticmethod
    def numeric_columns() -> tuple[str, ...]:
        """The columns holding numbers (not flags or text)."""
        hints = typing.get_type_hints(MissionResult)
        out: list[str] = []
        for f in dataclasses.fields(MissionResult):
            if f.name == "block_time_s":
                out += [f"{b}_time_s" for b in PIPELINE_BLOCKS]
                continue
            args = set(typing.get_args(hints[f.name])) or {hints[f.name]}
            if args & {float, int} and bool not in args:
                out.append(f.name)
        return tuple(out)

    @classmethod
    def from_result(cls, result: Mapping[str, Any], *, strict: bool = True) -> MissionResult:
        """From a ``result.json`` mapping. ``strict``: every field must be present (the runner's result
        carries them all, but the deck's figures only at sea); otherwise a missing one is None."""
        kw: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            if f.name == "error":
                kw["error"] = result.get("error")
                continue
            if f.name not in result:
                if strict and f.metadata != _SEA_ONLY:
                    raise KeyError(f"result has no {f.name!r}")
                continue
            kw[f.name] = result[f.name]
        if "success" not in kw:
            kw["success"] = kw.get("outcome") == "landed"
        blocks = kw.get("block_time_s")
        kw["block_time_s"] = dict(blocks) if isinstance(blocks, Mapping) else {}
        return cls(**kw)

    def row(self) -> dict[str, Any]:
        """The results.csv cells of :meth:`columns` (and ``error``)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            if f.name == "block_time_s":
                out.update({f"{b}_time_s": self.block_time_s.get(b) for b in PIPELINE_BLOCKS})
            else:
                out[f.name] = getattr(self, f.name)
        return out


SCENARIO_YAML = "scenario.yaml"
"""In every mission directory (``alight fly`` and campaigns): the mission's whole scenario;
``alight fly DIR/scenario.yaml`` flies it again."""


def write_scenario_yaml(path: Path, scenario: Mapping[str, Any]) -> None:
    """A scenario file that flies the mission again (``alight fly path``)."""
    import json

    import yaml

    text = "# The whole scenario of this mission: alight fly scenario.yaml --out DIR flies it again.\n"
    path.write_text(text + yaml.safe_dump(json.loads(json.dumps(dict(scenario))), sort_keys=False), "utf-8")


__all__ = ["OUTCOMES", "SCENARIO_YAML", "MissionResult", "write_scenario_yaml"]
