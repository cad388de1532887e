"""The mission state machine of paper 000 Sec. II-F (Fig. 6), with the failsafes a real mission needs.

Paper 000 has four states: takeoff, exploration, platform tracking, landing. We add:

- ``LANDED``: the motors are stopped (paper: "the vehicle stops the motors when the distance to the
  platform is below a given threshold").
- ``GO_AROUND``: the target was lost, or the vehicle drifted off the pad, during the descent; climb back
  to the tracking height while following the last estimate, then track again.
- ``ABORT``: too many go-arounds, or the mission's time budget is spent; hold position at the exploration
  altitude (a real vehicle would return home). The runner reports the mission as ``aborted``.
- Tracking falls back to exploration when the target has not been seen for ``lost_timeout_s``.

The machine is a pure function of its inputs and its own small memory; what each mode flies is the
guidance's business (``mission/guidance.py``). Every transition is listed in ``TRANSITIONS`` and the
tests walk the whole table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from alight.types import EgoState, Mode, PlatformEstimate


@dataclass(frozen=True, kw_only=True)
class MissionConfig:
    """Parameters of the mission logic. Heights are above the surface they refer to."""

    takeoff_altitude_m: float = 4.0
    """Hover height reached after take-off, above the take-off point (m)."""
    explore_altitude_m: float = 12.0
    """Altitude of the coverage pattern (m)."""
    track_height_m: float = 2.5
    """Height above the pad while tracking, before the descent (m)."""
    land_speed_mps: float = 0.4
    """Vertical speed of the descent (m/s)."""
    hover_tolerance_m: float = 0.3
    """Take-off is done when within this height of the hover point ... (m)."""
    hover_speed_tolerance_mps: float = 0.3
    """... and slower than this (m/s)."""
    land_position_tolerance_m: float = 0.25
    """Landing starts when the horizontal offset to the pad is below this (m) ..."""
    land_velocity_tolerance_mps: float = 0.3
    """... and the horizontal velocity matches the platform's within this (m/s) ..."""
    land_dwell_s: float = 0.3
    """... for at least this long (s)."""
    max_estimate_age_s: float = 0.6
    """An estimate older than this does not start a landing (s)."""
    lost_timeout_s: float = 3.0
    """Tracking gives up and explores again when the target is unseen this long (s)."""
    land_lost_timeout_s: float = 1.0
    """The descent is abandoned (go-around) when the target is unseen this long (s)."""
    land_abort_offset_m: float = 0.6
    """The descent is abandoned when the horizontal offset to the pad exceeds this (m) ..."""
    land_abort_min_height_m: float = 0.4
    """... while still higher than this above the pad (below it, committing is safer) (m)."""
    land_commit_height_m: float = 1.5
    """Below this height above the pad a lost target no longer aborts the descent: a downward camera
    cannot see the whole pad from closer than about its own size, so the last metre is flown on the
    platform estimator's prediction (paper 000's reason for the model-based filter) (m)."""
    motor_cutoff_range_m: float = 0.03
    """The motors stop when the range finder (from the landing-gear feet) reads below this (m)."""
    max_go_arounds: int = 3
    """After this many go-arounds the mission aborts."""
    time_budget_s: float | None = None
    """Abort when the mission has run this long without landing (s); None for no budget."""

    def __post_init__(self) -> None:
        positive = (
            "takeoff_altitude_m",
            "explore_altitude_m",
            "track_height_m",
            "land_speed_mps",
            "land_position_tolerance_m",
            "land_velocity_tolerance_mps",
            "lost_timeout_s",
            "land_lost_timeout_s",
            "motor_cutoff_range_m",
        )
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"mission.{name} must be positive, got {value}")
        if self.max_go_arounds < 0:
            raise ValueError("mission.max_go_arounds must be >= 0")


# Every transition the machine can make: (from, to, event). The tests walk this table.
TRANSITIONS: tuple[tuple[Mode, Mode, str], ...] = (
    (Mode.IDLE, Mode.TAKEOFF, "mission started"),
    (Mode.TAKEOFF, Mode.EXPLORE, "hover reached, no target yet"),
    (Mode.TAKEOFF, Mode.TRACK, "hover reached, target already seen"),
    (Mode.TAKEOFF, Mode.TRACK, "target seen above the tracking height"),
    (Mode.EXPLORE, Mode.TRACK, "target detected"),
    (Mode.TRACK, Mode.LAND, "above the platform with matched velocity"),
    (Mode.TRACK, Mode.EXPLORE, "target lost"),
    (Mode.LAND, Mode.LANDED, "range below the motor cut-off"),
    (Mode.LAND, Mode.GO_AROUND, "target lost or off the pad during the descent"),
    (Mode.GO_AROUND, Mode.TRACK, "tracking height regained"),
    (Mode.GO_AROUND, Mode.ABORT, "too many go-arounds"),
    (Mode.EXPLORE, Mode.ABORT, "time budget spent"),
    (Mode.TRACK, Mode.ABORT, "time budget spent"),
    (Mode.LAND, Mode.ABORT, "time budget spent"),
)


@dataclass(frozen=True, slots=True)
class MissionStatus:
    mode: Mode
    changed: bool
    """True when this step changed the mode."""
    reason: str
    """The event that caused the last transition."""
    mode_since: float
    """Time at which the current mode was entered (s)."""


class Mission:
    """Decides the mode from the ego estimate, the platform estimate and the range finder."""

    def __init__(self, config: MissionConfig | None = None) -> None:
        self.config = config or MissionConfig()
        self.reset()

    def reset(self) -> None:
        self.mode = Mode.IDLE
        self.mode_since = 0.0
        self.reason = ""
        self.go_arounds = 0
        self._t_start: float | None = None
        self._matched_since: float | None = None
        self.takeoff_point_W = np.zeros(3)
        self.history: list[tuple[float, Mode, str]] = []

    # -- helpers ---------------------------------------------------------------------------------
    def _go(self, t: float, mode: Mode, reason: str) -> None:
        self.mode, self.mode_since, self.reason = mode, t, reason
        self._matched_since = None
        self.history.append((t, mode, reason))

    @staticmethod
    def _age(t: float, target: PlatformEstimate | None) -> float:
        return math.inf if target is None else t - target.t_last_measurement

    def hover_point_W(self) -> np.ndarray:
        return self.takeoff_point_W + np.array([0.0, 0.0, self.config.takeoff_altitude_m])

    # -- the step ----------------------------------------------------------------------------------
    def step(
        self, t: float, ego: EgoState, target: PlatformEstimate | None, range_m: float | None
    ) -> MissionStatus:
        """Advance the machine to time ``t``. ``target`` is the platform estimate at ``t`` (None before
        the first detection); ``range_m`` is the range finder's reading from the feet, None when invalid."""
        cfg = self.config
        before = self.mode
        if self.mode is Mode.IDLE:
            self._t_start = t
            self.takeoff_point_W = ego.p_WB.copy()
            self._go(t, Mode.TAKEOFF, "mission started")
            return MissionStatus(self.mode, True, self.reason, self.mode_since)

        age = self._age(t, target)
        over_budget = (
            cfg.time_budget_s is not None
            and self._t_start is not None
            and t - self._t_start > cfg.time_budget_s
        )
        mode = self.mode

        if mode is Mode.TAKEOFF:
            # Done at the hover altitude once steady. A horizontal offset (wind holding the vehicle off
            # the take-off point) is the position loop's to remove, not a reason to stay in take-off.
            offset = abs(float(ego.p_WB[2] - self.hover_point_W()[2]))
            speed = float(np.linalg.norm(ego.v_WB))
            height = float(ego.p_WB[2] - self.takeoff_point_W[2])
            if target is not None and age < cfg.lost_timeout_s and height >= cfg.track_height_m:
                # a platform seen during the climb is followed at once: it moves on while we climb
                self._go(t, Mode.TRACK, "target seen above the tracking height")
            elif offset < cfg.hover_tolerance_m and speed < cfg.hover_speed_tolerance_mps:
                if target is not None and age < cfg.lost_timeout_s:
                    self._go(t, Mode.TRACK, "hover reached, target already seen")
                else:
                    self._go(t, Mode.EXPLORE, "hover reached, no target yet")

        elif mode is Mode.EXPLORE:
            if over_budget:
                self._go(t, Mode.ABORT, "time budget spent")
            elif target is not None and age < cfg.lost_timeout_s:
                self._go(t, Mode.TRACK, "target detected")

        elif mode is Mode.TRACK:
            if over_budget:
                self._go(t, Mode.ABORT, "time budget spent")
            elif target is None or age > cfg.lost_timeout_s:
                self._go(t, Mode.EXPLORE, "target lost")
            else:
                dp = float(np.linalg.norm(ego.p_WB[:2] - target.p_WP[:2]))
                dv = float(np.linalg.norm(ego.v_WB[:2] - target.v_WP[:2]))
                matched = (
                    dp < cfg.land_position_tolerance_m
                    and dv < cfg.land_velocity_tolerance_mps
                    and age < cfg.max_estimate_age_s
                )
                if not matched:
                    self._matched_since = None
                elif self._matched_since is None:
                    self._matched_since = t
                if self._matched_since is not None and t - self._matched_since >= cfg.land_dwell_s:
                    self._go(t, Mode.LAND, "above the platform with matched velocity")

        elif mode is Mode.LAND:
            height = None if target is None else float(ego.p_WB[2] - target.p_WP[2])
            if range_m is not None and math.isfinite(range_m) and range_m < cfg.motor_cutoff_range_m:
                self._go(t, Mode.LANDED, "range below the motor cut-off")
            elif over_budget:
                self._go(t, Mode.ABORT, "time budget spent")
            elif target is None or (
                age > cfg.land_lost_timeout_s and (height is None or height > cfg.land_commit_height_m)
            ):
                self._go_around(t, "target lost during the descent")
            else:
                dp = float(np.linalg.norm(ego.p_WB[:2] - target.p_WP[:2]))
                if (
                    dp > cfg.land_abort_offset_m
                    and height is not None
                    and height > cfg.land_abort_min_height_m
                ):
                    self._go_around(t, "off the pad during the descent")

        elif mode is Mode.GO_AROUND:
            if self.go_arounds > cfg.max_go_arounds:
                self._go(t, Mode.ABORT, "too many go-arounds")
            elif target is not None:
                height = float(ego.p_WB[2] - target.p_WP[2])
                if height > cfg.track_height_m - cfg.hover_tolerance_m:
                    self._go(t, Mode.TRACK, "tracking height regained")
            elif ego.p_WB[2] > cfg.explore_altitude_m - cfg.hover_tolerance_m:
                self._go(t, Mode.TRACK, "tracking height regained")

        # LANDED and ABORT are final.
        return MissionStatus(self.mode, self.mode is not before, self.reason, self.mode_since)

    def _go_around(self, t: float, reason: str) -> None:
        self.go_arounds += 1
        self._go(t, Mode.GO_AROUND, reason)
