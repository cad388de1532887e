"""Candidate sampling and minimum-cost pick (paper 000, Falanga et al. 2017, Sec. II-D and II-F.3).

At each control cycle the planner samples n end times t_k over a prediction horizon, takes the platform's
predicted state at each t_k as the final state of one minimum-jerk primitive (final acceleration free),
rejects the candidates that fail the input or the floor test, and keeps the feasible one of least cost J.
The new best replaces the plan being flown only if its end point differs significantly from the previous
plan's (Sec. II-F.3); the exact rule is in :meth:`CandidatePlanner.plan`.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import NDArray

from alight.airframe import DEFAULT_AIRFRAME, Airframe
from alight.errors import ConfigError
from alight.planning.min_jerk import (
    EndConstraint,
    MinJerkTrajectory,
    _evaluate_kernel,
    _pack_end,
)
from alight.types import FloatArray

__all__ = ["PlannerConfig", "PlanStatus", "PlanResult", "CandidatePlanner", "sample_end_times"]


def sample_end_times(
    t: float,
    n: int,
    horizon_min: float,
    horizon_max: float,
    rng: np.random.Generator | None = None,
) -> FloatArray:
    """n absolute end times (s), shape (n,), sampling the horizon [t + horizon_min, t + horizon_max].

    Without ``rng`` the samples are evenly spaced, ends included (deterministic, so that consecutive
    cycles produce comparable candidates and the hysteresis sees a stable best); with ``rng`` they are
    drawn uniformly at random and sorted.
    """
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if not (0.0 < horizon_min <= horizon_max and math.isfinite(horizon_max)):
        raise ValueError(f"need 0 < horizon_min <= horizon_max, got {horizon_min}, {horizon_max}")
    if rng is not None:
        return t + np.sort(rng.uniform(horizon_min, horizon_max, n))
    if n == 1:
        return np.array([t + 0.5 * (horizon_min + horizon_max)])
    return t + np.linspace(horizon_min, horizon_max, n)


@njit(cache=True)
def _plan_kernel(  # type: ignore[no-untyped-def]  # pragma: no cover
    p0, v0, a0, t, end_times, pf, vf, af, mode, limits, check_floor, floor_z, prev, prev_t_end,
    coef, costs, codes, floor_ok, best,
):  # fmt: skip
    """Validate, evaluate every candidate (one fused pass), pick the min-cost feasible one into ``best``
    (packed (9, 3)) and measure the hysteresis distance to the packed previous plan ``prev`` (ignored
    when ``prev_t_end`` is NaN). Returns (error, best index, feasible count, distance): error 1 for
    non-finite input, 2 for an end time not after t."""
    n = end_times.shape[0]
    T = np.empty(n)
    for k in range(3):
        if not (np.isfinite(p0[k]) and np.isfinite(v0[k]) and np.isfinite(a0[k])):
            return 1, -1, 0, np.nan
    for i in range(n):
        T[i] = end_times[i] - t
        if not np.isfinite(T[i]):
            return 1, -1, 0, np.nan
        if not T[i] > 0.0:
            return 2, -1, 0, np.nan
        for k in range(3):
            if not (np.isfinite(pf[i, k]) and np.isfinite(vf[i, k])):
                return 1, -1, 0, np.nan
    for i in range(af.shape[0]):
        for k in range(3):
            if not np.isfinite(af[i, k]):
                return 1, -1, 0, np.nan
    q = np.array([0.0, 0.0, floor_z])
    nrm = np.array([0.0, 0.0, 1.0])
    _evaluate_kernel(
        p0.reshape(1, 3), v0.reshape(1, 3), a0.reshape(1, 3), T, pf, vf, af, mode, limits, check_floor,
        q, nrm, coef[0], coef[1], coef[2], costs, codes, floor_ok,
    )  # fmt: skip
    b = -1
    nf = 0
    for i in range(n):
        if codes[i] == 0 and floor_ok[i]:
            nf += 1
            if b < 0 or costs[i] < costs[b]:
                b = i
    if b < 0:
        return 0, -1, 0, np.nan
    for k in range(3):
        best[0, k] = p0[k]
        best[1, k] = v0[k]
        best[2, k] = a0[k]
        best[3, k] = coef[0, b, k]
        best[4, k] = coef[1, b, k]
        best[5, k] = coef[2, b, k]
    _pack_end(best, T[b])
    dist = np.nan
    if np.isfinite(prev_t_end):
        # both plans continued straight past their ends (MinJerkTrajectory.sample) to a common time
        te = t + T[b]
        tc = max(te, prev_t_end)
        d2 = 0.0
        for k in range(3):
            dk = best[6, k] + best[7, k] * (tc - te) - prev[6, k] - prev[7, k] * (tc - prev_t_end)
            d2 += dk * dk
        dist = np.sqrt(d2)
    return 0, b, nf, dist


def _default_f_limits() -> tuple[float, float]:
    return DEFAULT_AIRFRAME.collective_accel_limits


@dataclass(frozen=True, kw_only=True)
class PlannerConfig:
    """Parameters of :class:`CandidatePlanner` (defaults: paper 000 and the default airframe)."""

    n_candidates: int = 20
    """Candidates per cycle (paper 000 Sec. III-D: 20)."""
    horizon_min_s: float = 1.0
    """Shortest candidate duration (s)."""
    horizon_max_s: float = 5.0
    """Longest candidate duration (s)."""
    f_min: float = field(default_factory=lambda: _default_f_limits()[0])
    """Lowest mass-normalised collective thrust (m/s^2)."""
    f_max: float = field(default_factory=lambda: _default_f_limits()[1])
    """Highest mass-normalised collective thrust (m/s^2)."""
    w_max: float = DEFAULT_AIRFRAME.max_body_rate
    """Bound on the body rates (rad/s), tested as |jerk| / f <= w_max."""
    min_section_s: float = 0.02
    """Resolution of the recursive input test (s)."""
    floor_z: float | None = 0.5
    """Height of the floor plane (m, normal +z); None switches the floor test off."""
    adopt_threshold_m: float = 0.2
    """A new best replaces the current plan only if their end points differ by at least this (m)."""
    end_constraint: EndConstraint = EndConstraint.POS_VEL
    """Final state fixed by each candidate; paper 000 fixes position and velocity, acceleration free."""

    def __post_init__(self) -> None:
        if self.n_candidates < 1:
            raise ConfigError(f"n_candidates must be >= 1, got {self.n_candidates}")
        if not (0.0 < self.horizon_min_s <= self.horizon_max_s < math.inf):
            raise ConfigError(
                f"need 0 < horizon_min_s <= horizon_max_s, got {self.horizon_min_s}, {self.horizon_max_s}"
            )
        if not (0.0 <= self.f_min < self.f_max < math.inf):
            raise ConfigError(f"need 0 <= f_min < f_max, got {self.f_min}, {self.f_max}")
        if not (0.0 < self.w_max < math.inf):
            raise ConfigError(f"w_max must be > 0, got {self.w_max}")
        if not (0.0 < self.min_section_s < math.inf):
            raise ConfigError(f"min_section_s must be > 0, got {self.min_section_s}")
        if self.floor_z is not None and not math.isfinite(self.floor_z):
            raise ConfigError(f"floor_z must be finite or None, got {self.floor_z}")
        if not (0.0 <= self.adopt_threshold_m < math.inf):
            raise ConfigError(f"adopt_threshold_m must be >= 0, got {self.adopt_threshold_m}")
        object.__setattr__(self, "end_constraint", EndConstraint(self.end_constraint))

    @classmethod
    def from_airframe(cls, airframe: Airframe, **overrides: object) -> PlannerConfig:
        """Thrust and rate limits from ``airframe``; other fields from ``overrides`` or the defaults."""
        f_min, f_max = airframe.collective_accel_limits
        kw: dict[str, object] = {"f_min": f_min, "f_max": f_max, "w_max": airframe.max_body_rate}
        kw.update(overrides)
        return cls(**kw)  # type: ignore[arg-type]


class PlanStatus(enum.StrEnum):
    """What :meth:`CandidatePlanner.plan` did with the plan being flown."""

    ADOPTED = "adopted"
    """The new best candidate replaced the plan (or there was none)."""
    KEPT_SIMILAR = "kept_similar"
    """The new best ends too close to the current plan's end: the current plan is kept."""
    NO_FEASIBLE = "no_feasible"
    """No candidate passed both tests: the current plan (possibly None) is kept."""


@dataclass(frozen=True)
class PlanResult:
    """Outcome of one planning cycle."""

    trajectory: MinJerkTrajectory | None
    """The plan to fly: the new best when adopted, else the previous plan (None if there never was one)."""
    adopted: bool
    """True when ``trajectory`` is this cycle's new best."""
    status: PlanStatus
    """Why ``trajectory`` is what it is."""
    n_feasible: int
    """Candidates that passed the input test (FEASIBLE only) and the floor test."""
    costs: FloatArray
    """J of every candidate (m^2/s^6), (n,)."""
    codes: NDArray[np.int64]
    """:class:`InputFeasibility` code of every candidate, (n,) int64."""
    floor_ok: NDArray[np.bool_]
    """Floor test of every candidate, (n,) bool."""
    best_index: int
    """Index of this cycle's min-cost feasible candidate, -1 if none."""
    best: MinJerkTrajectory | None
    """This cycle's min-cost feasible candidate, adopted or not."""
    end_distance_m: float
    """The end-point distance the hysteresis compared (m); NaN when there was nothing to compare."""


class CandidatePlanner:
    """Paper 000's planner: n minimum-jerk candidates to predicted platform states, min-cost feasible pick,
    hysteresis on the end point. Stateful only through the plan being flown (:meth:`reset` forgets it)."""

    def __init__(self, config: PlannerConfig | None = None) -> None:
        self.config = config if config is not None else PlannerConfig()
        c = self.config
        self._limits = np.array([c.f_min, c.f_max, c.w_max, c.min_section_s])
        self._zero_af = np.zeros((1, 3))
        self._zero_packed = np.zeros((9, 3))
        # read-only like every trajectory's _packed, which takes its place once there is a plan: one
        # compiled signature of _plan_kernel for both
        self._zero_packed.flags.writeable = False
        self._previous: MinJerkTrajectory | None = None

    @property
    def previous(self) -> MinJerkTrajectory | None:
        """The plan being flown (the last adopted one), or None."""
        return self._previous

    def reset(self) -> None:
        """Forget the plan being flown (call it when the mission changes mode)."""
        self._previous = None

    def plan(
        self,
        t: float,
        p0: FloatArray,
        v0: FloatArray,
        a0: FloatArray,
        end_times: FloatArray,
        p_end: FloatArray,
        v_end: FloatArray,
        floor_z: float | None = None,
        a_end: FloatArray | None = None,
    ) -> PlanResult:
        """Plan from the state (p0, v0, a0) at time t to the n end states (all in W).

        Args:
            t: current time (s).
            p0, v0, a0: current position (m), velocity (m/s), acceleration (m/s^2), each (3,).
            end_times: absolute end times (s), (n,), each > t (see :func:`sample_end_times`).
            p_end, v_end: final positions (m) and velocities (m/s), (n, 3): the platform's predicted
                states at ``end_times`` (plus the hover offset above the pad, which is the caller's).
            floor_z: floor height (m) for this call; None uses ``config.floor_z``.
            a_end: final accelerations (m/s^2), (3,) or (n, 3); only used with ``EndConstraint.POS_VEL_ACC``.

        Hysteresis rule (paper 000 Sec. II-F.3, "executed only if the final position of the two
        trajectories differ significantly"): the two plans are compared where both are defined at the same
        absolute time, t_c = max(end of new best, end of current plan), using each plan's documented
        continuation past its end (straight at its final velocity). Both end states are predictions of the
        same moving platform, so comparing them at one time separates a changed prediction from a mere
        shift of the end time along the platform's path. The current plan is kept when
        ``|new(t_c).p - current(t_c).p| < adopt_threshold_m``.
        """
        c = self.config
        P0, V0, A0, te, PF, VF, AF = self._arrays(p0, v0, a0, end_times, p_end, v_end, a_end)
        n = te.shape[0]
        fz = c.floor_z if floor_z is None else float(floor_z)
        prev = self._previous
        coef = np.empty((3, n, 3))
        costs = np.empty(n)
        codes = np.empty(n, dtype=np.int64)
        floor_ok = np.empty(n, dtype=np.bool_)
        packed = np.empty((9, 3))
        err, b, n_feasible, dist = _plan_kernel(
            P0, V0, A0, float(t), te, PF, VF, AF, int(c.end_constraint), self._limits, fz is not None,
            0.0 if fz is None else fz, self._zero_packed if prev is None else prev._packed,
            math.nan if prev is None else prev.t_end, coef, costs, codes, floor_ok, packed,
        )  # fmt: skip
        if err == 1:
            raise ValueError("the state, end times and end states must be finite")
        if err == 2:
            raise ValueError("every end time must be later than t")
        if b < 0:
            return PlanResult(
                prev, False, PlanStatus.NO_FEASIBLE, 0, costs, codes, floor_ok, -1, None, math.nan
            )
        t0 = float(t)
        best = MinJerkTrajectory._from_packed(t0, float(te[b]) - t0, packed)
        if prev is not None and dist < c.adopt_threshold_m:
            return PlanResult(
                prev, False, PlanStatus.KEPT_SIMILAR, n_feasible, costs, codes, floor_ok, b, best, dist
            )
        self._previous = best
        return PlanResult(best, True, PlanStatus.ADOPTED, n_feasible, costs, codes, floor_ok, b, best, dist)

    def _arrays(
        self,
        p0: FloatArray,
        v0: FloatArray,
        a0: FloatArray,
        end_times: FloatArray,
        p_end: FloatArray,
        v_end: FloatArray,
        a_end: FloatArray | None,
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """:meth:`plan`'s inputs as contiguous float64 arrays, their shapes checked (ValueError)."""
        # Fresh writable copies (3 floats each): numba compiles one signature per read-only flag, and the
        # state arrives read-only (a frozen EgoState) or writable depending on the caller; always writable
        # keeps _plan_kernel (and the kernels it calls) to one compiled signature instead of three.
        P0 = np.array(p0, dtype=np.float64)
        V0 = np.array(v0, dtype=np.float64)
        A0 = np.array(a0, dtype=np.float64)
        te = np.ascontiguousarray(end_times, dtype=np.float64)
        PF = np.ascontiguousarray(p_end, dtype=np.float64)
        VF = np.ascontiguousarray(v_end, dtype=np.float64)
        n = te.shape[0] if te.ndim == 1 else 0
        if P0.shape != (3,) or V0.shape != (3,) or A0.shape != (3,):
            raise ValueError(f"p0, v0, a0 must have shape (3,), got {P0.shape}, {V0.shape}, {A0.shape}")
        if n == 0 or PF.shape != (n, 3) or VF.shape != (n, 3):
            raise ValueError(
                f"need end_times (n,), p_end and v_end (n, 3); got {te.shape}, {PF.shape}, {VF.shape}"
            )
        if a_end is None:
            AF = self._zero_af
        else:
            AF = np.ascontiguousarray(a_end, dtype=np.float64).reshape(-1, 3)
            if AF.shape[0] not in (1, n):
                raise ValueError(f"a_end must have shape (3,) or ({n}, 3)")
        return P0, V0, A0, te, PF, VF, AF
