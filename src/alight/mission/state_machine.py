"""The mission state machine of paper 000 Sec. II-F (Fig. 6), with the failsafes a real mission needs,
all relative to the moving platform.

Paper 000 has four states: takeoff, exploration, platform tracking, landing. We add:

- ``SEARCH``: the target was lost while tracking. TRACK first *coasts* on the platform estimator's
  prediction for ``lost_timeout_s`` (the guidance keeps following the predicted platform and climbs to
  widen the view); then SEARCH flies a spiral centred on the *predicted* platform position whose radius
  grows with the prediction's uncertainty (mission/guidance.py), for ``search_timeout_s``; only then does
  the mission fall back to covering the whole area (EXPLORE).
- ``LANDED``: the onboard land detector (mission/touchdown_detector.py) decided the vehicle stands on the
  deck; the motors are stopped.
- ``GO_AROUND``: during the descent, above the commit height, a descent gate failed (target unseen too
  long, horizontal offset, relative velocity, estimator consistency): climb back to the tracking height
  above the predicted platform while following it, then track again. Below ``land_commit_height_m`` the
  descent continues on the prediction (a downward camera cannot see the whole pad from closer than about
  its size), for at most ``land_commit_timeout_s`` and while the range finder does not see the ground
  beside the deck (``land_commit_ground_margin_m``) and, on a vehicle with an optical-flow module, while
  the deck under the feet moves as the platform estimate says (``land_commit_deck_velocity_error_mps``),
  when those are set; while a gate is only marginal the descent holds its height (``descent_hold``).
- ``ABORT``: the take-off did not finish in time, too many go-arounds or target losses, or the time
  budget is spent. In a descent, the abort comes at the end of a go-around, at the tracking height: the
  final action never starts just over a moving deck. ABORT performs the ``final_action``:
  ``hover`` (climb to the exploration altitude and hold), ``return`` (fly to the take-off point at the
  exploration altitude and land there) or ``land_in_place``; ``final_action_complete`` says when it is
  done (hovering steadily at the hold point for ``abort_hover_s``, or touchdown detected on board).

Every failsafe is recorded in ``events`` (time, kind, reason), and the abort's reason in
``abort_reason``. The machine is a pure function of its inputs and its own small memory; what each mode
flies is the guidance's business (``mission/guidance.py``). Every transition is listed in ``TRANSITIONS``
and the tests walk the whole table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field
from pydantic.dataclasses import dataclass as pydantic_dataclass

from alight.mission.touchdown_detector import TouchdownConfig
from alight.settings import SETTINGS, Altitude, Duration, NonNegFloat, PositiveFloat
from alight.types import EgoState, FloatArray, Mode, PlatformEstimate

if TYPE_CHECKING:
    from alight.mission.quiet_window import QuietWindowGate

FinalAction = Literal["hover", "return", "land_in_place"]
FINAL_ACTIONS: tuple[str, ...] = ("hover", "return", "land_in_place")
Tilt = Annotated[float, Field(gt=0, lt=1.5, allow_inf_nan=False)]
"""A tilt limit (rad), short of 1.5 (86 deg): a limit at or past the horizontal is a typo."""


@pydantic_dataclass(frozen=True, kw_only=True, config=SETTINGS)
class MissionConfig:
    """Parameters of the mission logic. Heights are above the surface they refer to. These are the
    defaults of every preset (a scenario's ``mission:`` key left out or None keeps them)."""

    takeoff_altitude_m: Altitude | None = None
    """Hover height reached after take-off, above the take-off point (m); None: the exploration altitude.
    Climbing straight up first gives the camera its widest footprint over the take-off point within
    seconds, before the pattern leaves it: a moving platform crossing the area is most often near it early
    (the zamanakos_sdu straight-line misses of a 4 m take-off were all platforms that passed there while
    the vehicle was still low and flying its first leg the other way)."""
    explore_altitude_m: Altitude = 12.0
    """Altitude of the coverage pattern (m)."""
    track_height_m: Altitude = 2.5
    """Height above the pad while tracking, before the descent (m)."""
    land_speed_mps: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)] = 0.4
    """Vertical speed of the descent (m/s)."""
    hover_tolerance_m: float = 0.3
    """Take-off is done when within this height of the hover point ... (m)."""
    hover_speed_tolerance_mps: float = 0.3
    """... and slower than this (m/s)."""
    takeoff_timeout_s: PositiveFloat = 30.0
    """Take-off not done after this long (wind stronger than the vehicle, a motor short of thrust):
    abort (s)."""
    takeoff_clearance_m: PositiveFloat = 0.3
    """During the take-off, below this height above the take-off point (m), the tilt is limited to
    ``takeoff_max_tilt_rad`` (as PX4 limits it during its take-off ramp): leaning into a wind or toward
    the climb's goal with the feet this close to the ground would put a foot on it (a foot 0.2 m out
    reaches 0.14 m down at 45 deg)."""
    takeoff_max_tilt_rad: Annotated[float, Field(gt=0, lt=math.pi / 2, allow_inf_nan=False)] = math.radians(
        12.0
    )
    """The take-off's tilt limit near the ground (rad); 12 deg is PX4's ``MPC_TILTMAX_LND``."""
    land_touchdown_max_tilt_rad: Tilt | None = None
    """In a committed descent, with the range finder reading less than ``land_touchdown_clearance_m``
    from the feet, the commanded tilt is limited to this (rad), as PX4's ``MPC_TILTMAX_LND`` limits it
    in its landings: the feet meet the deck no more tilted than the gear tolerates, and the vehicle drifts
    with a gust for that last fraction of a second instead of leaning into it. None: no limit (the
    papers' descent)."""
    land_touchdown_clearance_m: PositiveFloat = 0.1
    """The range from the feet (m) below which ``land_touchdown_max_tilt_rad`` applies."""
    land_position_tolerance_m: PositiveFloat = 0.25
    """Descent gate, horizontal offset to the pad: the landing starts below this (m) ..."""
    land_velocity_tolerance_mps: PositiveFloat = 0.3
    """Descent gate, relative horizontal velocity: ... and with the platform's velocity matched within
    this (m/s) ..."""
    max_estimate_age_s: PositiveFloat = 0.6
    """Descent gate, estimate age: ... and the last measurement younger than this (s) ..."""
    land_max_position_std_m: PositiveFloat = 0.3
    """Descent gate, estimator consistency: ... and the platform estimate's horizontal standard
    deviation, sqrt(trace of its xy covariance / 2), below this (m) ..."""
    land_dwell_s: float = 0.3
    """... all for at least this long (s)."""
    land_hold_offset_m: PositiveFloat = 0.45
    """During the descent, above the commit height, the vehicle holds its height while the offset to the
    pad exceeds this, or the relative velocity ``land_hold_rel_speed_mps``, or the estimate is older than
    ``max_estimate_age_s`` or less certain than ``land_max_position_std_m`` (m)."""
    land_hold_rel_speed_mps: PositiveFloat = 0.6
    """See ``land_hold_offset_m`` (m/s)."""
    land_abort_offset_m: PositiveFloat = 0.6
    """The descent is abandoned (go-around) when the horizontal offset to the pad exceeds this (m) ..."""
    land_abort_rel_speed_mps: PositiveFloat = 1.2
    """... or the relative horizontal velocity exceeds this (m/s) ..."""
    land_lost_timeout_s: PositiveFloat = 1.0
    """... or the target is unseen this long (s) ..."""
    land_abort_position_std_m: PositiveFloat = 0.8
    """... or the estimate's horizontal standard deviation exceeds this (m) ..."""
    land_hold_timeout_s: PositiveFloat = 3.0
    """... or the descent has held its height this long (s)."""
    land_commit_height_m: Altitude = 0.6
    """Below this height above the pad no gate stops the descent any more: it continues on the platform
    estimator's prediction (m). The camera sees the tag's cross down to about 0.3 m, but a moving pad may
    leave the view in the last half metre (a downward camera cannot see the whole pad from closer than
    about its own size: paper 000's reason for the model-based filter)."""
    land_commit_timeout_s: PositiveFloat | None = None
    """A descent that has been below the commit height this long without a touchdown goes around (s): it
    missed the pad (a platform that braked or drove off while the last half metre was flown on the
    prediction) and would otherwise hover beside it for ever. None: twice the time the descent takes from
    the commit height to the pad, plus 3 s for the land detector."""
    land_commit_speed_change_mps: PositiveFloat = 0.5
    """A committed descent goes around when the platform estimate's speed has changed by more than this
    since the commit (m/s), while the vehicle is still above a quarter of the commit height: the platform
    braked or drove off under the last half metre (the estimator follows a speed change within a few
    measurements, and the camera may lose the pad right after), and the prediction the descent flies on
    no longer holds."""
    land_commit_deck_velocity_error_mps: PositiveFloat | None = 0.5
    """Go-around when, in a committed descent, the deck's velocity that the optical-flow module measures
    under the feet (when the vehicle has one: the ego velocity less the measured slip) differs from the
    platform estimate's, which the descent flies on, by more than this (m/s): the deck braked or sped up
    under the last half metre, which the camera no longer sees and the estimate follows only after a few
    measurements. A hard brake (6 m/s^2) passes 0.5 m/s about 85 ms in. Why the deck's velocity and not
    the slip: in 12 m/s wind or a tractor's U-turn the *vehicle* slips up to 1.1 m/s while it holds or
    catches up, and lands well; the deck itself does what the estimate says. None: off. Without a module
    the check has nothing to read."""
    land_commit_ground_margin_m: PositiveFloat | None = 0.2
    """Go-around when, in a committed descent, the range finder (from the feet) reads more than this
    beyond the body's height over the estimated deck (m): the surface below is lower than the deck, the
    prediction has left the pad and the vehicle would land beside it (a platform that braked under the
    last half metre, when the camera no longer sees the pad). It needs a deck higher than the margin
    plus the gear. None: off. Paper 000's descent has no such check; it is on for every preset, as the
    other failsafes are: without it a platform braking under the committed descent crashed 3 of 50
    groundtruth and 3 of 50 falanga2017 missions of the fault campaign (examples/campaigns/faults.yaml,
    class brake_stop)."""
    land_commit_max_tilt_rad: Tilt | None = None
    """The descent holds at the commit height until the vehicle's tilt, low-passed over
    ``land_tilt_time_constant_s``, is below this (rad), then commits; it waits at most
    ``land_tilt_wait_s``, then goes around. A vehicle holding against strong wind leans, and turbulence
    swings the lean by +-7 deg (one sigma) within a second or two: the contact judge (and a real gear)
    tolerates 25 deg, so the last second of the descent is started in a lull, as a ship's helicopter
    waits for a quiescent deck. None: off (the papers' descent, which commits on its position gates
    alone)."""
    land_steady_tilt_max_rad: Tilt | None = None
    """With ``land_commit_max_tilt_rad``: a lean above this (rad) holds the commit even when it is steady
    (its spread below ``land_tilt_min_spread_rad``). A steady lean is what the vehicle lands with however
    long it waits, which is acceptable up to what the gear tolerates and not above: the Matrice 100 holding
    12 m/s of wind leans 21-35 deg around a 28 deg mean on some seeds, a spread just under 5 deg, and
    committed into it touched down at 30-35 deg. Waiting there gives the circling deck time to turn
    downwind (less airspeed, less lean), or ends in a go-around. None: no limit."""
    land_commit_max_platform_accel_mps2: PositiveFloat | None = None
    """The descent holds at the commit height until the platform estimate's horizontal acceleration (the
    centripetal ``v_t omega`` of a turning unicycle) is at most this (m/s^2), then commits; committed, it
    pauses while the body is above half the commit height. Why: below the commit height the camera loses
    the pad and the last ~0.5 s (blind time plus the camera's latency) is flown on the prediction; a turn
    that ends (or begins) in that window puts up to ``a * 0.5 s`` into the relative velocity at contact.
    A tractor's 4 m U-turn at 3 m/s (2.25 m/s^2) gave 1.0-1.4 m/s, past the contact judge's 0.75, in 4 of
    20 envelope missions at 5886e7b; a steady turn is predicted well, so only hard turns are waited out.
    It waits at most ``land_tilt_wait_s``, then goes around. None: off (the papers' descent)."""
    land_steady_turn_s: PositiveFloat | None = None
    """With ``land_commit_max_platform_accel_mps2``: a turn that the platform estimate has held steady
    this long (s) no longer holds the commit, up to ``land_steady_turn_max_accel_mps2``. A sustained
    turn (a circle, a motorway bend, a ship holding its turn) is what the constant-turn-rate prediction
    the committed descent flies on predicts exactly, and waiting for the straight that a circle never
    drives ended in go-arounds (sustained circles at 1.8-3.2 m/s^2: 0 of 60 landed). Longer than a
    manoeuvre that ends: a tractor's 4 m U-turn at 3 m/s lasts 4.2 s, and it still waits for the row.
    "Steady": the estimate's signed turn rate ``(v x a)_z / |v|^2`` stays within
    ``land_steady_turn_band_rad_s`` of its running mean (EMA over ``land_steady_turn_s / 3``). None: every
    hard turn holds the commit."""
    land_steady_turn_band_rad_s: PositiveFloat = 0.08
    """See ``land_steady_turn_s`` (rad/s): about three times the turn-rate estimate's own jitter on a
    30 m circle at 8.5 m/s (0.02-0.03 rad/s), a tenth of a tractor's U-turn rate."""
    land_steady_turn_max_accel_mps2: PositiveFloat = 3.5
    """A steady turn harder than this (m/s^2) holds the commit however long it lasts: the vehicle leans
    into the centripetal acceleration too (atan(3.5 / 9.81) = 20 deg before any rotor drag), and the
    touchdown tilt limit is 25 deg."""
    land_tilt_wait_s: PositiveFloat = 20.0
    """Longest wait at the commit height for a lull in the tilt or the end of a hard turn before a
    go-around (s)."""
    land_tilt_time_constant_s: PositiveFloat = 0.3
    """Low-pass time constant of the tilt the commit gate reads (s): long enough to ignore the
    controller's own jitter, short enough that a lull is still there when the feet reach the deck
    (about a second later at 0.4 m/s)."""
    land_tilt_min_spread_rad: NonNegFloat = 0.0
    """The commit gate waits only while the tilt's standard deviation over the last ~2 s is at least this
    (rad): a steady lean (rotor drag behind a fast deck in calm air, 17-24 deg at 12 m/s for the F450)
    is what the vehicle touches down with however long it waits, an unsteady one (gusts) can be waited
    out."""
    lost_timeout_s: Duration = 3.0
    """Tracking coasts on the prediction while the target is unseen this long, then searches (s)."""
    search_timeout_s: PositiveFloat = 20.0
    """The search around the predicted platform lasts this long before the whole area is explored
    again (s)."""
    max_target_losses: Annotated[int, Field(ge=0)] = 5
    """The mission aborts when the target is lost (TRACK -> SEARCH) more often than this."""
    max_go_arounds: Annotated[int, Field(ge=0, le=1000)] = 3
    """The mission aborts after more go-arounds than this."""
    time_budget_s: Duration | None = None
    """Abort when the mission has run this long without landing (s); None for no budget."""
    final_action: FinalAction = "hover"
    """What ABORT does: ``hover`` at the exploration altitude, ``return`` to the take-off point and land
    there, or ``land_in_place``."""
    abort_hover_s: PositiveFloat = 2.0
    """The ``hover`` final action is complete after holding the hold point steadily this long (s)."""
    touchdown: TouchdownConfig = field(default_factory=TouchdownConfig)
    """The onboard land detector's parameters."""


_TILT_SPREAD_TIME_CONSTANT_S = 2.0
"""Window (EMA time constant, s) of the tilt's mean and spread the commit gate reads: about the
correlation time of low-altitude turbulence at 12 m/s (MIL-F-8785C: L_u / V = 23 m / 12 m/s)."""

# Every transition the machine can make: (from, to, event). The tests walk this table.
TRANSITIONS: tuple[tuple[Mode, Mode, str], ...] = (
    (Mode.IDLE, Mode.TAKEOFF, "mission started"),
    (Mode.TAKEOFF, Mode.EXPLORE, "hover reached, no target yet"),
    (Mode.TAKEOFF, Mode.TRACK, "hover reached, target already seen"),
    (Mode.TAKEOFF, Mode.TRACK, "target seen above the tracking height"),
    (Mode.TAKEOFF, Mode.ABORT, "take-off timeout"),
    (Mode.EXPLORE, Mode.TRACK, "target detected"),
    (Mode.EXPLORE, Mode.ABORT, "time budget spent"),
    (Mode.TRACK, Mode.LAND, "above the platform with matched velocity"),
    (Mode.TRACK, Mode.SEARCH, "target lost, coast ended"),
    (Mode.TRACK, Mode.ABORT, "too many target losses"),
    (Mode.TRACK, Mode.ABORT, "time budget spent"),
    (Mode.SEARCH, Mode.TRACK, "target reacquired"),
    (Mode.SEARCH, Mode.EXPLORE, "search around the prediction timed out"),
    (Mode.SEARCH, Mode.ABORT, "time budget spent"),
    (Mode.LAND, Mode.LANDED, "touchdown detected on board"),
    (Mode.LAND, Mode.GO_AROUND, "target lost during the descent"),
    (Mode.LAND, Mode.GO_AROUND, "off the pad during the descent"),
    (Mode.LAND, Mode.GO_AROUND, "relative velocity too large during the descent"),
    (Mode.LAND, Mode.GO_AROUND, "estimate too uncertain during the descent"),
    (Mode.LAND, Mode.GO_AROUND, "descent held too long"),
    (Mode.LAND, Mode.GO_AROUND, "no lull in the tilt"),
    (Mode.LAND, Mode.GO_AROUND, "the platform kept turning hard"),
    (Mode.LAND, Mode.GO_AROUND, "no touchdown after the commit height"),
    (Mode.LAND, Mode.GO_AROUND, "platform speed changed after the commit"),
    (Mode.LAND, Mode.GO_AROUND, "ground below the committed descent"),
    (Mode.LAND, Mode.GO_AROUND, "the deck left the estimate under the committed descent (optical flow)"),
    (Mode.LAND, Mode.GO_AROUND, "time budget spent"),
    (Mode.LAND, Mode.GO_AROUND, "no quiet window in the deck's motion"),
    (Mode.LAND, Mode.GO_AROUND, "the deck's quiet window closed before contact"),
    (Mode.GO_AROUND, Mode.TRACK, "tracking height regained"),
    (Mode.GO_AROUND, Mode.ABORT, "too many go-arounds"),
    (Mode.GO_AROUND, Mode.ABORT, "time budget spent"),
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


@dataclass(frozen=True, slots=True)
class FailsafeEvent:
    """One failsafe event, as ``result.json`` records it."""

    t: float
    """Time (s)."""
    kind: str
    """``coast``, ``reacquired``, ``search``, ``explore``, ``descent_hold``, ``go_around``, ``abort``,
    ``final_action``, ``final_action_complete``."""
    reason: str


def position_std_m(target: PlatformEstimate) -> float:
    """Horizontal standard deviation of a platform estimate, sqrt(trace(cov_xy) / 2) (m): the
    consistency gate's measure (a diverging or starved filter's covariance grows)."""
    c = target.cov_p_WP
    return math.sqrt(max(0.5 * (float(c[0, 0]) + float(c[1, 1])), 0.0))


def signed_turn_rate(target: PlatformEstimate) -> float:
    """The platform estimate's turn rate (rad/s, counter-clockwise), ``(v x a)_z / |v|^2``; 0 below
    0.5 m/s (the heading of a vehicle at rest says nothing) or when not finite."""
    vx, vy = float(target.v_WP[0]), float(target.v_WP[1])
    ax, ay = float(target.a_WP[0]), float(target.a_WP[1])
    speed2 = vx * vx + vy * vy
    w = (vx * ay - vy * ax) / speed2 if speed2 >= 0.25 else 0.0
    return w if math.isfinite(w) else 0.0


class SteadyTurn:
    """How long the platform estimate's turn rate has stayed within a band of its running mean (the
    commit rule of a sustained turn, ``MissionConfig.land_steady_turn_s``). The mean is an EMA over a
    third of the required duration; the run restarts when the rate leaves the band, when the mean
    changes sign (a figure-8's crossing), or after a gap of more than 0.5 s without an estimate."""

    def __init__(self) -> None:
        self.mean_rad_s = 0.0
        self._t: float | None = None
        self._since: float | None = None

    def update(self, t: float, target: PlatformEstimate | None, duration_s: float, band_rad_s: float) -> None:
        """Fold in the estimate at ``t`` (None: no estimate, the run restarts)."""
        prev, self._t = self._t, t
        if target is None or prev is None or not 0.0 < t - prev <= 0.5:
            self.mean_rad_s = 0.0 if target is None else signed_turn_rate(target)
            self._since = None if target is None else t
            return
        w = signed_turn_rate(target)
        dt = t - prev
        mean = self.mean_rad_s + dt / (duration_s / 3.0 + dt) * (w - self.mean_rad_s)
        if abs(w - mean) > band_rad_s or mean * self.mean_rad_s < 0.0:
            self._since = t
        self.mean_rad_s = mean

    def steady_for(self, t: float) -> float:
        """How long (s) the turn rate has been steady at ``t``; 0 before any estimate."""
        return 0.0 if self._since is None else t - self._since


class Mission:
    """Decides the mode from the ego estimate, the platform estimate and the onboard land detector."""

    def __init__(self, config: MissionConfig | None = None) -> None:
        self.config = config or MissionConfig()
        self.quiet_window: QuietWindowGate | None = None
        """The quiet-window touchdown on a ship's deck (:meth:`attach_quiet_window`); None: off."""
        self._quiet_since = math.nan
        self._quiet_hold = False
        self.reset()

    def reset(self) -> None:
        self.mode = Mode.IDLE
        self.mode_since = 0.0
        self.reason = ""
        self.go_arounds = 0
        self.target_losses = 0
        self._t_start: float | None = None
        self._matched_since: float | None = None
        self._hold_since: float | None = None
        self._committed_since: float | None = None
        self._committed_speed = 0.0
        self._coasting = False
        self.tilt_lp_rad = 0.0
        """The vehicle's tilt, low-passed over ``land_tilt_time_constant_s`` (rad), for the commit gate."""
        self.tilt_sd_rad = 0.0
        """Standard deviation of the tilt about its 2 s mean, over ~2 s (rad), for the commit gate."""
        self._tilt_mean = 0.0
        self._tilt_var = 0.0
        self._t_tilt: float | None = None
        self._tilt_wait = False
        self.descent_hold = False
        """True while the descent holds its height (a marginal gate); the guidance reads it."""
        self._turn = SteadyTurn()
        self.takeoff_point_W = np.zeros(3)
        self.history: list[tuple[float, Mode, str]] = []
        self.events: list[FailsafeEvent] = []
        self.abort_reason: str | None = None
        self.abort_phase = ""
        """What the final action is doing: ``climb``, ``transit``, ``descend``, ``hold``, ``done``."""
        self.abort_goal_W = np.zeros(3)
        """Where the final action goes: the hold point, the point above home, or the landing spot."""
        self._steady_since: float | None = None
        self.final_action_complete = False

    # -- helpers ---------------------------------------------------------------------------------
    def _go(self, t: float, mode: Mode, reason: str) -> None:
        self.mode, self.mode_since, self.reason = mode, t, reason
        self._matched_since = None
        self._hold_since = None
        self._committed_since = None
        self._tilt_wait = False
        self.descent_hold = False
        self.history.append((t, mode, reason))

    def _update_tilt(self, t: float, ego: EgoState) -> None:
        """Low-pass the tilt (the angle of the body z axis from the vertical) for the commit gate."""
        if self.config.land_commit_max_tilt_rad is None:
            return
        x, y = float(ego.q_WB[0]), float(ego.q_WB[1])
        tilt = math.acos(min(1.0, max(-1.0, 1.0 - 2.0 * (x * x + y * y))))
        prev, self._t_tilt = self._t_tilt, t
        if not math.isfinite(tilt):
            return
        if prev is None or not 0.0 < t - prev <= 0.5:
            self.tilt_lp_rad = self._tilt_mean = tilt
            self._tilt_var = 0.0
            self.tilt_sd_rad = 0.0
            return
        dt = t - prev
        gain = dt / (self.config.land_tilt_time_constant_s + dt)
        self.tilt_lp_rad += gain * (tilt - self.tilt_lp_rad)
        slow = dt / (_TILT_SPREAD_TIME_CONSTANT_S + dt)
        self._tilt_mean += slow * (tilt - self._tilt_mean)
        self._tilt_var += slow * ((tilt - self._tilt_mean) ** 2 - self._tilt_var)
        self.tilt_sd_rad = math.sqrt(max(self._tilt_var, 0.0))

    def _no_lull(self) -> bool:
        """The commit gate is shut: an unsteady tilt above the limit."""
        cfg = self.config
        if cfg.land_commit_max_tilt_rad is None:
            return False
        ceiling = cfg.land_steady_tilt_max_rad
        return self.tilt_lp_rad > cfg.land_commit_max_tilt_rad and (
            self.tilt_sd_rad >= cfg.land_tilt_min_spread_rad
            or (ceiling is not None and self.tilt_lp_rad > ceiling)
        )

    def _turning_hard(self, t: float, target: PlatformEstimate) -> bool:
        """The commit gate is shut: the platform estimate accelerates (turns) harder than the limit, and
        not in a turn it has held steady for ``land_steady_turn_s`` (up to
        ``land_steady_turn_max_accel_mps2``). A non-finite acceleration shuts it too (the prediction the
        committed descent would fly on is not trustworthy)."""
        cfg = self.config
        limit = cfg.land_commit_max_platform_accel_mps2
        if limit is None:
            return False
        a = math.hypot(float(target.a_WP[0]), float(target.a_WP[1]))
        if a <= limit:
            return False
        if cfg.land_steady_turn_s is None or not a <= cfg.land_steady_turn_max_accel_mps2:
            return True
        return self._turn.steady_for(t) < cfg.land_steady_turn_s

    def _event(self, t: float, kind: str, reason: str) -> None:
        self.events.append(FailsafeEvent(t, kind, reason))

    def _abort(self, t: float, ego: EgoState, reason: str) -> None:
        cfg = self.config
        self._go(t, Mode.ABORT, reason)
        self.abort_reason = reason
        self._event(t, "abort", reason)
        p = ego.p_WB
        if cfg.final_action == "hover":
            self.abort_phase = "climb"
            self.abort_goal_W = np.array([p[0], p[1], max(float(p[2]), cfg.explore_altitude_m)])
        elif cfg.final_action == "return":
            self.abort_phase = "transit"
            home = self.takeoff_point_W
            self.abort_goal_W = np.array([home[0], home[1], max(float(p[2]), cfg.explore_altitude_m)])
        else:
            self.abort_phase = "descend"
            self.abort_goal_W = np.array([p[0], p[1], float(self.takeoff_point_W[2])])
        self._event(t, "final_action", f"{cfg.final_action}: {self.abort_phase}")

    @staticmethod
    def _age(t: float, target: PlatformEstimate | None) -> float:
        return math.inf if target is None else t - target.t_last_measurement

    def hover_point_W(self) -> FloatArray:
        c = self.config
        height = c.explore_altitude_m if c.takeoff_altitude_m is None else c.takeoff_altitude_m
        p: FloatArray = self.takeoff_point_W + np.array([0.0, 0.0, height])
        return p

    # -- the step ----------------------------------------------------------------------------------
    def step(
        self,
        t: float,
        ego: EgoState,
        target: PlatformEstimate | None,
        range_m: float | None = None,
        *,
        touchdown: bool = False,
        deck_velocity_W: FloatArray | None = None,
    ) -> MissionStatus:
        """Advance the machine to time ``t``. ``target`` is the platform estimate at ``t`` (None before
        the first detection); ``range_m`` is the range finder's reading from the feet, None when invalid,
        read only by the committed descent's ground check (the pipeline gives the smallest of its last
        three readings: one spurious long return must not send the vehicle around; the touchdown is the
        land detector's); ``touchdown``: the onboard land detector says the vehicle stands on a
        surface; ``deck_velocity_W``: the horizontal velocity (2,) of the surface under the feet measured by
        an optical-flow module, None without a recent sample (read only by the committed descent)."""
        cfg = self.config
        before = self.mode
        if self.mode is Mode.IDLE:
            self._t_start = t
            self.takeoff_point_W = ego.p_WB.copy()
            self._go(t, Mode.TAKEOFF, "mission started")
            return MissionStatus(self.mode, True, self.reason, self.mode_since)

        self._update_tilt(t, ego)
        if cfg.land_steady_turn_s is not None:
            self._turn.update(t, target, cfg.land_steady_turn_s, cfg.land_steady_turn_band_rad_s)
        age = self._age(t, target)
        over_budget = (
            cfg.time_budget_s is not None
            and self._t_start is not None
            and t - self._t_start > cfg.time_budget_s
        )
        mode = self.mode

        if mode is Mode.TAKEOFF:
            self._step_takeoff(t, ego, target, age)

        elif mode is Mode.EXPLORE:
            if over_budget:
                self._abort(t, ego, "time budget spent")
            elif target is not None and age < cfg.lost_timeout_s:
                self._go(t, Mode.TRACK, "target detected")

        elif mode is Mode.TRACK:
            self._step_track(t, ego, target, age, over_budget)

        elif mode is Mode.SEARCH:
            if over_budget:
                self._abort(t, ego, "time budget spent")
            elif target is not None and target.t_last_measurement > self.mode_since:
                self._event(t, "reacquired", "target seen during the search")
                self._go(t, Mode.TRACK, "target reacquired")
            elif t - self.mode_since > cfg.search_timeout_s:
                self._event(t, "explore", "search around the prediction timed out")
                self._go(t, Mode.EXPLORE, "search around the prediction timed out")

        elif mode is Mode.LAND:
            self._step_land(t, ego, target, age, over_budget, touchdown, range_m, deck_velocity_W)
            self.descent_hold = self.descent_hold or (self._quiet_hold and self.mode is Mode.LAND)

        elif mode is Mode.GO_AROUND:
            self._step_go_around(t, ego, target, over_budget)

        elif mode is Mode.ABORT:
            self._step_abort(t, ego, touchdown)

        # LANDED is final; ABORT's only way on is its final action.
        return MissionStatus(self.mode, self.mode is not before, self.reason, self.mode_since)

    def _step_takeoff(self, t: float, ego: EgoState, target: PlatformEstimate | None, age: float) -> None:
        cfg = self.config
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
        elif t - self.mode_since > cfg.takeoff_timeout_s:
            self._event(t, "takeoff_timeout", f"hover not reached in {cfg.takeoff_timeout_s:g} s")
            self._abort(t, ego, "take-off timeout")

    def _step_go_around(
        self, t: float, ego: EgoState, target: PlatformEstimate | None, over_budget: bool
    ) -> None:
        cfg = self.config
        # A go-around is flown to its end, the tracking height over the deck, also past the retry
        # limit or the time budget: the final action then starts clear of the deck. Started in the
        # committed descent, a quarter metre over a deck at 5 m/s, the final action's climb (a long
        # move to a hover point that stays behind) kept sinking for 0.8 s while the vehicle braked,
        # and met the deck 0.8 m off its centre at 1.6 m/s (the envelope's figure-8, 2026-11-29).
        # Without an estimate the deck's height is unknown: the limits act at once, as before.
        if target is not None:
            regained = float(ego.p_WB[2] - target.p_WP[2]) > cfg.track_height_m - cfg.hover_tolerance_m
        else:
            regained = bool(ego.p_WB[2] > cfg.explore_altitude_m - cfg.hover_tolerance_m)
        limit = self.go_arounds > cfg.max_go_arounds
        if (limit or over_budget) and (regained or target is None):
            if limit:
                self._event(t, "retry_limit", f"{self.go_arounds} go-arounds")
                self._abort(t, ego, "too many go-arounds")
            else:
                self._abort(t, ego, "time budget spent")
        elif regained:
            self._go(t, Mode.TRACK, "tracking height regained")

    def _step_track(
        self, t: float, ego: EgoState, target: PlatformEstimate | None, age: float, over_budget: bool
    ) -> None:
        cfg = self.config
        if over_budget:
            self._abort(t, ego, "time budget spent")
            return
        if target is None or age > cfg.lost_timeout_s:
            self._coasting = False
            self.target_losses += 1
            if self.target_losses > cfg.max_target_losses:
                self._event(t, "retry_limit", f"target lost {self.target_losses} times")
                self._abort(t, ego, "too many target losses")
            else:
                self._event(t, "search", "coast ended: search around the predicted platform")
                self._go(t, Mode.SEARCH, "target lost, coast ended")
            return
        if age > cfg.max_estimate_age_s and not self._coasting:
            self._coasting = True
            self._event(t, "coast", "target unseen: following the prediction")
        elif age <= cfg.max_estimate_age_s and self._coasting:
            self._coasting = False
            self._event(t, "reacquired", "target seen again while coasting")
        dp = float(np.linalg.norm(ego.p_WB[:2] - target.p_WP[:2]))
        dv = float(np.linalg.norm(ego.v_WB[:2] - target.v_WP[:2]))
        matched = (
            dp < cfg.land_position_tolerance_m
            and dv < cfg.land_velocity_tolerance_mps
            and age < cfg.max_estimate_age_s
            and position_std_m(target) < cfg.land_max_position_std_m
        )
        if not matched:
            self._matched_since = None
        elif self._matched_since is None:
            self._matched_since = t
        if self._matched_since is not None and t - self._matched_since >= cfg.land_dwell_s:
            self._go(t, Mode.LAND, "above the platform with matched velocity")

    def _step_land(
        self,
        t: float,
        ego: EgoState,
        target: PlatformEstimate | None,
        age: float,
        over_budget: bool,
        touchdown: bool,
        range_m: float | None = None,
        deck_velocity_W: FloatArray | None = None,
    ) -> None:
        cfg = self.config
        if touchdown:
            self._go(t, Mode.LANDED, "touchdown detected on board")
            return
        if over_budget:
            # the go-around climbs clear of the deck first; its end is the abort
            self._go_around(t, "time budget spent")
            return
        if target is None:
            self._go_around(t, "target lost during the descent")
            return
        if self._quiet_window_step(t, ego):
            return
        height = float(ego.p_WB[2] - target.p_WP[2])
        no_lull = self._no_lull()
        turning = self._turning_hard(t, target)
        if (
            self._committed_since is None
            and height <= cfg.land_commit_height_m
            and not self.descent_hold
            and not (no_lull or turning)
        ):
            # Committed: the descent continues on the prediction. Only from a descent whose gates are all
            # good: a vehicle that sinks through the commit height while a gate holds the descent (it
            # lags its held reference) is not committed, and the gates still apply to it.
            self._committed_since = t
            self._committed_speed = float(np.hypot(target.v_WP[0], target.v_WP[1]))
        if self._committed_since is not None:
            committed_s = t - self._committed_since
            self._step_committed(t, committed_s, target, height, no_lull or turning, range_m, deck_velocity_W)
            return
        dp = float(np.linalg.norm(ego.p_WB[:2] - target.p_WP[:2]))
        dv = float(np.linalg.norm(ego.v_WB[:2] - target.v_WP[:2]))
        std = position_std_m(target)
        if age > cfg.land_lost_timeout_s:
            self._go_around(t, "target lost during the descent")
        elif dp > cfg.land_abort_offset_m:
            self._go_around(t, "off the pad during the descent")
        elif dv > cfg.land_abort_rel_speed_mps:
            self._go_around(t, "relative velocity too large during the descent")
        elif std > cfg.land_abort_position_std_m:
            self._go_around(t, "estimate too uncertain during the descent")
        else:
            marginal = (
                dp > cfg.land_hold_offset_m
                or dv > cfg.land_hold_rel_speed_mps
                or age > cfg.max_estimate_age_s
                or std > cfg.land_max_position_std_m
            )
            # the commit gates: at the commit height, wait for the tilt to drop and for a hard turn of the
            # platform to end (a marginal gate first)
            tilt_wait = not marginal and (no_lull or turning) and height <= cfg.land_commit_height_m
            if tilt_wait and not self._tilt_wait:
                self._tilt_wait_event(t, target, no_lull)
            self._tilt_wait = tilt_wait
            if (marginal or tilt_wait) and not self.descent_hold:
                self.descent_hold, self._hold_since = True, t
                if marginal:
                    why = f"offset {dp:.2f} m, rel. speed {dv:.2f} m/s, age {age:.2f} s, std {std:.2f} m"
                    self._event(t, "descent_hold", why)
            elif not (marginal or tilt_wait):
                self.descent_hold, self._hold_since = False, None
            limit = cfg.land_tilt_wait_s if tilt_wait else cfg.land_hold_timeout_s
            if self._hold_since is not None and t - self._hold_since > limit:
                if not tilt_wait:
                    self._go_around(t, "descent held too long")
                else:
                    self._go_around(t, "no lull in the tilt" if no_lull else "the platform kept turning hard")

    # -- the quiet-window touchdown on a ship's deck (issue 37; the logic is in mission/quiet_window.py) --
    def attach_quiet_window(self, gate: QuietWindowGate) -> None:
        """Land in the deck's quiet windows (a platform estimator that predicts the deck's motion)."""
        self.quiet_window = gate

    def _quiet_window_step(self, t: float, ego: EgoState) -> bool:
        """The quiet-window gate in the landing: True when it sent the vehicle around (the step ends);
        while it waits for its window, :meth:`step` holds the descent after the other gates have run."""
        gate = self.quiet_window
        was_holding, self._quiet_hold = self._quiet_hold, False
        if gate is None:
            return False
        if self._quiet_since != self.mode_since:  # a new approach
            gate.reset()
            self._quiet_since = self.mode_since
        decision = gate.step(t, float(ego.p_WB[2]))
        if decision == "go_around":
            self._go_around(t, gate.reason)
            return True
        if decision == "hold" and not was_holding:
            self._event(t, "descent_hold", "waiting above the deck for a quiet window")
        self._quiet_hold = decision == "hold"
        return False

    def _tilt_wait_event(self, t: float, target: PlatformEstimate, no_lull: bool) -> None:
        """Record that the descent waits at the commit height: for a lull in the tilt (``no_lull``), or
        for the platform to end its hard turn."""
        if no_lull:
            why = f"tilt {math.degrees(self.tilt_lp_rad):.1f} deg: waiting for a lull"
        else:
            a = math.hypot(float(target.a_WP[0]), float(target.a_WP[1]))
            why = f"platform turning at {a:.2f} m/s^2: waiting for it to drive straight"
        self._event(t, "descent_hold", why)

    def _step_committed(
        self,
        t: float,
        committed_s: float,
        target: PlatformEstimate,
        height: float,
        gate_shut: bool,
        range_m: float | None,
        deck_velocity_W: FloatArray | None,
    ) -> None:
        """The committed descent's checks (``committed_s``: how long it has been committed, s; ``height``:
        the body's over the estimated deck, m; ``gate_shut``: the tilt or the platform's turn shuts the
        commit gate now)."""
        cfg = self.config
        change = abs(float(np.hypot(target.v_WP[0], target.v_WP[1])) - self._committed_speed)
        margin = cfg.land_commit_ground_margin_m
        if committed_s > self.commit_timeout_s():
            self._go_around(t, "no touchdown after the commit height")
        elif change > cfg.land_commit_speed_change_mps and height > 0.25 * cfg.land_commit_height_m:
            self._go_around(t, "platform speed changed after the commit")
        elif (
            cfg.land_commit_deck_velocity_error_mps is not None
            and deck_velocity_W is not None
            and math.hypot(
                float(deck_velocity_W[0]) - float(target.v_WP[0]),
                float(deck_velocity_W[1]) - float(target.v_WP[1]),
            )
            > cfg.land_commit_deck_velocity_error_mps
        ):
            # measured, not predicted: the deck under the feet no longer moves as the estimate the
            # descent flies on (optical flow). No height floor: the module sees the deck until the
            # feet are centimetres over it
            self._go_around(t, "the deck left the estimate under the committed descent (optical flow)")
        elif margin is not None and range_m is not None and range_m > height + margin:
            # the range from the feet exceeds the body's height over the estimated deck: the surface
            # below is lower than the deck (the ground beside it)
            self._go_around(t, "ground below the committed descent")
        else:
            # a gust or a hard turn after the commit: pause the descent (no go-around this low) until
            # it is over, while the feet are still clear of the deck; the commit timeout still runs
            self.descent_hold = gate_shut and height > 0.5 * cfg.land_commit_height_m

    def commit_timeout_s(self) -> float:
        """How long a committed descent may last without a touchdown (s): ``land_commit_timeout_s``."""
        cfg = self.config
        if cfg.land_commit_timeout_s is not None:
            return cfg.land_commit_timeout_s
        return 2.0 * cfg.land_commit_height_m / cfg.land_speed_mps + 3.0

    @property
    def committed(self) -> bool:
        """True while the descent is committed (below the commit height, entered with every gate good)."""
        return self._committed_since is not None

    def tilt_limit_rad(self, mode: Mode, ego: EgoState, range_raw_m: float | None) -> float | None:
        """The tilt limit for the controller now (rad; None: unlimited), in ``mode`` (the last step's) with
        the ego estimate ``ego`` (its height over :attr:`takeoff_point_W` during the take-off) and
        ``range_raw_m``, the range finder's latest reading from the feet as the sensor reported it
        (``-inf``: closer than its minimum range; None or NaN: invalid).

        Near the ground during the take-off, the tilt is limited (``takeoff_clearance_m``,
        ``takeoff_max_tilt_rad``): a vehicle that leans into a wind or toward its climb's goal with its
        feet a few centimetres up puts a foot on the ground and tips. PX4 limits the tilt during its
        take-off ramp for the same reason. The vehicle drifts with the wind until clear, then corrects.

        In a committed descent with the range finder reading less than ``land_touchdown_clearance_m``
        from the feet, the tilt is limited to ``land_touchdown_max_tilt_rad`` when set (PX4's
        ``MPC_TILTMAX_LND`` does it for its landings): the feet meet the deck level enough for the gear,
        and the vehicle drifts with a gust for the last fraction of a second instead of leaning into it."""
        cfg = self.config
        if (
            mode is Mode.TAKEOFF
            and float(ego.p_WB[2]) - float(self.takeoff_point_W[2]) < cfg.takeoff_clearance_m
        ):
            return cfg.takeoff_max_tilt_rad
        if (
            mode is Mode.LAND
            and cfg.land_touchdown_max_tilt_rad is not None
            and self._committed_since is not None
        ):
            r = range_raw_m
            if r is not None and (
                r == -math.inf or (math.isfinite(r) and r < cfg.land_touchdown_clearance_m)
            ):
                return cfg.land_touchdown_max_tilt_rad
        return None

    def _go_around(self, t: float, reason: str) -> None:
        self.go_arounds += 1
        self._event(t, "go_around", reason)
        self._go(t, Mode.GO_AROUND, reason)

    def _step_abort(self, t: float, ego: EgoState, touchdown: bool) -> None:
        cfg = self.config
        phase = self.abort_phase
        if phase in ("done", ""):
            return
        goal = self.abort_goal_W
        near = float(np.linalg.norm(ego.p_WB[:2] - goal[:2])) < 0.5
        steady = float(np.linalg.norm(ego.v_WB)) < 0.3
        if phase == "climb" and near and abs(float(ego.p_WB[2] - goal[2])) < 0.5 and steady:
            self.abort_phase, self._steady_since = "hold", t
        elif phase == "hold":
            if not (near and steady):
                self._steady_since = None
            elif self._steady_since is None:
                self._steady_since = t
            if self._steady_since is not None and t - self._steady_since >= cfg.abort_hover_s:
                self.abort_phase = "done"
        elif phase == "transit" and near and float(np.linalg.norm(ego.v_WB[:2])) < 0.5:
            self.abort_phase = "descend"
            self.abort_goal_W = np.array([goal[0], goal[1], float(self.takeoff_point_W[2])])
        elif phase == "descend" and touchdown:
            self.abort_phase = "done"
        if self.abort_phase != phase:
            kind = "final_action_complete" if self.abort_phase == "done" else "final_action"
            self._event(t, kind, f"{cfg.final_action}: {self.abort_phase}")
            self.final_action_complete = self.abort_phase == "done"
