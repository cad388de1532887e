"""Touchdown judging: every branch of DESIGN.md's landing-outcome table."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from alight.sim.platform import PlatformTruth
from alight.sim.touchdown import ContactLimits, judge_contact
from alight.types import Outcome

PAD = 1.5
GEAR = 0.1
H = 0.5
LIM = ContactLimits()
I3 = np.eye(3)


def _pad(v=(0.0, 0.0, 0.0), yaw=0.0, xy=(10.0, 5.0)):
    return PlatformTruth(0.0, np.array([xy[0], xy[1], H]), np.array(v, dtype=float), np.zeros(3), yaw, 0.0)


def _judge(dxy=(0.0, 0.0), v=(0.0, 0.0, -0.3), R=I3, pad=None, z=None):
    pad = pad or _pad()
    p = np.array([pad.p_WP[0] + dxy[0], pad.p_WP[1] + dxy[1], H + GEAR if z is None else z])
    return judge_contact(p, np.array(v, dtype=float), R, pad, PAD, GEAR, LIM)


def test_no_contact_while_feet_are_above_the_surface():
    assert _judge(z=H + GEAR + 1e-6) is None
    # beside the platform the surface is the ground: feet below the pad height but above ground
    assert _judge(dxy=(3.0, 0.0), z=0.3) is None


def test_gentle_centred_landing():
    c = _judge(dxy=(0.1, -0.2))
    assert c is not None and c.outcome is Outcome.LANDED and c.surface == "pad" and c.reason == ""
    assert c.touchdown_error_m == pytest.approx(math.hypot(0.1, 0.2))
    assert c.rel_vertical_speed_mps == pytest.approx(0.3)
    assert c.tilt_rad == pytest.approx(0.0)


def test_footprint_is_the_pad_shrunk_by_the_gear_half_width():
    assert _judge(dxy=(0.549, 0.549)).outcome is Outcome.LANDED
    c = _judge(dxy=(0.56, 0.0))
    assert c.outcome is Outcome.CRASHED and c.surface == "pad" and c.reason == "off_footprint"
    assert c.touchdown_error_m == pytest.approx(0.56)
    # centre off the pad but the gear on its edge: a platform contact, crashed
    c = _judge(dxy=(0.0, -0.85))
    assert c.outcome is Outcome.CRASHED and c.surface == "pad" and c.reason == "off_footprint"
    # the footprint turns with the platform's heading: 0.7 m along W x is 0.49 m along each pad axis
    assert _judge(dxy=(0.7, 0.0), pad=_pad(yaw=math.pi / 4)).outcome is Outcome.LANDED
    assert _judge(dxy=(0.7, 0.0), pad=_pad(yaw=0.0)).outcome is Outcome.CRASHED


def test_ground_contact_is_a_crash_however_gentle():
    c = _judge(dxy=(5.0, 0.0), v=(0.0, 0.0, -0.1), z=GEAR)
    assert c.outcome is Outcome.CRASHED and c.surface == "ground" and c.reason == "ground"
    assert c.touchdown_error_m == pytest.approx(5.0)


def test_vertical_speed_limit_is_inclusive():
    assert _judge(v=(0.0, 0.0, -1.0)).outcome is Outcome.LANDED
    c = _judge(v=(0.0, 0.0, -1.2))
    assert c.outcome is Outcome.CRASHED and c.reason == "vertical_speed"


def test_horizontal_speed_is_relative_to_the_platform():
    moving = _pad(v=(2.0, 0.0, 0.0))
    assert _judge(v=(2.5, 0.3, -0.5), pad=moving).outcome is Outcome.LANDED  # 0.58 m/s relative
    c = _judge(v=(0.0, 0.0, -0.5), pad=moving)
    assert c.outcome is Outcome.CRASHED and c.reason == "horizontal_speed"
    assert c.rel_horizontal_speed_mps == pytest.approx(2.0)
    assert c.rel_speed_mps == pytest.approx(math.hypot(2.0, 0.5))


def test_tilt_limit():
    assert _judge(R=Rotation.from_euler("x", math.radians(20)).as_matrix()).outcome is Outcome.LANDED
    c = _judge(R=Rotation.from_euler("xy", [math.radians(20), math.radians(20)]).as_matrix())
    assert c.outcome is Outcome.CRASHED and c.reason == "tilt"
    assert c.tilt_rad == pytest.approx(math.acos(math.cos(math.radians(20)) ** 2))


def test_several_violations_are_all_reported():
    c = _judge(dxy=(0.6, 0.0), v=(1.0, 0.0, -2.0))
    assert c.outcome is Outcome.CRASHED
    assert c.reason == "off_footprint,vertical_speed,horizontal_speed"


def test_custom_limits_and_validation():
    lim = ContactLimits(gear_half_width=0.0, max_vertical_speed_mps=2.0)
    pad = _pad()
    p = np.array([pad.p_WP[0] + 0.7, pad.p_WP[1], H + GEAR])
    assert judge_contact(p, np.array([0.0, 0.0, -1.5]), I3, pad, PAD, GEAR, lim).outcome is Outcome.LANDED
    with pytest.raises(ValueError):
        ContactLimits(max_tilt_deg=-1.0)


def test_the_contact_model_names_the_surface_a_tilted_foot_touches():
    from alight.sim.touchdown import judge_contact

    # the centre's gear height is still above the pad, but the contact model says a foot touches it
    pad = _pad()
    p = np.array([pad.p_WP[0], pad.p_WP[1], H + GEAR + 0.02])
    assert judge_contact(p, np.array([0.0, 0.0, -0.3]), I3, pad, PAD, GEAR, LIM) is None
    c = judge_contact(p, np.array([0.0, 0.0, -0.3]), I3, pad, PAD, GEAR, LIM, surface="pad")
    assert c is not None and c.outcome is Outcome.LANDED and c.surface == "pad"


def test_ground_is_a_safe_surface_only_for_an_abort_landing():
    from alight.sim.touchdown import judge_contact

    p = np.array([0.0, 0.0, GEAR])
    far = _pad(xy=(30.0, 0.0))
    assert judge_contact(p, np.array([0, 0, -0.3]), I3, far, PAD, GEAR, LIM).reason == "ground"
    ok = judge_contact(p, np.array([0, 0, -0.3]), I3, far, PAD, GEAR, LIM, ground_ok=True)
    assert ok.outcome is Outcome.LANDED and ok.surface == "ground"
    hard = judge_contact(p, np.array([0, 0, -1.5]), I3, far, PAD, GEAR, LIM, ground_ok=True)
    assert hard.outcome is Outcome.CRASHED and hard.reason == "vertical_speed"


def test_settled_judgement():
    from alight.sim.touchdown import judge_settled

    pad = _pad()
    on = np.array([pad.p_WP[0] + 0.1, pad.p_WP[1], H + GEAR])
    assert judge_settled(on, I3, pad, PAD, LIM, 4, 0) == (Outcome.LANDED, "")
    slid = np.array([pad.p_WP[0] + 0.6, pad.p_WP[1], H + GEAR])
    assert judge_settled(slid, I3, pad, PAD, LIM, 2, 0) == (Outcome.CRASHED, "off_footprint")
    assert judge_settled(on, I3, pad, PAD, LIM, 0, 4) == (Outcome.CRASHED, "ground,not_on_pad")
    assert judge_settled(on, I3, pad, PAD, LIM, 0, 0) == (Outcome.CRASHED, "not_on_pad")
    tipped = Rotation.from_euler("x", math.radians(60)).as_matrix()
    assert judge_settled(on, tipped, pad, PAD, LIM, 2, 0)[1] == "tipped_over"
    # an abort's landing: upright on the ground is the safe end
    assert judge_settled(np.array([0.0, 0.0, GEAR]), I3, pad, PAD, LIM, 0, 4, ground_ok=True) == (
        Outcome.LANDED,
        "",
    )
    assert judge_settled(np.array([0.0, 0.0, GEAR]), tipped, pad, PAD, LIM, 0, 2, ground_ok=True)[0] is (
        Outcome.CRASHED
    )
