"""Planning: the minimum-jerk motion primitive with its feasibility tests, the candidate planner of
paper 000 (Sec. II-D) and the exploration (coverage) route. :data:`PLANNERS` (``planning/registry.py``) is the
planner stage's registry. See README.md in this folder."""

from alight.planning.candidates import (
    CandidatePlanner,
    PlannerConfig,
    PlanResult,
    PlanStatus,
    sample_end_times,
)
from alight.planning.exploration import ExplorationRoute, footprint_width_m, lawnmower_waypoints
from alight.planning.min_jerk import (
    CandidateBatch,
    EndConstraint,
    InputFeasibility,
    MinJerkTrajectory,
    evaluate_candidates,
    floor_feasibility,
    input_feasibility,
    min_jerk_coefficients,
    min_jerk_cost,
)
from alight.planning.registry import PLANNERS, PlannerParams, PlannerSpec

__all__ = [
    "CandidateBatch",
    "CandidatePlanner",
    "EndConstraint",
    "ExplorationRoute",
    "InputFeasibility",
    "MinJerkTrajectory",
    "PLANNERS",
    "PlanResult",
    "PlanStatus",
    "PlannerConfig",
    "PlannerParams",
    "PlannerSpec",
    "evaluate_candidates",
    "floor_feasibility",
    "footprint_width_m",
    "input_feasibility",
    "lawnmower_waypoints",
    "min_jerk_coefficients",
    "min_jerk_cost",
    "sample_end_times",
]
