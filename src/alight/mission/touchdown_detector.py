"""The onboard land detector: decides from what the vehicle senses that it stands on the deck, and when
to stop its motors.

A real vehicle does not know the truth of its contact; it has an accelerometer, a range finder with a
blind zone, its own vertical speed estimate and the thrust it commands. This block follows PX4's
multicopter land detector (``MulticopterLandDetector``: ground contact, then maybe-landed, then landed,
each a condition held for a time) in three states:

``AIRBORNE``
    until *ground contact*: no vertical motion relative to the platform (ego estimate, and the platform
    estimate's vertical velocity when there is one) **and** evidence of a surface under the feet (an
    impact on the accelerometer within the last ``impact_memory_s``, a valid range reading below
    ``range_floor_m`` (not the sensor's "too close", ``-inf`` in ROS REP 117), or a commanded thrust
    below ``held_thrust_fraction`` of hover that does not make the vehicle sink),
    unless a valid range reading above ``airborne_range_m`` says the vehicle is in the air, held for
    ``ground_contact_s``.
``GROUND_CONTACT``
    the thrust is spooled down (:meth:`thrust_scale`, a ramp to zero over ``spool_down_s``) and the
    attitude levelled (:meth:`level_rates`), as PX4 lowers its thrust and drops the horizontal thrust on
    ground contact: a vehicle that is really on the deck stays still; one that is not
    (a hover in the range finder's blind zone, a false impact) starts to sink, its vertical speed breaks
    the condition and the detector returns to ``AIRBORNE`` with full thrust before it has fallen far.
``LANDED``
    ground contact held with the commanded thrust below ``low_thrust_fraction`` of the hover thrust for
    ``landed_s``: the motors may stop (``Command.motors_off``). Final.

The detector only runs while the mission is landing (the Pipeline arms it in ``LAND``); a range reading
inside the blind zone alone never stops the motors.
"""

from __future__ import annotations

import math
from enum import StrEnum
from typing import Annotated, Literal

import numpy as np
from pydantic import Field
from pydantic.dataclasses import dataclass as pydantic_dataclass

from alight.numerics.rotation import rotmat_entries
from alight.settings import SETTINGS, PositiveFloat
from alight.types import GRAVITY_MPS2, Command, EgoState, FloatArray, PlatformEstimate

_ZERO3 = np.zeros(3)
Fraction = Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)]


EVIDENCE_NAMES = ("still", "impact", "at_floor", "held", "in_air")
"""The names of :attr:`TouchdownDetector.evidence`, in the order update keeps them."""


class TouchdownState(StrEnum):
    AIRBORNE = "airborne"
    GROUND_CONTACT = "ground_contact"
    LANDED = "landed"


@pydantic_dataclass(frozen=True, kw_only=True, config=SETTINGS)
class TouchdownConfig:
    """Parameters of the land detector (defaults near PX4's ``LNDMC_*`` and ``MPC_THR_HOVER``)."""

    hover_thrust_N: PositiveFloat = 9.81
    """Collective thrust that holds the vehicle in hover (N): the airframe's weight (PX4 learns it)."""
    max_vertical_speed_mps: PositiveFloat = 0.25
    """Ground contact needs |v_z| relative to the platform below this (m/s) (PX4 LNDMC_Z_VEL_MAX 0.25)."""
    impact_mps2: PositiveFloat = 4.0
    """An impact: the accelerometer's specific force differs from 1 g by more than this (m/s^2)."""
    impact_memory_s: PositiveFloat = 1.0
    """An impact is evidence of contact for this long (s)."""
    range_floor_m: PositiveFloat = 0.08
    """A valid range reading (from the feet) below this is "at the floor" (m)."""
    held_thrust_fraction: Fraction = 0.8
    """Also evidence of a surface: the commanded thrust below this fraction of hover with no vertical
    motion (PX4's low-throttle test: in the air that thrust would sink the vehicle at 2 m/s^2; something
    holds it up). It finds the touchdown whose impact was too soft to see (kim_kaist's 0.1 m/s descent:
    the descent reference keeps going below the deck, so the position loop lowers the thrust)."""
    airborne_range_m: PositiveFloat = 0.5
    """A valid range reading above this vetoes ground contact (m): the vehicle is plainly in the air,
    whatever the accelerometer says (a gust's jolt during a slow descent is not an impact)."""
    ground_contact_s: PositiveFloat = 0.15
    """Ground contact must hold this long before the thrust spools down (s)."""
    spool_down_s: PositiveFloat = 0.5
    """Time for the thrust to ramp from the commanded value to zero on ground contact (s)."""
    low_thrust_fraction: Fraction = 0.3
    """Landed needs the commanded thrust below this fraction of the hover thrust ... """
    landed_s: PositiveFloat = 0.3
    """... for this long, with ground contact kept (s) (PX4: maybe-landed then landed, 0.3 s each)."""
    level_gain_per_s: PositiveFloat = 4.0
    """On ground contact the attitude command is replaced by one that levels the vehicle at this rate per
    radian of tilt (1/s): as PX4 removes the horizontal thrust on ground contact, a vehicle that kept
    leaning into a turning deck's acceleration would push itself over one pair of feet."""
    level_to: Literal["vertical", "steady"] = "vertical"
    """What the attitude is levelled toward on ground contact: ``vertical`` (PX4), or ``steady``: the
    thrust direction held on average over the last ``steady_tilt_time_constant_s`` before contact. On a
    fast deck the vehicle leans into the rotor drag of its airspeed (20 deg at 12 m/s for the F450);
    levelling it then brakes it against the deck, and after a bounce it falls behind the pad. The steady
    tilt balances the steady forces (drag, wind) but not the manoeuvres."""
    steady_tilt_time_constant_s: PositiveFloat = 1.0
    """Low-pass time constant of the thrust direction for ``level_to: steady`` (s)."""


class TouchdownDetector:
    """The land detector's state machine (see the module docstring). Feed it the IMU (:meth:`on_imu`)
    all the time and :meth:`update` at the controller's rate while landing."""

    def __init__(self, config: TouchdownConfig | None = None) -> None:
        self.config = config or TouchdownConfig()
        self.thrust_flown = True
        """Whether the commanded thrust is what lifts the vehicle. False while an autopilot's position
        controller flies the bridge's position setpoints: the pipeline's own thrust then tells nothing of
        a surface (with PX4 it read "held up" 0.4 m above the deck), until ground contact, from which on
        the bridge flies the pipeline's thrust."""
        self._zb_lp: tuple[float, float, float] | None = None
        self._t_att = -math.inf
        self.reset()

    def observe_attitude(self, t: float, q_WB: FloatArray) -> None:
        """The attitude while airborne, for ``level_to: steady`` (a low-pass of the body z axis in W);
        nothing otherwise."""
        if self.config.level_to != "steady" or self.state is not TouchdownState.AIRBORNE:
            return
        x, y, z, w = (float(v) for v in q_WB)
        zb = (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))
        dt = t - self._t_att
        self._t_att = t
        if self._zb_lp is None or not 0.0 < dt < 0.5:
            self._zb_lp = zb
            return
        g = dt / (self.config.steady_tilt_time_constant_s + dt)
        lp = self._zb_lp
        self._zb_lp = (lp[0] + g * (zb[0] - lp[0]), lp[1] + g * (zb[1] - lp[1]), lp[2] + g * (zb[2] - lp[2]))

    def reset(self) -> None:
        """Back to ``AIRBORNE`` (a go-around, a new approach)."""
        self.state = TouchdownState.AIRBORNE
        self.t_impact = -math.inf
        self._contact_since: float | None = None
        self._spool_t0: float | None = None
        self._low_since: float | None = None
        self.t_landed: float | None = None
        self.reason = ""
        self._tests: tuple[bool, ...] = ()

    def on_imu(self, t: float, f_B: FloatArray) -> None:
        """An accelerometer sample: specific force in B (m/s^2). Scalars only: this runs at the IMU
        rate."""
        fx, fy, fz = float(f_B[0]), float(f_B[1]), float(f_B[2])
        if abs(math.sqrt(fx * fx + fy * fy + fz * fz) - GRAVITY_MPS2) > self.config.impact_mps2:
            self.t_impact = t

    def thrust_scale(self, t: float) -> float:
        """Factor in [0, 1] on the commanded collective thrust: 1 while airborne, the spool-down ramp on
        ground contact, 0 once landed."""
        if self.state is TouchdownState.LANDED:
            return 0.0
        if self.state is TouchdownState.GROUND_CONTACT and self._spool_t0 is not None:
            return max(0.0, 1.0 - (t - self._spool_t0) / self.config.spool_down_s)
        return 1.0

    def spooling(self) -> bool:
        """True while the thrust spools down on ground contact (the attitude is levelled then)."""
        return self.state is TouchdownState.GROUND_CONTACT

    def level_rates(self, q_WB: FloatArray) -> FloatArray:
        """Body-rate command (rad/s, in B) that turns the body z axis toward the vertical at
        ``level_gain_per_s`` per radian, with no yaw rate: w_B = k e3 x (R^T e_z), i.e. k R^T (z_B x e_z).
        ``q_WB``: the attitude (x, y, z, w)."""
        x, y, z, w = (float(v) for v in q_WB)
        r00, r01, _, r10, r11, _, r20, r21, _ = rotmat_entries.py_func(x, y, z, w, 2.0)  # q as it is
        k = self.config.level_gain_per_s
        if self.config.level_to == "steady" and self._zb_lp is not None:
            # the target direction e expressed in B: its dot products with the body x and y axes in W
            n = math.sqrt(sum(c * c for c in self._zb_lp))
            e = (self._zb_lp[0] / n, self._zb_lp[1] / n, self._zb_lp[2] / n)
            ex = r00 * e[0] + r10 * e[1] + r20 * e[2]  # the body x axis (column 0 of R_WB) . e
            ey = r01 * e[0] + r11 * e[1] + r21 * e[2]  # the body y axis . e
            return np.array([-k * ey, k * ex, 0.0])
        # e_z expressed in B: the third row of R_WB
        return np.array([-k * r21, k * r20, 0.0])

    @property
    def evidence(self) -> dict[str, bool]:
        """The last update's tests, by name, for logs (kept as a tuple: update runs at the controller's
        rate through the descent)."""
        return dict(zip(EVIDENCE_NAMES, self._tests, strict=False))

    def update(self, t: float, v_z_rel_mps: float, range_m: float | None, thrust_N: float) -> TouchdownState:
        """Advance to ``t``. ``v_z_rel_mps``: the ego estimate's vertical speed relative to the platform
        estimate's (m/s); ``range_m``: the latest range reading from the feet (m), ``-inf`` when the
        sensor reports a target closer than its minimum range (no evidence either way), ``+inf``/None/NaN
        when it has none;
        ``thrust_N``: the collective thrust commanded (after :meth:`thrust_scale`)."""
        cfg = self.config
        if self.state is TouchdownState.LANDED:
            return self.state
        # The sensor's "too close" (-inf) is not evidence of the floor: a vehicle descending slowly
        # (kim_kaist's 0.1 m/s) is "still" by the speed test while it crosses the 0.2 m blind zone, and
        # spooling down and levelling there, 0.1-0.2 m above a moving pad in gusts, doubled the
        # touchdown error (8 seeds: 0.063 -> 0.116 m).
        at_floor = range_m is not None and math.isfinite(range_m) and range_m < cfg.range_floor_m
        impact = t - self.t_impact <= cfg.impact_memory_s
        still = math.isfinite(v_z_rel_mps) and abs(v_z_rel_mps) < cfg.max_vertical_speed_mps
        in_air = range_m is not None and math.isfinite(range_m) and range_m > cfg.airborne_range_m
        # the commanded thrust is evidence only where it flies: not while an autopilot's position
        # controller holds the vehicle (thrust_flown False) before the spool-down takes over
        flown = self.thrust_flown or self.state is not TouchdownState.AIRBORNE
        held = flown and thrust_N < cfg.held_thrust_fraction * cfg.hover_thrust_N
        contact = still and (impact or at_floor or held) and not in_air
        self._tests = (still, impact, at_floor, held, in_air)
        if not contact:
            self._contact_since = self._spool_t0 = self._low_since = None
            self.state = TouchdownState.AIRBORNE
            return self.state
        if self._contact_since is None:
            self._contact_since = t
        if self.state is TouchdownState.AIRBORNE and t - self._contact_since >= cfg.ground_contact_s:
            self.state = TouchdownState.GROUND_CONTACT
            self._spool_t0 = t
        if self.state is TouchdownState.GROUND_CONTACT:
            if thrust_N < cfg.low_thrust_fraction * cfg.hover_thrust_N:
                if self._low_since is None:
                    self._low_since = t
                if t - self._low_since >= cfg.landed_s:
                    self.state = TouchdownState.LANDED
                    self.t_landed = t
                    self.reason = "impact" if impact else ("range at floor" if at_floor else "held up")
            else:
                self._low_since = None
        return self.state

    def command(
        self,
        t: float,
        ego: EgoState,
        target: PlatformEstimate | None,
        range_raw_m: float | None,
        cmd: Command,
    ) -> Command:
        """The controller's command ``cmd`` through the land detector while it is armed (a descent): the
        thrust spooled down on ground contact with the attitude levelled, and the motors stopped once
        :meth:`update` (fed the vertical speed relative to the platform estimate, the raw range reading
        and the spooled thrust) says landed."""
        scale = self.thrust_scale(t)
        thrust = cmd.thrust_N * scale
        v_z_rel = float(ego.v_WB[2]) - (0.0 if target is None else float(target.v_WP[2]))
        if self.update(t, v_z_rel, range_raw_m, thrust) is TouchdownState.LANDED:
            return Command(t, 0.0, _ZERO3, motors_off=True)
        if self.spooling():
            return Command(t, thrust, self.level_rates(ego.q_WB))
        return cmd
