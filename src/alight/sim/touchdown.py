"""Judging the first contact of the vehicle with the pad, the platform or the ground (ground truth).

DESIGN.md "Landing outcome": ``landed`` when the vehicle's centre is inside the pad footprint shrunk by
the landing gear's half-width, the vertical speed relative to the pad is at most 1.0 m/s, the horizontal
one at most 0.75 m/s and the tilt at most 25 deg; ``crashed`` on the ground, on the platform outside that
footprint, or beyond those limits.

The contact geometry: the feet are ``gear_height`` below the body origin (upright vehicle, as specified;
a tilted vehicle's lowest foot is lower by up to ``gear_half_width sin(tilt)``, which matters only for
crashes). The surface under the vehicle is the pad when the gear's footprint overlaps the pad, i.e. the
centre is inside the pad square grown by ``gear_half_width`` (the footprint is taken as aligned with the
pad), and the ground otherwise. Touching the pad from the side (feet below the pad height while over
it) counts as a platform contact too.

On a vessel at sea (``deck`` given: a :class:`~alight.sim.sea.world_deck.DeckPose`) the judge works in
the deck's frame P: the footprint test on the deck's own axes, the speed relative to the deck's material
point under the vehicle along the deck's normal (the "vertical" limit) and across it (the "horizontal"
limit), the vehicle's tilt relative to the deck's normal; the deck's own tilt is reported with them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from alight.types import FloatArray, Outcome

from .platform import PlatformTruth, pad_contains
from .sea.world_deck import DeckPose


@dataclass(frozen=True, kw_only=True)
class ContactLimits:
    """What a landing must respect (scenario parameters)."""

    gear_half_width: float = 0.2
    """Half the landing gear's footprint (m); the centre must stay this far inside the pad's edges."""
    max_vertical_speed_mps: float = 1.0
    """Largest vertical speed relative to the pad at contact (m/s)."""
    max_horizontal_speed_mps: float = 0.75
    """Largest horizontal speed relative to the pad at contact (m/s)."""
    max_tilt_deg: float = 25.0
    """Largest angle between the body z axis and the vertical at contact (deg)."""

    def __post_init__(self) -> None:
        for name in ("gear_half_width", "max_vertical_speed_mps", "max_horizontal_speed_mps", "max_tilt_deg"):
            v = getattr(self, name)
            if not (v >= 0.0 and math.isfinite(v)):
                raise ValueError(f"{name} must be >= 0 and finite, got {v}")


@dataclass(frozen=True, slots=True)
class Contact:
    """The judged first contact."""

    outcome: Outcome
    """``Outcome.LANDED`` or ``Outcome.CRASHED``."""
    surface: str
    """What was touched: ``pad`` or ``ground``."""
    reason: str
    """Why it crashed (``ground``, ``off_footprint``, ``vertical_speed``, ``horizontal_speed``, ``tilt``,
    comma-separated), empty when landed."""
    touchdown_error_m: float
    """Horizontal distance between the vehicle's centre and the pad's centre (m)."""
    rel_vertical_speed_mps: float
    """|v_z| of the vehicle relative to the touched surface (m/s)."""
    rel_horizontal_speed_mps: float
    """Horizontal speed of the vehicle relative to the touched surface (m/s)."""
    rel_speed_mps: float
    """Speed relative to the touched surface (m/s)."""
    tilt_rad: float
    """Angle between the body z axis and the vertical (rad)."""
    platform_speed_mps: float = 0.0
    """The platform's horizontal speed at the contact (m/s), whatever was touched."""
    platform_turn_rate_rad_s: float = 0.0
    """The platform's heading rate at the contact (rad/s, counter-clockwise)."""
    deck: DeckFigures | None = None
    """On a vessel's deck at sea: the contact in the deck's frame (None on level ground)."""


@dataclass(frozen=True, slots=True)
class DeckFigures:
    """A contact in the frame of a tilted, moving deck."""

    touchdown_error_m: float | None
    """Distance from the pad centre in the deck's plane (m); None off the deck."""
    normal_speed_mps: float | None
    """|speed| relative to the deck's material point under the vehicle, along the deck's normal (m/s)."""
    tangential_speed_mps: float | None
    """The same relative speed, across the normal (in the deck's plane) (m/s)."""
    relative_tilt_rad: float | None
    """Angle between the body z axis and the deck's normal (rad)."""
    deck_tilt_rad: float
    """The deck's own tilt from the horizontal (rad)."""


def _surface_under_feet(
    p_xy: FloatArray, feet_z: float, platform: PlatformTruth, pad_size_m: float, limits: ContactLimits
) -> str | None:
    """``pad`` or ``ground`` when the feet at height ``feet_z`` (m) reach that surface, else None."""
    over_platform = bool(pad_contains(p_xy, platform.p_WP, platform.yaw, pad_size_m, -limits.gear_half_width))
    if over_platform and feet_z <= float(platform.p_WP[2]):
        return "pad"
    if feet_z <= 0.0:
        return "ground"
    return None


def judge_contact(
    p_WB: FloatArray,
    v_WB: FloatArray,
    R_WB: FloatArray,
    platform: PlatformTruth,
    pad_size_m: float,
    gear_height: float,
    limits: ContactLimits,
    *,
    surface: str | None = None,
    ground_ok: bool = False,
    deck: DeckPose | None = None,
) -> Contact | None:
    """The contact at this instant, or None while the feet are above the surface below.

    ``p_WB`` (3,) m, ``v_WB`` (3,) m/s, ``R_WB`` (3, 3): the vehicle's true state; ``platform``: the
    platform's true state; ``pad_size_m``: side of the pad (m); ``gear_height``: body origin above the
    feet (m). Call at every dynamics step after take-off (the vehicle standing on the ground before
    take-off would count as a ground crash) and keep the first non-None answer. Nothing can be touched
    while ``p_WB[2] - gear_height`` is above the pad height, so a runner can skip the call (and the
    platform state) until then.

    ``surface``: ``pad`` or ``ground`` when the caller knows what the feet touch (the simulator's
    contact model reports it; a tilted vehicle's foot touches before its centre's gear height does):
    that surface is judged without the geometric test. ``ground_ok``: a ground contact is judged on its
    speeds and tilt, not a crash by itself (the landing of an abort's final action). ``deck``: the deck
    of a vessel at sea (module docstring); ``surface`` is then required.
    """
    if deck is not None:
        if surface is None:
            raise ValueError("a contact on a deck at sea is judged with its surface given")
        return _judge_on_deck(p_WB, v_WB, R_WB, deck, pad_size_m, limits, surface, ground_ok)
    p_xy = np.asarray(p_WB[:2], dtype=np.float64)
    if surface is None:
        feet_z = float(p_WB[2]) - gear_height
        if feet_z > platform.p_WP[2] and feet_z > 0.0:
            return None  # the common case, kept cheap: above every surface
        surface = _surface_under_feet(p_xy, feet_z, platform, pad_size_m, limits)
        if surface is None:
            return None
    if surface == "pad":
        v_rel = np.asarray(v_WB, dtype=np.float64) - platform.v_WP
    else:
        v_rel = np.asarray(v_WB, dtype=np.float64)

    vz = abs(float(v_rel[2]))
    vh = math.hypot(float(v_rel[0]), float(v_rel[1]))
    tilt = math.acos(min(1.0, max(-1.0, float(R_WB[2, 2]))))
    err = math.hypot(float(p_WB[0] - platform.p_WP[0]), float(p_WB[1] - platform.p_WP[1]))

    reasons = []
    if surface == "ground" and not ground_ok:
        reasons.append("ground")
    else:
        if surface == "pad" and not pad_contains(
            p_xy, platform.p_WP, platform.yaw, pad_size_m, limits.gear_half_width
        ):
            reasons.append("off_footprint")
        _exceeded(reasons, vz, vh, tilt, limits)
    return _contact(
        surface, reasons, err, v_rel, tilt,
        math.hypot(float(platform.v_WP[0]), float(platform.v_WP[1])), float(platform.yaw_rate),
    )  # fmt: skip


def _exceeded(
    reasons: list[str],
    v_normal: float | None,
    v_along: float | None,
    tilt: float | None,
    limits: ContactLimits,
) -> None:
    """Appends to ``reasons`` the limits that a contact's speeds across and along the surface and its
    tilt to it exceed (None: not measured)."""
    if v_normal is not None and v_normal > limits.max_vertical_speed_mps:
        reasons.append("vertical_speed")
    if v_along is not None and v_along > limits.max_horizontal_speed_mps:
        reasons.append("horizontal_speed")
    if tilt is not None and tilt > math.radians(limits.max_tilt_deg):
        reasons.append("tilt")


def _contact(
    surface: str,
    reasons: list[str],
    err: float,
    v_rel: FloatArray,
    tilt: float,
    platform_speed_mps: float,
    platform_turn_rate_rad_s: float,
    deck: DeckFigures | None = None,
) -> Contact:
    """The verdict of a contact with its figures (``v_rel``: the vehicle's velocity relative to what it
    touched, W)."""
    vz = abs(float(v_rel[2]))
    vh = math.hypot(float(v_rel[0]), float(v_rel[1]))
    return Contact(
        outcome=Outcome.CRASHED if reasons else Outcome.LANDED,
        surface=surface,
        reason=",".join(reasons),
        touchdown_error_m=err,
        rel_vertical_speed_mps=vz,
        rel_horizontal_speed_mps=vh,
        rel_speed_mps=math.sqrt(vz * vz + vh * vh),
        tilt_rad=tilt,
        platform_speed_mps=platform_speed_mps,
        platform_turn_rate_rad_s=platform_turn_rate_rad_s,
        deck=deck,
    )


def judge_settled(
    p_WB: FloatArray,
    R_WB: FloatArray,
    platform: PlatformTruth,
    pad_size_m: float,
    limits: ContactLimits,
    feet_on_deck: int,
    feet_on_ground: int,
    *,
    ground_ok: bool = False,
) -> tuple[Outcome, str]:
    """The outcome once the vehicle has settled (``settle_s`` after the motors stopped): ``LANDED`` when
    it still stands on the pad (feet on the deck, none on the ground, centre inside the footprint, tilt
    within the limit), else ``CRASHED`` with why (``ground``, ``not_on_pad``, ``off_footprint``,
    ``tipped_over``). ``ground_ok``: an abort's landing, where standing upright on the ground (or the
    pad) is the safe end: ``LANDED`` then means "settled safely" and the caller scores it ``aborted``.
    ``feet_on_deck``/``feet_on_ground``: what the contact model reports touching."""
    tilt = math.acos(min(1.0, max(-1.0, float(R_WB[2, 2]))))
    reasons = []
    if tilt > math.radians(limits.max_tilt_deg):
        reasons.append("tipped_over")
    if ground_ok:
        if feet_on_deck + feet_on_ground == 0:
            reasons.append("not_on_a_surface")
    else:
        if feet_on_ground > 0:
            reasons.append("ground")
        if feet_on_deck == 0:
            reasons.append("not_on_pad")
        elif not pad_contains(
            np.asarray(p_WB[:2], dtype=np.float64),
            platform.p_WP,
            platform.yaw,
            pad_size_m,
            limits.gear_half_width,
        ):
            reasons.append("off_footprint")
    return (Outcome.CRASHED if reasons else Outcome.LANDED), ",".join(reasons)


def deck_figures(p_WB: FloatArray, v_WB: FloatArray, R_WB: FloatArray, deck: DeckPose) -> DeckFigures:
    """The vehicle at ``p_WB``, ``v_WB``, ``R_WB`` in the frame of ``deck`` (its contact figures)."""
    n = deck.R_WP[:, 2]
    local = deck.local(p_WB)
    v_rel = np.asarray(v_WB, dtype=np.float64) - deck.surface_velocity(p_WB)
    vn = float(v_rel @ n)
    vt = float(np.linalg.norm(v_rel - vn * n))
    rel_tilt = math.acos(min(1.0, max(-1.0, float(np.asarray(R_WB)[:, 2] @ n))))
    return DeckFigures(
        touchdown_error_m=math.hypot(float(local[0]), float(local[1])),
        normal_speed_mps=abs(vn),
        tangential_speed_mps=vt,
        relative_tilt_rad=rel_tilt,
        deck_tilt_rad=math.acos(min(1.0, max(-1.0, float(deck.R_WP[2, 2])))),
    )


def _on_pad(local_P: FloatArray, pad_size_m: float, inset_m: float) -> bool:
    half = 0.5 * pad_size_m - inset_m
    return abs(float(local_P[0])) <= half and abs(float(local_P[1])) <= half


def _judge_on_deck(
    p_WB: FloatArray,
    v_WB: FloatArray,
    R_WB: FloatArray,
    deck: DeckPose,
    pad_size_m: float,
    limits: ContactLimits,
    surface: str,
    ground_ok: bool,
) -> Contact:
    """:func:`judge_contact` on a vessel's deck (module docstring): the limits in the deck's frame."""
    R_WB = np.asarray(R_WB, dtype=np.float64)
    tilt = math.acos(min(1.0, max(-1.0, float(R_WB[2, 2]))))
    err = math.hypot(float(p_WB[0] - deck.p_WP[0]), float(p_WB[1] - deck.p_WP[1]))
    reasons = []
    if surface == "pad":
        fig = deck_figures(p_WB, v_WB, R_WB, deck)
        v_rel = np.asarray(v_WB, dtype=np.float64) - deck.surface_velocity(p_WB)
        checked = (fig.normal_speed_mps, fig.tangential_speed_mps, fig.relative_tilt_rad)
        if not _on_pad(deck.local(p_WB), pad_size_m, limits.gear_half_width):
            reasons.append("off_footprint")
    else:
        deck_tilt = math.acos(min(1.0, max(-1.0, float(deck.R_WP[2, 2]))))
        fig = DeckFigures(None, None, None, None, deck_tilt)
        v_rel = np.asarray(v_WB, dtype=np.float64)
        checked = (abs(float(v_rel[2])), math.hypot(float(v_rel[0]), float(v_rel[1])), tilt)
        if not ground_ok:
            reasons.append("ground")
    vn, vt, rel_tilt = checked
    if not reasons or reasons == ["off_footprint"]:
        _exceeded(reasons, vn, vt, rel_tilt, limits)
    return _contact(
        surface, reasons, err, v_rel, tilt, math.hypot(float(deck.v_WP[0]), float(deck.v_WP[1])),
        float(deck.w_WP_W[2]),  # the deck's yaw rate: its body rate about the vertical
        deck=fig,
    )  # fmt: skip


def judge_settled_on_deck(
    p_WB: FloatArray,
    R_WB: FloatArray,
    deck: DeckPose,
    pad_size_m: float,
    limits: ContactLimits,
    feet_on_deck: int,
    feet_on_ground: int,
    *,
    ground_ok: bool = False,
) -> tuple[Outcome, str]:
    """:func:`judge_settled` on a vessel's deck: still standing on the pad means the feet on the deck,
    none in the water, the centre inside the footprint on the deck's axes and the tilt relative to the
    deck's normal within the limit; a vehicle that slid off the rolling deck is ``CRASHED``."""
    n = deck.R_WP[:, 2]
    on_deck = feet_on_deck > 0
    up = n if on_deck else np.array([0.0, 0.0, 1.0])
    tilt = math.acos(min(1.0, max(-1.0, float(np.asarray(R_WB)[:, 2] @ up))))
    reasons = []
    if tilt > math.radians(limits.max_tilt_deg):
        reasons.append("tipped_over")
    if ground_ok:
        if feet_on_deck + feet_on_ground == 0:
            reasons.append("not_on_a_surface")
    else:
        if feet_on_ground > 0:
            reasons.append("ground")
        if not on_deck:
            reasons.append("not_on_pad")
        elif not _on_pad(deck.local(p_WB), pad_size_m, limits.gear_half_width):
            reasons.append("off_footprint")
    return (Outcome.CRASHED if reasons else Outcome.LANDED), ",".join(reasons)
