"""The planner stage's registry: :data:`PLANNERS`, the planners a scenario's ``blocks.planner`` names,
with their parameters and factories (:class:`alight.blockspec.BlockSpec`). The build context is the
vehicle's :class:`alight.airframe.Airframe`."""

from __future__ import annotations

import math
from dataclasses import dataclass

from alight.airframe import Airframe
from alight.blockspec import BlockSpec
from alight.planning.candidates import CandidatePlanner, PlannerConfig
from alight.planning.min_jerk import EndConstraint


@dataclass(frozen=True, kw_only=True)
class PlannerParams:
    """Paper 000's planner: minimum-jerk candidates to predicted platform states, the cheapest feasible."""

    n_candidates: int = 20
    horizon_min_s: float = 1.0
    horizon_max_s: float = 3.0
    rate_hz: float = 50.0
    """Replanning rate (Hz); the mission logic runs at the same rate."""
    adopt_threshold_m: float = 0.2
    end_acceleration: str = "platform"
    """Final acceleration of each candidate: ``free`` as in paper 000, or ``platform``, the platform's
    predicted acceleration (removes the lag of free-end plans behind a platform on a curve)."""

    def __post_init__(self) -> None:
        if not 1 <= self.n_candidates <= 10000:
            raise ValueError(f"n_candidates must be in [1, 10000], got {self.n_candidates}")
        for name, v in (
            ("horizon_min_s", self.horizon_min_s),
            ("horizon_max_s", self.horizon_max_s),
            ("rate_hz", self.rate_hz),
        ):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")
        if self.horizon_max_s < self.horizon_min_s:
            raise ValueError("horizon_max_s must be >= horizon_min_s")
        if not (math.isfinite(self.adopt_threshold_m) and self.adopt_threshold_m >= 0):
            raise ValueError(f"adopt_threshold_m must be finite and >= 0, got {self.adopt_threshold_m}")
        if self.end_acceleration not in ("free", "platform"):
            raise ValueError(f"end_acceleration must be 'free' or 'platform', got {self.end_acceleration!r}")


def _min_jerk_candidates(p: PlannerParams, airframe: Airframe) -> CandidatePlanner:
    return CandidatePlanner(
        PlannerConfig.from_airframe(
            airframe,
            n_candidates=p.n_candidates,
            horizon_min_s=p.horizon_min_s,
            horizon_max_s=p.horizon_max_s,
            adopt_threshold_m=p.adopt_threshold_m,
            end_constraint=EndConstraint.POS_VEL_ACC
            if p.end_acceleration == "platform"
            else EndConstraint.POS_VEL,
        )
    )


PlannerSpec = BlockSpec[Airframe, CandidatePlanner]
"""A planner block: parameters (with ``rate_hz``, the mission logic's rate) and the airframe -> a
planner."""

PLANNERS: dict[str, PlannerSpec] = {
    "min_jerk_candidates": BlockSpec(
        "planner",
        "min_jerk_candidates",
        "paper 000's minimum-jerk candidates to predicted platform states (Sec. II-D)",
        PlannerParams,
        build=_min_jerk_candidates,
    ),
}
"""The planner stage's blocks by name."""

__all__ = ["PLANNERS", "PlannerParams", "PlannerSpec"]
