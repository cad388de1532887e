"""Guidance: what each mission mode flies, as a reference trajectory for the controller.

- take-off: a rest-to-rest minimum-jerk primitive to the hover point (paper 000 Sec. II-F.1);
- exploration: the coverage pattern of the search area (Sec. II-F.2);
- tracking: candidate primitives to the platform's predicted states, the cheapest feasible one kept,
  replanned at the planner's rate (Sec. II-D, II-F.3);
- landing: match the platform in x, y (position, velocity, acceleration from its estimate) while
  descending at a set vertical speed (Sec. II-F.4);
- search (target lost, coast over): a spiral centred on the platform's *predicted* position, flown
  relative to that moving prediction, whose radius grows with the prediction's uncertainty (3 standard
  deviations of its position plus ``search_speed_uncertainty_mps`` times the time since the last
  sighting), at the exploration altitude; with ``max_platform_speed_mps`` the centre stops following the
  prediction once its 3 standard deviations outgrow the square the platform can have reached since it
  was last seen, and a later exploration covers that square, spiralling out from the last sighting;
- descent hold: while the mission says a descent gate is marginal, the descent pauses at its height and
  keeps matching the platform;
- go-around: keep matching the platform while climbing back to the tracking height above it;
- abort: the mission's final action: climb and hold, fly home at the exploration altitude and descend
  there, or descend in place; each descent continues below the surface so that the onboard land
  detector, not the guidance, ends it.

In take-off and exploration the camera, not the body, follows the reference ("aiming"): a vehicle holding
its position against a steady side force (wind) tilts into it, and its body-fixed downward camera then
looks ``h tan(tilt)`` downwind; at 12 m in paper 004's 12 m/s gusts that is ~8 m, and a platform passing
just upwind of the take-off point is never in view. The reference is shifted upwind by that much: the
side force is the part of the tilt that the vehicle's measured acceleration does not explain, low-passed.

Replanning (``update``) and sampling (``reference``) are separate so that the planner can run at 50 Hz
while the controller samples the current plan at its own rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field
from pydantic.dataclasses import dataclass as pydantic_dataclass

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.state_machine import Mission, MissionConfig, position_std_m
from alight.planning.candidates import CandidatePlanner, PlanResult, PlanStatus, sample_end_times
from alight.planning.envelope import (
    adaptive_horizon,
    horizontal_speed_limit,
    intercept_time,
    search_half_width,
)
from alight.planning.exploration import (
    ExplorationRoute,
    footprint_width_m,
    lawnmower_waypoints,
    ring_waypoints,
    spiral_waypoints,
)
from alight.planning.min_jerk import MinJerkTrajectory
from alight.settings import SETTINGS, FiniteFloat, NonNegFloat, PositiveFloat
from alight.types import GRAVITY_MPS2, EgoState, FloatArray, Mode, PlatformEstimate, Reference, wrap_angle

if TYPE_CHECKING:
    from alight.estimation import PlatformEstimator

_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)
_AIMED_MODES = (Mode.TAKEOFF, Mode.EXPLORE)
_SCAN_MODES = (Mode.TAKEOFF, Mode.EXPLORE, Mode.SEARCH)


@pydantic_dataclass(frozen=True, kw_only=True, config=SETTINGS)
class GuidanceConfig:
    search_area: tuple[float, float, float, float] = (-20.0, 20.0, -20.0, 20.0)
    """x_min, x_max, y_min, y_max of the area to explore (m)."""
    camera_fov_rad: float = math.radians(64.0)
    """Narrower field of view of the downward camera; it sets the spacing of the coverage rows (rad)."""
    coverage_overlap: float = 0.2
    """Fraction of the camera footprint shared by neighbouring rows."""
    cruise_speed_mps: float = 4.0
    """Speed of point-to-point moves (take-off, abort, exploration legs) (m/s)."""
    search_pattern: Literal["spiral", "lawnmower"] = "spiral"
    """``spiral`` (outward from the take-off point) or ``lawnmower`` (rows from the nearest corner)."""
    climb_speed_mps: float = 1.0
    """Vertical speed of a go-around (m/s)."""
    takeoff_climb_speed_mps: PositiveFloat | None = None
    """Peak vertical speed of the take-off climb (m/s); None: half ``cruise_speed_mps``."""
    max_climb_accel_mps2: float = 0.5 * (DEFAULT_AIRFRAME.thrust_to_weight - 1.0) * GRAVITY_MPS2
    """Largest vertical acceleration the take-off climb is planned with (m/s^2): half the airframe's
    spare thrust, leaving the other half to the position loop."""
    land_floor_below_pad_m: float = 0.3
    """The descent's reference keeps going this far below the pad surface, so the vehicle keeps sinking
    until the range finder stops the motors rather than hovering just above the pad (m)."""
    yaw: float = 0.0
    """Heading at take-off (rad); held throughout unless ``scan_yaw_rate_rad_s`` or the weathervane
    (``weathervane_min_tilt_rad``) turns it."""
    scan_yaw_rate_rad_s: Annotated[float, Field(ge=-3.0, le=3.0, allow_inf_nan=False)] = 0.0
    """Turn the heading at this rate (rad/s) while nothing is in view (take-off, exploration, search), so
    that the camera's wide axis sweeps round; the heading reached is held in every other mode. A
    downward camera's view is a rectangle (~90 x 64 deg: 12 x 7.5 m half-widths at 12 m), and a platform
    passing the take-off point 8 m away along the narrow side is never in view with a fixed heading. 0:
    the fixed heading of the papers."""
    weathervane_min_tilt_rad: Annotated[float, Field(ge=0.0, lt=1.5, allow_inf_nan=False)] | None = None
    """Turn the heading, outside the scan, so that the camera's wider field of view lies along the
    vehicle's steady lean against wind and drag (the side force per unit mass, low-passed; not the lean
    spent on its own acceleration) once that lean exceeds this tilt (rad). A vehicle holding against 12 m/s of
    wind leans 22-26 deg (the Matrice 100); along the view's narrow side (32 deg half-view for paper
    000's camera) that puts the point below the vehicle near the image edge and the pad leaves the view
    in every gust, along the wide side (45 deg) it stays in. PX4's weathervane turns the nose into the
    wind for the same reason a fixed-wing does; here the camera's axis sets which way. None: off (the
    papers' fixed heading)."""
    wide_view_axis_B_rad: FiniteFloat = 0.0
    """Direction of the camera's wider field of view in the body's xy plane (rad, from body x toward body
    y); the preset builder derives it from the camera model and its mount. Only its direction modulo pi
    matters."""
    weathervane_yaw_rate_rad_s: PositiveFloat = 0.5
    """Largest turn rate of the weathervane (rad/s)."""
    weathervane_time_constant_s: PositiveFloat = 2.0
    """Low-pass time constant of the lean the weathervane follows (s): long enough that a manoeuvre or a
    gust does not swing the heading, short enough to follow a wind that turns."""
    search_expansions: int = 2
    """After a full pass over the search area without a sighting, search a ring around it this many times
    (a moving platform that was not found has most likely driven out of the area)."""
    search_growth_m: float = 20.0
    """Each expansion grows the searched area by this much on every side (m)."""
    aim_camera: bool = True
    """Shift the take-off and exploration references upwind so that the downward camera's optical axis,
    not the body, follows them (see the module docstring)."""
    aim_time_constant_s: PositiveFloat = 1.5
    """Low-pass time constant of the tilt that sets the aiming offset (s): long enough to average out the
    vehicle's own manoeuvres, short enough to follow paper 004's 5.5 s gust steps."""
    aim_max_tan_tilt: NonNegFloat = 1.0
    """Largest tilt tangent the aiming offset uses (45 deg)."""
    search_speed_uncertainty_mps: NonNegFloat = 1.0
    """Growth of the search radius around the predicted platform per second since the last sighting
    (m/s): how fast the platform may drift from its prediction (a speed or heading change unseen)."""
    search_max_radius_m: float = 30.0
    """Largest radius of the search around the prediction (m)."""
    abort_descent_speed_mps: float = 1.0
    """Vertical speed of a final action's descent down to ``abort_slow_height_m`` (m/s) ..."""
    abort_slow_height_m: float = 2.0
    """... below which it descends at the mission's landing speed (m)."""

    intercept: bool = False
    """Fly to meet the platform's predicted path where the vehicle can first be (an intercept point,
    ahead of a fast platform) rather than chase its predicted positions over the fixed horizon
    (planning/envelope.py). Off: paper 000's tracking."""
    adaptive_horizon: bool = False
    """Size the candidates' horizon from the distance to cover and the airframe's acceleration (and the
    intercept time) instead of the planner's fixed ``[horizon_min_s, horizon_max_s]``."""
    no_feasible: Literal["keep", "extend"] = "keep"
    """When no candidate is feasible: ``keep`` the plan being flown (paper 000), or ``extend``: plan again
    with the horizon doubled, up to three times, and if still none fly the longest candidate with the
    controller clipping its inputs (planning/README.md)."""
    max_tilt_rad: Annotated[float, Field(gt=0, lt=math.pi / 2, allow_inf_nan=False)] = (
        DEFAULT_AIRFRAME.max_tilt_rad
    )
    """The airframe's tilt limit (rad): with the rotor drag, its top speed and horizontal acceleration."""
    rotor_drag_per_s: float = DEFAULT_AIRFRAME.rotor_drag[0]
    """The airframe's horizontal mass-normalised rotor drag (1/s)."""
    speed_margin: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = 0.7
    """Fraction of the airframe's top speed and horizontal acceleration the intercept is planned with,
    leaving the rest to the position loop."""
    max_speed_mps: PositiveFloat = 15.0
    """Cap on the intercept speed (m/s), whatever the airframe could do."""
    track_view_sigmas: NonNegFloat | None = None
    """Track no lower than the height at which the camera's narrower half-view spans this many standard
    deviations of the platform estimate's horizontal position: an estimate from the platform's GNSS
    alone is off by the receiver's bias (about 1 m per axis), and tracking it at the usual 2 m puts the
    pad beside a 1.2 m half-view, where the camera never sees it and the bias is never learned. Once the
    camera has the pad, the standard deviation is centimetres and this binds no more. None: off (the
    papers' tracking height rule alone)."""
    max_platform_speed_mps: NonNegFloat | None = None
    """The fastest the platform may drive (m/s): the initial search area grows by this much per second
    since take-off on every side; once the platform was seen, an exploration covers the square it can
    have reached since its last sighting (faster if it was seen faster), and the search spiral stops
    following a prediction whose uncertainty has outgrown that square. None: the fixed ``search_area``
    and a search that follows the prediction."""


def _rest_to_rest(
    t0: float, p0: FloatArray, v0: FloatArray, pf: FloatArray, speed: float, max_accel: float = math.inf
) -> MinJerkTrajectory:
    # A rest-to-rest minimum-jerk move peaks at 1.875 d / T in speed and at 10 / sqrt(3) d / T^2 in
    # acceleration; pick the shortest T that keeps both within their limits.
    d = float(np.linalg.norm(pf - p0))
    T = max(1.5, 1.875 * d / speed, math.sqrt(10.0 / math.sqrt(3.0) * d / max_accel))
    return MinJerkTrajectory.from_boundary(t0, T, p0, v0, _ZERO3, pf, _ZERO3, _ZERO3)


def _platform_jerk(target: PlatformEstimate) -> FloatArray:
    """Horizontal jerk of a platform turning at a constant rate (m/s^3): its acceleration rotates with
    the heading, j = w x a with the turn rate w = (v x a)_z / |v|^2. It is the jerk feed-forward of the
    descent, which the controller turns into body rates; without it the vehicle lags a turning pad."""
    vx, vy = float(target.v_WP[0]), float(target.v_WP[1])
    ax, ay = float(target.a_WP[0]), float(target.a_WP[1])
    speed2 = vx * vx + vy * vy
    if speed2 < 0.01:
        return _ZERO3
    w = (vx * ay - vy * ax) / speed2
    return np.array([-w * ay, w * ax, 0.0])


_VelocitySample = tuple[float, float, float, float]


def _side_force_over_g(
    t: float, ego: EgoState, prev: _VelocitySample | None
) -> tuple[_VelocitySample, tuple[float, float, float] | None]:
    """The horizontal side force per unit mass over g that the thrust holds against (wind, drag): the
    tilt not spent on the vehicle's own acceleration, that acceleration measured by differencing the
    estimated velocity since ``prev``. Returns this call's velocity sample (the next call's ``prev``)
    and ``(dt, f_x / (m g), f_y / (m g))``, or None when upside down, not finite, or without a velocity
    sample from the last 0.5 s."""
    x, y, z, w = ego.q_WB.tolist()
    zb_x, zb_y, zb_z = 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)
    vx, vy, vz = ego.v_WB.tolist()
    sample = (t, vx, vy, vz)
    if not zb_z > 0.2 or prev is None or not 0.0 < t - prev[0] <= 0.5:
        return sample, None
    dt = t - prev[0]
    ax, ay, az = (vx - prev[1]) / dt, (vy - prev[2]) / dt, (vz - prev[3]) / dt
    # The thrust direction is (a - f/m + g e3) / |.|, so the side force per unit mass over g is
    # tan(tilt) (1 + a_z / g) - a_xy / g.
    scale = (1.0 + az / GRAVITY_MPS2) / zb_z
    return sample, (dt, zb_x * scale - ax / GRAVITY_MPS2, zb_y * scale - ay / GRAVITY_MPS2)


def _peak_vertical_accel(traj: MinJerkTrajectory) -> float:
    """Largest |vertical acceleration| of a primitive, sampled at 17 points (m/s^2): a quintic's
    acceleration is a cubic, whose extremes a grid of this density finds within a few per cent."""
    return max(abs(float(traj.sample_packed(tk)[2, 2])) for tk in np.linspace(traj.t0, traj.t_end, 17))


class _SplitAxes:
    """A reference whose horizontal axes follow one primitive and whose height follows another.

    Why: a long intercept primitive (tens of seconds) shares its duration across the axes, and from a
    climbing start a minimum-jerk height profile over that long a time overshoots by about the initial
    climb rate times the duration (from 2 m/s over 20 s: 16 m above its goal). The height gets its own
    short primitive to the planned end height instead."""

    def __init__(self, xy: MinJerkTrajectory, z: MinJerkTrajectory) -> None:
        self.xy, self.z = xy, z
        self.t_end = xy.t_end

    def sample(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        pvaj = self.sample_packed(t)
        return pvaj[0], pvaj[1], pvaj[2], pvaj[3]

    def sample_packed(self, t: float) -> FloatArray:
        out = self.xy.sample_packed(t)
        out[:, 2] = self.z.sample_packed(t)[:, 2]
        return out


@dataclass(frozen=True, slots=True)
class _Sighting:
    """The platform where it was last measured."""

    t: float
    """Time of the measurement (s)."""
    p_xy: tuple[float, float]
    """The estimate's horizontal position at that time (m, W)."""
    half_width_m: float
    """3 standard deviations of that position (m)."""
    speed_mps: float
    """The estimate's horizontal speed at that time (m/s)."""


class Guidance:
    """Turns the mission mode and the estimates into a reference trajectory."""

    def __init__(
        self,
        mission_config: MissionConfig,
        planner: CandidatePlanner,
        config: GuidanceConfig | None = None,
    ) -> None:
        self.mission_config = mission_config
        self.planner = planner
        self.config = config or GuidanceConfig()
        self._mode: Mode | None = None
        self._traj: MinJerkTrajectory | _SplitAxes | None = None
        self._plan: MinJerkTrajectory | None = None
        self._route: ExplorationRoute | None = None
        self._expansions = 0
        self._hold: Reference | None = None
        self._mode_t0 = 0.0
        self._z_entry = 0.0
        self._last_ref: Reference | None = None
        self._tilt_tan_lp = (0.0, 0.0)
        self._v_aim: _VelocitySample | None = None
        self._aim_W = np.zeros(3)
        self.plans_adopted = 0
        self._descent_hold = False
        self._z_land = 0.0
        self._t_land = 0.0
        self._theta = 0.0
        self._t_search = 0.0
        self._yaw = self.config.yaw
        self._t_yaw: float | None = None
        self._lean_lp = (0.0, 0.0)
        self._v_lean: _VelocitySample | None = None
        self._abort_phase = ""
        self._abort_xy = np.zeros(2)
        self._abort_ground_z = 0.0
        self.search_radius_m = 0.0
        """Radius of the search around the predicted platform at the last reference (m)."""
        self._t_start: float | None = None
        self._area = self.config.search_area
        self._area_centre: tuple[float, float] | None = None
        """Where the exploration's spiral starts when the area is around a sighting (None: at the vehicle)."""
        self._sighting: _Sighting | None = None
        self._search_centre: tuple[float, float] | None = None
        """Where the search spiral holds its centre once the prediction says less than the speed bound
        (None: it follows the prediction)."""
        self.t_intercept_s: float | None = None
        """Time from the last replanning to the intercept point (s), None when not computed."""
        self.plans_extended = 0
        """Replannings that needed a longer horizon to find a feasible candidate."""
        self.plans_clipped = 0
        """Replannings that found none and flew the longest candidate unchecked."""

    @property
    def aim_offset_W(self) -> FloatArray:
        """Current aiming offset added to the take-off and exploration references (m), shape (3,)."""
        return self._aim_W.copy()

    def _update_aim(self, t: float, mode: Mode, ego: EgoState) -> None:
        """Low-pass the side force per unit mass and set the aiming offset from it. Only the aimed modes
        update it (it runs at the planner's rate, on scalars: this is in the simulator's hot loop); after
        a spell in another mode the filter restarts from its last value.

        The force is what the tilt does not spend on the vehicle's own acceleration, measured (the
        difference of the estimated velocity), not the reference's: the position loop's corrections tilt
        the vehicle too, and reading those as wind would move the reference further the same way, a
        loop that diverges (a 4 m/s pattern flown at 12 m/s)."""
        if not self.config.aim_camera or mode not in _AIMED_MODES:
            return
        self._v_aim, measured = _side_force_over_g(t, ego, self._v_aim)
        if measured is None:
            return  # upside down, not finite, or no recent velocity to difference: keep the offset
        dt, dx, dy = measured
        gain = dt / (self.config.aim_time_constant_s + dt)
        lx, ly = self._tilt_tan_lp
        lx, ly = lx + gain * (dx - lx), ly + gain * (dy - ly)
        if not (math.isfinite(lx) and math.isfinite(ly)):
            return
        self._tilt_tan_lp = (lx, ly)
        norm = math.hypot(lx, ly)
        cap = self.config.aim_max_tan_tilt
        k = max(float(ego.p_WB[2]), 0.0) * (cap / norm if norm > cap else 1.0)
        self._aim_W = np.array([k * lx, k * ly, 0.0])

    # ------------------------------------------------------------------------------------------------
    def update(
        self,
        t: float,
        mode: Mode,
        ego: EgoState,
        target: PlatformEstimate | None,
        estimator: PlatformEstimator | None,
        hover_point_W: FloatArray,
        mission: Mission | None = None,
    ) -> None:
        """Replan for ``mode`` at time ``t`` (called at the planner's rate). ``mission``: the state
        machine, for its descent hold and its final action's phase and goal."""
        self._update_aim(t, mode, ego)
        self._update_lean(t, ego)
        if self._t_start is None:
            self._t_start = t
        self._descent_hold = mission is not None and mission.descent_hold
        if target is not None:
            self._note_sighting(target)
        entered = mode is not self._mode
        if entered:
            if mode is Mode.EXPLORE:
                self._area, self._area_centre = self._search_area(t, target)
            self._enter(t, mode, ego, hover_point_W)
        if mode is Mode.ABORT and mission is not None and mission.abort_phase != self._abort_phase:
            self._enter_abort_phase(t, ego, mission.abort_phase, mission.abort_goal_W)
        elif (
            mode is Mode.EXPLORE
            and self._route is not None
            and self._expansions < self.config.search_expansions
            and self._route.done(t)
        ):
            self._expand_search(t, ego)
        if mode is Mode.TRACK and target is not None and estimator is not None:
            self._replan_tracking(t, ego, estimator, target)

    def _start_state(self, t: float, ego: EgoState) -> tuple[FloatArray, FloatArray, FloatArray]:
        # Continue from the reference being flown, sampled at t (a smooth command), unless the vehicle is
        # far from it (after a mode change or a disturbance): then restart from the estimate. Sampling at
        # t matters: restarting from the last command's reference (up to one control period old) would
        # set the plan back by v * period at every replanning and make it trail the platform.
        # What is returned is the state flown, the aiming offset included.
        ref: tuple[FloatArray, FloatArray, FloatArray] | None = None
        aimed = self._aim_W if self._mode in _AIMED_MODES else _ZERO3
        if self._traj is not None:
            p_t, v_t, a_t, _ = self._traj.sample(t)
            ref = (p_t + aimed, v_t, a_t)
        elif self._route is not None:
            p_t, v_t, a_t, _ = self._route.reference(t)
            ref = (p_t + aimed, v_t, a_t)
        elif self._last_ref is not None:
            ref = (self._last_ref.p, self._last_ref.v, self._last_ref.a)
        if ref is not None:
            p, v, a = ref
            if np.linalg.norm(p - ego.p_WB) < 0.5 and np.linalg.norm(v - ego.v_WB) < 1.0:
                return p, v, a
            return ego.p_WB, ego.v_WB, a
        return ego.p_WB, ego.v_WB, _ZERO3

    def _enter(self, t: float, mode: Mode, ego: EgoState, hover_point_W: FloatArray) -> None:
        cfg, mcfg = self.config, self.mission_config
        p0, v0, _ = self._start_state(t, ego)  # from the previous mode's reference
        self._mode, self._mode_t0, self._z_entry = mode, t, float(ego.p_WB[2])
        self._traj, self._route, self._plan = None, None, None
        if mode in _AIMED_MODES:
            p0 = p0 - self._aim_W  # the aimed references are flown with the offset added
        if mode is Mode.TAKEOFF:
            climb = cfg.takeoff_climb_speed_mps
            if climb is None:
                climb = cfg.cruise_speed_mps / 2
            self._traj = _rest_to_rest(
                t, ego.p_WB - self._aim_W, _ZERO3, np.asarray(hover_point_W, float), climb,
                cfg.max_climb_accel_mps2,
            )  # fmt: skip
        elif mode is Mode.EXPLORE:
            self._expansions = 0
            x0, x1, y0, y1 = self._area
            spacing = footprint_width_m(mcfg.explore_altitude_m, cfg.camera_fov_rad, cfg.coverage_overlap)
            if cfg.search_pattern == "spiral":
                # around the last sighting the platform is likeliest near it: spiral out from there
                centre = p0[:2] if self._area_centre is None else np.array(self._area_centre)
                waypoints = spiral_waypoints(
                    x0, x1, y0, y1, mcfg.explore_altitude_m, spacing, center_xy=centre
                )
            else:
                waypoints = lawnmower_waypoints(
                    x0, x1, y0, y1, mcfg.explore_altitude_m, spacing, start_xy=p0[:2]
                )
            self._route = ExplorationRoute(
                waypoints, t0=t, p0=p0, v0=v0, cruise_speed_mps=cfg.cruise_speed_mps
            )
        elif mode is Mode.TRACK:
            self.planner.reset()
        elif mode is Mode.LAND:
            self._z_land, self._t_land = float(ego.p_WB[2]), t
        elif mode is Mode.SEARCH:
            self._theta, self._t_search, self.search_radius_m = 0.0, t, 0.0
            self._search_centre = None
        elif mode is Mode.ABORT:
            self._abort_phase = ""
            goal = np.array([p0[0], p0[1], max(mcfg.explore_altitude_m, float(p0[2]))])
            self._traj = _rest_to_rest(t, p0, v0 * 0.0, goal, cfg.cruise_speed_mps / 2)

    def _enter_abort_phase(self, t: float, ego: EgoState, phase: str, goal_W: FloatArray) -> None:
        """A new phase of the final action: a rest-to-rest move to its goal (climb, transit), or a
        descent at the goal (``descend``), sampled in :meth:`reference`."""
        self._abort_phase = phase
        p0, v0, _ = self._start_state(t, ego)
        if phase in ("climb", "transit"):
            self._traj = _rest_to_rest(t, p0, v0, np.asarray(goal_W, float), self.config.cruise_speed_mps / 2)
        elif phase == "descend":
            self._traj = None
            self._z_land, self._t_land = float(p0[2]), t
            self._abort_xy = np.asarray(goal_W, float)[:2].copy()
            self._abort_ground_z = float(goal_W[2])

    def _expand_search(self, t: float, ego: EgoState) -> None:
        """The next ring around the search area (``search_growth_m`` wide), flown in loops."""
        cfg, mcfg = self.config, self.mission_config
        self._expansions += 1
        x0, x1, y0, y1 = self._area
        spacing = footprint_width_m(mcfg.explore_altitude_m, cfg.camera_fov_rad, cfg.coverage_overlap)
        growth = cfg.search_growth_m
        if cfg.max_platform_speed_mps is not None and self._route is not None:
            # the platform kept driving while the last pass was flown: the ring is that much wider
            growth = max(growth, cfg.max_platform_speed_mps * (t - self._route.approach.t0))
        waypoints = ring_waypoints(
            x0, x1, y0, y1,
            growth * (self._expansions - 1), growth * self._expansions,
            mcfg.explore_altitude_m, spacing,
        )  # fmt: skip
        p0, v0, _ = self._start_state(t, ego)
        self._route = ExplorationRoute(
            waypoints, t0=t, p0=p0 - self._aim_W, v0=v0, cruise_speed_mps=cfg.cruise_speed_mps
        )

    def _note_sighting(self, target: PlatformEstimate) -> None:
        """Keep where the platform was at its last measurement (the estimate taken back to that time) and
        how sure the estimate was there, for the reachable set of :meth:`_reach_m`."""
        if self.config.max_platform_speed_mps is None:
            return
        t_meas = target.t_last_measurement
        if not math.isfinite(t_meas) or (self._sighting is not None and t_meas <= self._sighting.t):
            return
        age = max(target.t - t_meas, 0.0)
        x = float(target.p_WP[0] - target.v_WP[0] * age)
        y = float(target.p_WP[1] - target.v_WP[1] * age)
        half = 3.0 * position_std_m(target)
        speed = math.hypot(float(target.v_WP[0]), float(target.v_WP[1]))
        if all(math.isfinite(a) for a in (x, y, half, speed)):
            self._sighting = _Sighting(t_meas, (x, y), half, speed)

    def _reach_m(self, t: float) -> float:
        """Half-width (m) of the square around the last sighting that the platform cannot have left by
        ``t``: 3 standard deviations there plus the fastest speed x the time since (planning/envelope.py).
        The fastest speed is ``max_platform_speed_mps``, or the speed the platform was seen at when that is
        more (the configured bound is a prior; a platform seen faster has shown it wrong). Needs
        ``max_platform_speed_mps`` and a sighting."""
        assert self._sighting is not None and self.config.max_platform_speed_mps is not None
        s = self._sighting
        v_max = max(self.config.max_platform_speed_mps, s.speed_mps)
        return search_half_width(s.half_width_m, t - s.t, v_max)

    def _search_area(
        self, t: float, target: PlatformEstimate | None
    ) -> tuple[tuple[float, float, float, float], tuple[float, float] | None]:
        """The area to explore from ``t`` and where its spiral starts (None: at the vehicle): the configured
        area, or with ``max_platform_speed_mps`` the area the platform can have reached: the configured
        area grown by speed x time since take-off (planning/envelope.py), or, once the platform was seen,
        the square around where it was last seen of half-width 3 standard deviations there plus speed x
        time since (:meth:`_reach_m`), spiralling out from that sighting.

        Not around the *predicted* position: after a long loss the prediction is a straight or circular
        extrapolation of a few seconds of tracking, tens of metres from a platform that turned (a
        figure-8's other lobe), and its own covariance says so (3 sigma in the hundreds of metres); the
        speed bound around the last sighting is the tighter of the two, and it is certain."""
        cfg = self.config
        v = cfg.max_platform_speed_mps
        if v is None:
            return cfg.search_area, None
        x0, x1, y0, y1 = cfg.search_area
        if self._sighting is not None:
            half = max(
                self._reach_m(t),
                0.5 * footprint_width_m(self.mission_config.explore_altitude_m, cfg.camera_fov_rad),
            )
            cx, cy = self._sighting.p_xy
            x0, x1, y0, y1 = cx - half, cx + half, cy - half, cy + half
            return (x0, x1, y0, y1), (0.5 * (x0 + x1), 0.5 * (y0 + y1))  # the area's centre, as the spiral's
        if target is not None:  # no sighting kept: the estimate carries no finite measurement time
            half = search_half_width(3.0 * position_std_m(target), t - target.t_last_measurement, v)
            cx, cy = float(target.p_WP[0]), float(target.p_WP[1])
            return (cx - half, cx + half, cy - half, cy + half), None
        grow = search_half_width(0.0, t - (self._t_start if self._t_start is not None else t), v)
        return (x0 - grow, x1 + grow, y0 - grow, y1 + grow), None

    def _track_height(self, t: float, ego: EgoState, target: PlatformEstimate, initialized: bool) -> float:
        """Height above the pad to track at (m).

        - Far from the platform the vehicle stays higher (half a metre more per metre of horizontal
          distance beyond 2 m), so the platform stays in the downward camera's view during the approach.
        - While the target is unseen it climbs toward the exploration altitude, widening the footprint
          around the predicted position before the mission gives up and explores again (target lost).
        - Until the estimator knows the platform's heading and speed (a first brief sighting), it holds
          its height over the last sighting instead of diving at a position that is already stale.
        """
        mcfg = self.mission_config
        above_pad = float(ego.p_WB[2] - target.p_WP[2])
        top = max(mcfg.explore_altitude_m - float(target.p_WP[2]), mcfg.track_height_m)
        floor = min(self._view_height(target), top)
        if not initialized:
            return max(min(max(above_pad, mcfg.track_height_m), top), floor)
        distance = float(np.hypot(*(ego.p_WB[:2] - target.p_WP[:2])))
        height = mcfg.track_height_m + 0.5 * max(distance - 2.0, 0.0)
        age = t - target.t_last_measurement
        grace = 0.5  # s: a few missed frames are normal
        frac = min(max((age - grace) / max(mcfg.lost_timeout_s - grace, 1e-3), 0.0), 1.0)
        return max(min(height + frac * top, top), floor)

    def _view_height(self, target: PlatformEstimate) -> float:
        """The height above the pad at which the narrower half-view spans ``track_view_sigmas`` standard
        deviations of the estimate's horizontal position (m); 0 when the rule is off."""
        k = self.config.track_view_sigmas
        if k is None:
            return 0.0
        return k * position_std_m(target) / math.tan(0.5 * self.config.camera_fov_rad)

    def _replan_tracking(
        self, t: float, ego: EgoState, estimator: PlatformEstimator, target: PlatformEstimate
    ) -> None:
        pcfg, cfg = self.planner.config, self.config
        lo, hi = pcfg.horizon_min_s, pcfg.horizon_max_s
        if (cfg.intercept or cfg.adaptive_horizon) and estimator.initialized:
            lo, hi = self._horizon(t, ego, estimator)
        times = sample_end_times(t, pcfg.n_candidates, lo, hi)
        height = self._track_height(t, ego, target, estimator.initialized)
        p0, v0, a0 = self._start_state(t, ego)
        result = self._plan_to(t, times, estimator, target, height, p0, v0, a0)
        if result.status is PlanStatus.NO_FEASIBLE and cfg.no_feasible == "extend":
            for k in (1, 2, 3):
                longer = t + (times - t) * 2.0**k
                result = self._plan_to(t, longer, estimator, target, height, p0, v0, a0)
                if result.status is not PlanStatus.NO_FEASIBLE:
                    self.plans_extended += 1
                    break
            else:
                # Nothing feasible even over 8x the horizon: fly the longest candidate (the gentlest)
                # and let the controller clip its thrust and tilt, rather than fly out a stale plan that
                # loses the platform (planning/README.md).
                self.plans_clipped += 1
                p_pred, v_pred, a_pred, _ = self._predict(estimator, target, longer[-1:])
                pf = p_pred[0] + np.array([0.0, 0.0, height])
                af = a_pred[0] if pcfg.end_constraint.name == "POS_VEL_ACC" else _ZERO3
                T = float(longer[-1] - t)
                plan = MinJerkTrajectory.from_boundary(t, T, p0, v0, a0, pf, v_pred[0], af)
                self._plan = plan
                self._traj = self._split_vertical(t, plan, p0, v0, a0)
                self.planner.reset()
                return
        if result.trajectory is not None:
            if result.trajectory is not self._plan:
                self.plans_adopted += 1
                self._plan = result.trajectory
                self._traj = self._split_vertical(t, result.trajectory, p0, v0, a0)

    def _split_vertical(
        self, t: float, plan: MinJerkTrajectory, p0: FloatArray, v0: FloatArray, a0: FloatArray
    ) -> MinJerkTrajectory | _SplitAxes:
        """With ``intercept``, a plan longer than the climb to its end height gets its own height profile
        (:class:`_SplitAxes`); otherwise the plan as it is (paper 000's behaviour)."""
        if not self.config.intercept:
            return plan
        z_end = float(plan.sample(plan.t_end)[0][2])
        pf = np.array([p0[0], p0[1], z_end])
        T_z = max(2.0, 2.0 * abs(z_end - float(p0[2])) / self.config.cruise_speed_mps)
        # Long enough that the height profile asks for no more vertical acceleration than the airframe
        # gives (the climb's limit, and half of g downward): from a 5 m/s climb toward a point 2 m below,
        # 2 s asks for -15 m/s^2, more than gravity gives with the motors idle; the vehicle cannot
        # follow, falls more than 1 m/s off the reference, each replanning restarts from its velocity,
        # and the reference keeps climbing (envelope wind, seed 2469339022: 83 m up). No more than it
        # starts with either, when that is already beyond the limit.
        a_limit = max(min(self.config.max_climb_accel_mps2, 0.5 * GRAVITY_MPS2), abs(float(a0[2])))
        while True:
            if plan.t_end - t <= T_z:
                return plan  # the plan's own height profile is no shorter: fly it as it is
            z = MinJerkTrajectory.from_boundary(t, T_z, p0, v0, a0, pf, _ZERO3, _ZERO3)
            if _peak_vertical_accel(z) <= a_limit or T_z >= 30.0:
                return _SplitAxes(plan, z)
            T_z *= 1.5

    @staticmethod
    def _predict(
        estimator: PlatformEstimator, target: PlatformEstimate, times: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        if estimator.initialized:
            return estimator.predict_ahead(times)
        # only a position so far: go there and look
        p_pred = np.repeat(target.p_WP[None, :], times.size, axis=0)
        return p_pred, np.zeros_like(p_pred), np.zeros_like(p_pred), np.zeros(times.size)

    def _plan_to(
        self,
        t: float,
        times: FloatArray,
        estimator: PlatformEstimator,
        target: PlatformEstimate,
        height: float,
        p0: FloatArray,
        v0: FloatArray,
        a0: FloatArray,
    ) -> PlanResult:
        p_pred, v_pred, a_pred, _ = self._predict(estimator, target, times)
        p_end = p_pred + np.array([0.0, 0.0, height])
        floor_z = float(np.max(p_pred[:, 2])) + 0.5 * self.mission_config.track_height_m
        floor_z = min(floor_z, float(p0[2]) - 0.05, float(np.min(p_end[:, 2])) - 0.05)
        return self.planner.plan(t, p0, v0, a0, times, p_end, v_pred, floor_z=floor_z, a_end=a_pred)

    def _horizon(self, t: float, ego: EgoState, estimator: PlatformEstimator) -> tuple[float, float]:
        """The candidates' duration window (planning/envelope.py): from the distance to the intercept
        point (with ``intercept``) or to the platform, and the airframe's horizontal acceleration."""
        cfg, pcfg = self.config, self.planner.config
        top = horizontal_speed_limit(cfg.max_tilt_rad, cfg.rotor_drag_per_s)
        speed = min(cfg.max_speed_mps, cfg.speed_margin * top)
        # horizontal acceleration: the tilt limit, and what the thrust limit leaves beside gravity
        a_h = math.tan(cfg.max_tilt_rad) * GRAVITY_MPS2
        if pcfg.f_max > GRAVITY_MPS2:
            a_h = min(a_h, math.sqrt(pcfg.f_max**2 - GRAVITY_MPS2**2))
        a_h *= cfg.speed_margin
        grid = np.linspace(0.0, 60.0, 241)
        p, _, _, _ = estimator.predict_ahead(t + grid)
        # At the intercept speed from now on, no acceleration ramp: with a ramp (intercept_time's
        # accel_mps2 at 2 / 5.77 of a_h, what a minimum-jerk move's bell-shaped speed allows) the meeting
        # point lies so far ahead that the plan starts slowly and the vehicle falls 130 m behind a
        # 12 m/s platform (seed 1: in contact after 44 s instead of 27 s); when [T, 1.1 T] is too short
        # to be feasible the 'extend' rule doubles it.
        t_int = intercept_time(ego.p_WB[:2], grid, p[:, :2], speed) if cfg.intercept else None
        self.t_intercept_s = t_int
        if t_int is not None:
            k = min(int(np.searchsorted(grid, t_int)), grid.size - 1)
            distance = float(np.hypot(*(p[k, :2] - ego.p_WB[:2])))
        else:
            distance = float(np.hypot(*(p[0, :2] - ego.p_WB[:2])))
        return adaptive_horizon(distance, a_h, pcfg.horizon_min_s, pcfg.horizon_max_s, t_int)

    # ------------------------------------------------------------------------------------------------
    def reference(self, t: float, mode: Mode, target: PlatformEstimate | None) -> Reference:
        """The reference at time ``t`` (called at the controller's rate)."""
        cfg, mcfg = self.config, self.mission_config
        yaw, yaw_rate = self._heading(t, mode)
        ref: Reference
        if mode is Mode.SEARCH and target is not None:
            ref = self._search_reference(t, target, yaw, yaw_rate)
        elif mode is Mode.ABORT and self._abort_phase == "descend":
            z, vz = self._descend(t, self._abort_ground_z, mcfg.land_speed_mps, fast=True)
            p = np.array([self._abort_xy[0], self._abort_xy[1], z])
            ref = Reference.trusted(t, p, np.array([0.0, 0.0, vz]), _ZERO3, _ZERO3, yaw, yaw_rate)
        elif mode in (Mode.LAND, Mode.GO_AROUND) and target is not None:
            dt = t - self._mode_t0
            if mode is Mode.LAND:
                # the ramp pauses while the mission holds the descent (a marginal gate)
                z, vz = self._descend(t, float(target.p_WP[2]), mcfg.land_speed_mps, fast=False)
            else:
                z_goal = float(target.p_WP[2]) + mcfg.track_height_m
                z = min(self._z_entry + cfg.climb_speed_mps * dt, z_goal)
                vz = cfg.climb_speed_mps if z < z_goal else 0.0
            pvaj = np.empty((4, 3))
            pvaj[0, 0:2] = target.p_WP[0:2]
            pvaj[1, 0:2] = target.v_WP[0:2]
            pvaj[2, 0:2] = target.a_WP[0:2]
            pvaj[0, 2], pvaj[1, 2], pvaj[2, 2] = z, vz, 0.0
            pvaj[3] = _platform_jerk(target)
            ref = Reference.from_packed(t, pvaj, yaw, yaw_rate)
        elif self._route is not None and mode is Mode.EXPLORE:
            pvaj = self._route.reference_packed(t)  # a new array
            pvaj[0] += self._aim_W
            ref = Reference.from_packed(t, pvaj, yaw, yaw_rate)
        elif self._traj is not None:
            pvaj = self._traj.sample_packed(t)  # a new array
            if mode is Mode.TAKEOFF:
                pvaj[0] += self._aim_W
            ref = Reference.from_packed(t, pvaj, yaw, yaw_rate)
        elif self._last_ref is not None:
            r = self._last_ref
            ref = Reference.trusted(t, r.p, _ZERO3, _ZERO3, _ZERO3, yaw, yaw_rate)
        else:
            raise RuntimeError("guidance.reference called before update")
        self._last_ref = ref
        return ref

    def _descend(self, t: float, surface_z: float, speed_mps: float, *, fast: bool) -> tuple[float, float]:
        """Height and vertical speed of a descent ramp toward ``surface_z`` (m), continued
        ``land_floor_below_pad_m`` below it so that the vehicle keeps sinking until the land detector
        stops the motors; paused while the descent is held. ``fast``: descend at
        ``abort_descent_speed_mps`` down to ``abort_slow_height_m``."""
        cfg = self.config
        dt = max(t - self._t_land, 0.0)
        self._t_land = t
        z_floor = surface_z - cfg.land_floor_below_pad_m
        speed = speed_mps
        if fast and self._z_land - surface_z > cfg.abort_slow_height_m:
            speed = max(cfg.abort_descent_speed_mps, speed_mps)
        if self._descent_hold:
            return self._z_land, 0.0
        self._z_land = max(self._z_land - speed * dt, z_floor)
        return self._z_land, (-speed if self._z_land > z_floor else 0.0)

    def _update_lean(self, t: float, ego: EgoState) -> None:
        """Low-pass the side force per unit mass over g, for the weathervane: the lean the thrust keeps
        against wind and drag, not the part spent on the vehicle's own acceleration (a figure-8's turns
        would swing the heading: 20 -> 16 of 20 landed when the weathervane followed the raw lean).
        Measured as in :meth:`_update_aim`. Scalars only: it runs at the planner's rate."""
        if self.config.weathervane_min_tilt_rad is None:
            return
        self._v_lean, measured = _side_force_over_g(t, ego, self._v_lean)
        if measured is None:
            return  # upside down, not finite, or no recent velocity to difference: keep the lean
        dt, dx, dy = measured
        if not (math.isfinite(dx) and math.isfinite(dy)):
            return
        gain = dt / (self.config.weathervane_time_constant_s + dt)
        lx, ly = self._lean_lp
        self._lean_lp = (lx + gain * (dx - lx), ly + gain * (dy - ly))

    def weathervane_goal(self) -> float | None:
        """The heading (rad) that puts the camera's wider view along the filtered side force, the nearer
        of the two that do (they differ by pi), or None while that force is below the tangent of
        ``weathervane_min_tilt_rad`` times g (or the weathervane is off)."""
        cfg = self.config
        if cfg.weathervane_min_tilt_rad is None:
            return None
        lx, ly = self._lean_lp
        if math.hypot(lx, ly) <= math.tan(cfg.weathervane_min_tilt_rad):
            return None
        goal = math.atan2(ly, lx) - cfg.wide_view_axis_B_rad
        error = wrap_angle(goal - self._yaw)
        if error > 0.5 * math.pi:
            error -= math.pi
        elif error <= -0.5 * math.pi:
            error += math.pi
        return wrap_angle(self._yaw + error)

    def _heading(self, t: float, mode: Mode) -> tuple[float, float]:
        """Heading (rad) and heading rate (rad/s) of the reference at ``t``: turning at
        ``scan_yaw_rate_rad_s`` in the modes where nothing is in view; in the others turning toward the
        weathervane's goal at most at ``weathervane_yaw_rate_rad_s`` when it has one, else held."""
        dt = 0.0 if self._t_yaw is None else max(t - self._t_yaw, 0.0)
        self._t_yaw = t
        rate = self.config.scan_yaw_rate_rad_s if mode in _SCAN_MODES else 0.0
        if rate != 0.0:
            self._yaw = wrap_angle(self._yaw + rate * dt)
            return self._yaw, rate
        goal = self.weathervane_goal()
        if goal is None or dt <= 0.0:
            return self._yaw, 0.0
        limit = self.config.weathervane_yaw_rate_rad_s
        step = min(max(wrap_angle(goal - self._yaw), -limit * dt), limit * dt)
        self._yaw = wrap_angle(self._yaw + step)
        return self._yaw, step / dt

    def _search_reference(self, t: float, target: PlatformEstimate, yaw: float, yaw_rate: float) -> Reference:
        """The spiral around the predicted platform (module docstring): its centre moves with the
        prediction, its radius grows at one pitch per turn up to the uncertainty radius, and its angle
        advances so that the vehicle moves at the cruise speed relative to the centre."""
        cfg, mcfg = self.config, self.mission_config
        dt = max(t - self._t_search, 0.0)
        self._t_search = t
        lost_s = max(t - target.t_last_measurement, 0.0)
        limit = min(
            3.0 * position_std_m(target) + cfg.search_speed_uncertainty_mps * lost_s, cfg.search_max_radius_m
        )
        pitch = footprint_width_m(mcfg.explore_altitude_m, cfg.camera_fov_rad, cfg.coverage_overlap)
        rho = min(pitch * self._theta / (2.0 * math.pi), limit)
        w = cfg.cruise_speed_mps / max(rho, 0.5 * pitch)
        self._theta += w * dt
        rho = min(pitch * self._theta / (2.0 * math.pi), limit)
        self.search_radius_m = rho
        c, s = math.cos(self._theta), math.sin(self._theta)
        z_goal = mcfg.explore_altitude_m
        z = min(self._z_entry + cfg.climb_speed_mps * (t - self._mode_t0), z_goal)
        vz = cfg.climb_speed_mps if z < z_goal else 0.0
        cx, cy, vcx, vcy = self._search_centre_at(t, target)
        p = np.array([cx + rho * c, cy + rho * s, z])
        v = np.array([vcx - rho * w * s, vcy + rho * w * c, vz])
        return Reference.trusted(t, p, v, _ZERO3, _ZERO3, yaw, yaw_rate)

    def _search_centre_at(self, t: float, target: PlatformEstimate) -> tuple[float, float, float, float]:
        """Centre of the search spiral and its velocity (m, m/s): the prediction, until the prediction's
        3 standard deviations outgrow the square the platform cannot have left since it was last seen
        (:meth:`_reach_m`, with ``max_platform_speed_mps``). From then on the centre holds where it is:
        the extrapolation says less than the speed bound, and following it on (a figure-8 platform
        predicted straight on at 5 m/s) leads the search 100 m away from a platform that turned back."""
        if self._search_centre is None and self._sighting is not None:
            if 3.0 * position_std_m(target) > self._reach_m(t):
                self._search_centre = (float(target.p_WP[0]), float(target.p_WP[1]))
        if self._search_centre is not None:
            return self._search_centre[0], self._search_centre[1], 0.0, 0.0
        return float(target.p_WP[0]), float(target.p_WP[1]), float(target.v_WP[0]), float(target.v_WP[1])
