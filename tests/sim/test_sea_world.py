"""The simulated world on a vessel at sea (issue 37, point 2): the ``platform.sea`` scenario key, the
contact with a tilted moving deck, the range finder on it, the camera's tilted deck and the judge in the
deck's frame. Closed forms where there are some: a body resting on an inclined plane, the ray-plane
distance, the projection of the deck's corners."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME as AF
from alight.control.rate import pack_low_level_params
from alight.errors import ConfigError
from alight.scenario import scenario_from_dict
from alight.sim import quadrotor as Q
from alight.sim.physics import IN_DECK, N_IN, tick_batch
from alight.sim.sea import SeaConfig
from alight.sim.sea.config import MotionTelemetryConfig
from alight.sim.sea.world_deck import DeckPose, MruStream, deck_attitude
from alight.sim.sensors import RangeFinder, RangeFinderConfig, range_to_deck
from alight.sim.touchdown import ContactLimits, judge_contact, judge_settled_on_deck
from alight.types import GRAVITY_MPS2, Outcome, quat_to_rotmat

PAR = Q.pack_params(AF)
LL = pack_low_level_params(AF)
CP = Q.pack_contact_params(AF)
G = GRAVITY_MPS2
MU = float(CP[Q.CP_MU])
V_SLIP = float(CP[Q.CP_V_SLIP])
DECK_Z = 2.0


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _tilted_deck(roll: float, v=(0.0, 0.0, 0.0), w=(0.0, 0.0, 0.0), half: float = 5.0) -> np.ndarray:
    d = np.zeros(Q.N_DK)
    d[Q.DK_ON] = 1.0
    d[Q.DK_TILTED] = 1.0
    d[Q.DK_HALF] = 0.75
    d[Q.DK_P : Q.DK_P + 3] = (0.0, 0.0, DECK_Z)
    d[Q.DK_V : Q.DK_V + 3] = v
    d[Q.DK_R : Q.DK_R + 9] = _rx(roll).ravel()
    d[Q.DK_W : Q.DK_W + 3] = w
    d[Q.DK_EXT : Q.DK_EXT + 4] = (-half, half, -half, half)
    return d


def _resting_on(deck: np.ndarray) -> np.ndarray:
    """The vehicle aligned with the deck, its feet on the surface (motors off)."""
    R = deck[Q.DK_R : Q.DK_R + 9].reshape(3, 3)
    p = deck[Q.DK_P : Q.DK_P + 3] + R @ np.array([0.0, 0.0, AF.gear_height])
    roll = math.atan2(R[2, 1], R[2, 2])
    x = Q.initial_state(p)
    x[Q.IX_Q : Q.IX_Q + 4] = (math.sin(0.5 * roll), 0.0, 0.0, math.cos(0.5 * roll))
    return x


def _fly(x: np.ndarray, seconds: float, deck: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    inputs = np.zeros(N_IN)
    noise = np.zeros((1, 12))
    xs, ds = [], []
    d = deck.copy()
    for _ in range(round(seconds / 0.005)):
        inputs[IN_DECK : IN_DECK + Q.N_DK] = d
        out, _, _, _ = tick_batch(
            x, inputs, PAR, LL, np.zeros(6), noise, np.ones(6), 0.001, 5, CP, 1, -math.inf, math.inf
        )
        x = out[0]
        now = np.empty(Q.N_DK)
        Q.deck_at(d, 0.005, now)
        d = now
        xs.append(x.copy())
        ds.append(d.copy())
    return np.array(xs), np.array(ds)


def _wrench(x: np.ndarray, deck: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    f, tq, counts = np.zeros(3), np.zeros(3), np.zeros(2)
    Q.contact_wrench(x, deck, CP, f, tq, counts)
    return f, counts


# -- the scenario key ------------------------------------------------------------------------------------


def test_the_sea_is_off_by_default_and_writes_no_key():
    s = scenario_from_dict({})
    assert s.platform.sea is None
    assert "sea" not in s.model_dump(mode="json")["platform"]
    sea = scenario_from_dict({"platform": {"sea": {"sea_state": 4, "motion_telemetry": {"rate_hz": 20}}}})
    assert sea.platform.sea == SeaConfig(sea_state=4, motion_telemetry=MotionTelemetryConfig(rate_hz=20.0))
    again = scenario_from_dict(sea.model_dump(mode="json"))
    assert again.platform.sea == sea.platform.sea


@pytest.mark.parametrize(
    ("sea", "needle"),
    [
        ({}, "needs sea_state or hs_m"),
        ({"sea_state": 3, "hs_m": 1.0, "tp_s": 5.0}, "not both"),
        ({"hs_m": "1.5", "tp_s": 6.0}, "platform.sea.hs_m: Input should be a valid number"),
        ({"sea_state": True}, "platform.sea.sea_state"),
        ({"sea_state": 3, "vessel": "trawler"}, "unknown vessel"),
        ({"sea_state": 3, "pad_offset_m": 1.0}, "platform.sea.pad_offset_m"),
        ({"sea_state": 3, "vessel": "small_usv", "pad_offset_m": [3.0, 0.0, 0.5]}, "off the small_usv"),
        ({"sea_state": 3, "swell": 1}, "platform.sea.swell: Extra inputs"),
        ({"sea_state": 3, "motion_telemetry": {"rate_hz": 0}}, "platform.sea.motion_telemetry.rate_hz"),
        ({"hs_m": 3.0, "tp_s": 3.0}, "steeper"),
    ],
)
def test_bad_sea_keys_are_refused_in_one_line(sea, needle):
    with pytest.raises(ConfigError, match=needle) as info:
        scenario_from_dict({"platform": {"sea": sea}}, "s.yaml")
    assert "\n" not in str(info.value)
    assert str(info.value).startswith("s.yaml: platform.sea")


def test_a_pad_height_at_sea_is_refused():
    with pytest.raises(ConfigError, match="pad_height_m has no effect with platform.sea") as info:
        scenario_from_dict({"platform": {"pad_height_m": 1.0, "sea": {"sea_state": 3}}}, "s.yaml")
    assert "\n" not in str(info.value)


def test_in_still_water_the_pad_follows_the_platform_path_exactly():
    # the centre of motion rides Rz(yaw) r_xy behind the pad (the frigate's pad is 55 m aft): on a
    # circle the pad's position, velocity and acceleration are the path's, the centre's turn included
    from alight.sim.platform import Platform, PlatformConfig
    from alight.sim.sea.world_deck import SeaDeck

    platform = Platform(
        PlatformConfig(path="circle", speed_mps=3.0, circle_radius_m=40.0), np.random.default_rng(0)
    )
    t = np.arange(0.0, 20.0, 0.005)
    path = platform.states(t)
    deck = SeaDeck(SeaConfig(sea_state=0, vessel="frigate"), np.random.default_rng(1), 3.0, path, 0.005, 0.75)
    r = deck.motion.r_B
    np.testing.assert_allclose(deck.pad.p_WP[:, :2], path.p_WP[:, :2], atol=1e-9)
    np.testing.assert_allclose(deck.pad.p_WP[:, 2], r[2], atol=1e-12)
    np.testing.assert_allclose(deck.pad.v_WP, path.v_WP, atol=1e-6)
    np.testing.assert_allclose(deck.pad.a_WP[5:-5], path.a_WP[5:-5], atol=1e-4)  # central difference of yaw'
    centre = path.p_WP[:, :2] - deck.pad.R_WP[:, :2, :2] @ r[:2]
    assert np.min(np.linalg.norm(centre - path.p_WP[:, :2], axis=1)) == pytest.approx(55.0, abs=1e-9)


# -- contact with a tilted, moving deck ------------------------------------------------------------------


def test_a_body_resting_on_a_tilted_deck_is_held_along_the_normal_inside_the_friction_cone():
    # 10 deg of roll, tan 10 deg = 0.18 < mu: the regularised friction holds the body with a slow creep
    # v = v_slip tan(a) / sqrt(mu^2 - tan(a)^2) (mu N v / sqrt(v^2 + v_slip^2) = W sin a), and the
    # contact force balances the weight: W cos a along the normal, W sin a up the slope
    a = math.radians(10.0)
    deck = _tilted_deck(a)
    xs, ds = _fly(_resting_on(deck), 3.0, deck)
    x = xs[-1]
    f, counts = _wrench(x, ds[-1])
    n = _rx(a)[:, 2]
    W = AF.weight_N
    assert counts[0] == 4 and counts[1] == 0
    assert float(f @ n) == pytest.approx(W * math.cos(a), rel=2e-3)
    tangential = f - float(f @ n) * n
    assert np.linalg.norm(tangential) == pytest.approx(W * math.sin(a), rel=5e-3)
    assert np.linalg.norm(tangential) <= MU * float(f @ n)  # inside the cone
    downhill = np.array([0.0, 0.0, -1.0]) - (-n[2]) * n  # gravity's direction in the deck's plane
    downhill /= np.linalg.norm(downhill)
    assert float(tangential @ downhill) < 0.0  # friction points up the slope
    creep = V_SLIP * math.tan(a) / math.sqrt(MU**2 - math.tan(a) ** 2)
    v = x[Q.SL_V]
    assert float(v @ downhill) == pytest.approx(creep, rel=0.03)
    assert abs(float(v @ n)) < 1e-4  # no motion off the plane
    # the body stays aligned with the deck: its z axis is the normal
    assert float(quat_to_rotmat(x[Q.SL_Q])[:, 2] @ n) > math.cos(math.radians(0.2))


def test_a_deck_steeper_than_the_friction_cone_lets_the_body_slide_at_the_closed_form_rate():
    a = math.radians(40.0)  # tan 40 deg = 0.84 > mu = 0.6
    deck = _tilted_deck(a)
    xs, _ = _fly(_resting_on(deck), 1.0, deck)
    n = _rx(a)[:, 2]
    downhill = np.array([0.0, 0.0, -1.0]) + n[2] * n
    downhill /= np.linalg.norm(downhill)
    v0, v1 = float(xs[99, Q.IX_V : Q.IX_V + 3] @ downhill), float(xs[199, Q.IX_V : Q.IX_V + 3] @ downhill)
    accel = (v1 - v0) / 0.5
    assert accel == pytest.approx(G * (math.sin(a) - MU * math.cos(a)), rel=0.02)


def test_the_deck_motion_is_carried_through_the_contact():
    # a deck tilted 5 deg, moving at 2 m/s and rolling at 0.1 rad/s: the body resting on it moves with
    # the deck's material point under it (the creep aside) and keeps its attitude relative to the deck
    w = np.array([0.1, 0.0, 0.0])
    deck = _tilted_deck(math.radians(5.0), v=(2.0, 0.0, 0.0), w=tuple(w))
    xs, ds = _fly(_resting_on(deck), 1.5, deck)
    x, d = xs[-1], ds[-1]
    R = d[Q.DK_R : Q.DK_R + 9].reshape(3, 3)
    # the deck as a rigid body carries the vehicle's centre at v_WP + w x (p_WB - p_WP), less the creep
    # down the slope of the friction's regularisation (closed form at the final 13.6 deg: 8.8 mm/s)
    carried = d[Q.DK_V : Q.DK_V + 3] + np.cross(w, x[Q.SL_P] - d[Q.DK_P : Q.DK_P + 3])
    tilt = math.radians(5.0) + 0.15
    creep = V_SLIP * math.tan(tilt) / math.sqrt(MU**2 - math.tan(tilt) ** 2)
    rel = x[Q.SL_V] - carried
    assert abs(float(rel @ R[:, 2])) < 1e-3
    assert np.linalg.norm(rel) < 1.2 * creep
    assert np.linalg.norm(x[Q.SL_V] - d[Q.DK_V : Q.DK_V + 3]) > 2.0 * creep  # the roll's w x r is seen
    assert float(quat_to_rotmat(x[Q.SL_Q])[:, 2] @ R[:, 2]) > math.cos(math.radians(0.5))
    roll = deck_attitude(R)[0]
    assert roll == pytest.approx(math.radians(5.0) + 0.1 * 1.5, abs=1e-6)  # Exp(w t) carried the deck


def test_a_vehicle_slides_off_a_steep_deck_into_the_sea_and_is_judged_so():
    # motors off on a small deck rolled 40 deg (beyond the friction cone): it slides off the low edge,
    # falls to the sea's level and the settled judge calls it crashed
    deck = _tilted_deck(math.radians(40.0), half=1.0)
    xs, ds = _fly(_resting_on(deck), 2.5, deck)
    x, d = xs[-1], ds[-1]
    _, counts = _wrench(x, d)
    assert counts[0] == 0 and counts[1] > 0 and x[Q.IX_P + 2] < AF.gear_height + 0.3
    R = d[Q.DK_R : Q.DK_R + 9].reshape(3, 3)
    pose = DeckPose(d[Q.DK_P : Q.DK_P + 3], R, d[Q.DK_V : Q.DK_V + 3], np.zeros(3), (-1.0, 1.0, -1.0, 1.0))
    outcome, reason = judge_settled_on_deck(
        x[Q.SL_P], quat_to_rotmat(x[Q.SL_Q]), pose, 1.5, ContactLimits(), int(counts[0]), int(counts[1])
    )
    assert outcome is Outcome.CRASHED and "ground" in reason and "not_on_pad" in reason


def test_a_level_deck_row_is_the_flat_world_contact():
    # the tilted branch is only taken on a tilted deck: a level deck's row leaves the flat world's
    # arithmetic alone, and a tilted deck at zero tilt gives the same forces to rounding
    flat = np.zeros(Q.N_DK)
    flat[Q.DK_ON], flat[Q.DK_HALF] = 1.0, 5.0
    flat[Q.DK_P + 2] = DECK_Z
    tilted = _tilted_deck(0.0)
    x = _resting_on(tilted)
    x[Q.IX_P + 2] -= 0.002
    x[Q.SL_V] = (0.3, -0.2, -0.1)
    f_flat, c_flat = _wrench(x, flat)
    f_tilt, c_tilt = _wrench(x, tilted)
    assert c_flat[0] == c_tilt[0] == 4
    np.testing.assert_allclose(f_tilt, f_flat, rtol=1e-12, atol=1e-12)


# -- the range finder on the deck ------------------------------------------------------------------------


def test_the_range_to_a_tilted_deck_is_the_ray_plane_distance():
    rng = np.random.default_rng(3)
    R = _rx(math.radians(8.0)) @ np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    p = np.array([1.0, -2.0, DECK_Z])
    n = R[:, 2]
    ext = np.array([-3.0, 3.0, -2.0, 2.0])
    on_deck = on_sea = 0
    for _ in range(400):
        o = p + np.array([*rng.uniform(-4.0, 4.0, 2), rng.uniform(0.5, 6.0)])
        d = np.array([*rng.normal(0.0, 0.3, 2), -1.0])
        d /= np.linalg.norm(d)
        got = range_to_deck(o, d, p, R, ext)
        lam = float((p - o) @ n) / float(d @ n)
        local = R.T @ (o + lam * d - p)
        if ext[0] <= local[0] <= ext[1] and ext[2] <= local[1] <= ext[3]:
            assert got == pytest.approx(lam, rel=1e-12)
            on_deck += 1
        else:
            assert got == pytest.approx(o[2] / -d[2], rel=1e-12)  # the sea's mean level
            on_sea += 1
    assert on_deck > 100 and on_sea > 50
    rf = RangeFinder(RangeFinderConfig(noise_std_m=0.0, max_range_m=40.0), np.random.default_rng(0))
    q = np.array([math.sin(0.1), 0.0, 0.0, math.cos(0.1)])  # rolled 0.2 rad
    p_WB = p + np.array([0.3, 0.2, 3.0])
    o = p_WB + quat_to_rotmat(q) @ np.array(rf.config.origin_B)
    d = -quat_to_rotmat(q)[:, 2]
    expected = float((p - o) @ n) / float(d @ n)
    assert rf.measure_on_deck(p_WB, q, p, R, ext) == pytest.approx(expected, rel=1e-12)


# -- the camera sees the tilted deck ---------------------------------------------------------------------


def _deck_mask(renderer, p_WC, R_WC, p_WP, R_WP):
    img = renderer.render(p_WC, R_WC, (p_WP, 0.0), R_WP=R_WP).astype(np.int16)
    bare = renderer.render(p_WC, R_WC, (p_WP + np.array([500.0, 0.0, 0.0]), 0.0), R_WP=R_WP).astype(np.int16)
    return (np.abs(img - bare) > 0).astype(np.uint8)


def _polygon_mask(camera, corners_W, p_WC, R_WC):
    X_C = (corners_W - p_WC) @ R_WC
    uv = camera.project(X_C)
    mask = np.zeros((camera.height, camera.width), np.uint8)
    cv2.fillConvexPoly(mask, np.round(uv * 16).astype(np.int32), 1, lineType=cv2.LINE_8, shift=4)
    return mask


def test_a_rolled_deck_renders_where_its_corners_project():
    from alight.cameras.pinhole import PinholeCamera
    from alight.pads import FalangaTag
    from alight.sim.render import Renderer, RenderOptions
    from alight.sim.textures import make_ground_texture

    camera = PinholeCamera.default_downward()
    options = RenderOptions(noise_sigma_dn=0.0, deck_length_m=3.0, deck_width_m=2.4, deck_gray_dn=20.0)
    renderer = Renderer(camera, make_ground_texture("grass", np.random.default_rng(0)), FalangaTag(), options)
    R_WC = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # looking down
    p_WC = np.array([0.2, -0.1, DECK_Z + 4.0])
    p_WP = np.array([0.0, 0.0, DECK_Z])
    R_WP = _rx(math.radians(20.0))
    got = _deck_mask(renderer, p_WC, R_WC, p_WP, R_WP)
    corners_P = renderer.deck_corners_P
    rolled = _polygon_mask(camera, p_WP + corners_P @ R_WP.T, p_WC, R_WC)
    level = _polygon_mask(camera, p_WP + corners_P, p_WC, R_WC)

    def iou(a, b):
        return float(np.sum(a & b)) / float(np.sum(a | b))

    assert iou(got, rolled) > 0.98
    assert iou(got, level) < 0.92  # the test sees the roll: the level deck's outline does not fit
    # a yaw-only R_WP renders exactly as the level deck turned by that yaw
    c, s = math.cos(0.4), math.sin(0.4)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    a = renderer.render(p_WC, R_WC, (p_WP, 0.4), R_WP=Rz)
    b = renderer.render(p_WC, R_WC, (p_WP, 0.4))
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 1


# -- the judge in the deck's frame -----------------------------------------------------------------------


def _pose(roll: float, v=(0.0, 0.0, 0.0), w=(0.0, 0.0, 0.0)) -> DeckPose:
    return DeckPose(np.array([0.0, 0.0, DECK_Z]), _rx(roll), np.array(v, float), np.array(w, float),
                    (-4.0, 4.0, -3.0, 3.0))  # fmt: skip


def test_the_judge_measures_speed_and_tilt_against_the_deck():
    roll = math.radians(6.0)
    deck = _pose(roll, v=(3.0, 0.0, 0.5), w=(0.2, 0.0, 0.0))
    n = deck.R_WP[:, 2]
    p_WB = deck.p_WP + deck.R_WP @ np.array([0.1, 0.2, AF.gear_height])
    v_surface = deck.surface_velocity(p_WB)
    t_dir = deck.R_WP[:, 0]
    v_WB = v_surface - 0.4 * n + 0.3 * t_dir  # closing at 0.4 m/s, sliding at 0.3 m/s along the deck
    R_WB = _rx(roll + math.radians(4.0))
    c = judge_contact(p_WB, v_WB, R_WB, None, 1.5, AF.gear_height, ContactLimits(), surface="pad", deck=deck)  # type: ignore[arg-type]
    assert c is not None and c.outcome is Outcome.LANDED and c.deck is not None
    assert c.deck.normal_speed_mps == pytest.approx(0.4, abs=1e-12)
    assert c.deck.tangential_speed_mps == pytest.approx(0.3, abs=1e-12)
    assert c.deck.relative_tilt_rad == pytest.approx(math.radians(4.0), abs=1e-9)
    assert c.deck.deck_tilt_rad == pytest.approx(roll, abs=1e-12)
    assert c.deck.touchdown_error_m == pytest.approx(math.hypot(0.1, 0.2), abs=1e-12)
    fast = judge_contact(p_WB, v_surface - 1.2 * n, deck.R_WP, None, 1.5, AF.gear_height, ContactLimits(),  # type: ignore[arg-type]
                         surface="pad", deck=deck)  # fmt: skip
    assert fast is not None and fast.outcome is Outcome.CRASHED and fast.reason == "vertical_speed"


def test_a_vehicle_that_slid_off_the_deck_is_judged_crashed():
    deck = _pose(math.radians(12.0))
    on = deck.p_WP + deck.R_WP @ np.array([0.0, 0.0, AF.gear_height])
    lim = ContactLimits()
    assert judge_settled_on_deck(on, deck.R_WP, deck, 1.5, lim, 4, 0) == (Outcome.LANDED, "")
    off = deck.p_WP + deck.R_WP @ np.array([0.0, 1.2, AF.gear_height])  # on the deck, off the pad
    assert judge_settled_on_deck(off, deck.R_WP, deck, 1.5, lim, 4, 0) == (Outcome.CRASHED, "off_footprint")
    assert judge_settled_on_deck(off, np.eye(3), deck, 1.5, lim, 0, 2)[0] is Outcome.CRASHED  # in the sea


# -- the MRU broadcast -----------------------------------------------------------------------------------


def test_the_motion_telemetry_samples_the_deck_at_its_rate_after_its_latency():
    cfg = MotionTelemetryConfig(
        rate_hz=10.0, latency_s=0.05, attitude_noise_deg=0.0, heave_rate_noise_mps=0.0
    )
    mru = MruStream(cfg, np.random.default_rng(0))
    R = _rx(0.05)
    got = []
    for k in range(200):  # 1 s at 200 Hz
        got += mru.arrivals(k * 0.005, R, 0.7)
    assert len(got) == 10
    assert all(m.t_arrival == pytest.approx(m.t_stamp + 0.05) for m in got)
    assert got[0].attitude == pytest.approx([0.05, 0.0]) and got[0].heave_rate == 0.7


# -- a seeded mission on the deck ------------------------------------------------------------------------


def test_a_seeded_sea_mission_lands_and_reports_the_deck_figures():
    from alight.evaluation.result import MissionResult
    from alight.evaluation.runner import run_mission

    case = {
        "preset": "groundtruth",
        "seed": 1,
        "platform": {"path": "straight", "speed_mps": 1.5, "sea": {"sea_state": 3, "vessel": "patrol_boat"}},
    }
    run = run_mission(scenario_from_dict(case))
    r = run.result
    assert r["outcome"] == "landed" and r["contact_surface"] == "pad"
    for key in ("deck_touchdown_error_m", "deck_normal_speed_mps", "deck_tangential_speed_mps",
                "deck_relative_tilt_deg", "deck_tilt_deg"):  # fmt: skip
        assert isinstance(r[key], float) and math.isfinite(r[key]), key
    assert r["deck_touchdown_error_m"] < 0.75 and r["deck_normal_speed_mps"] <= 1.0
    row = MissionResult.from_result(r).row()
    assert row["deck_tilt_deg"] == r["deck_tilt_deg"]
    again = run_mission(scenario_from_dict(case)).result
    assert again["deck_tilt_deg"] == r["deck_tilt_deg"]  # the sea is seeded by the scenario
    flat = run_mission(
        scenario_from_dict({**case, "platform": {"path": "straight", "speed_mps": 1.5}})
    ).result
    assert "deck_tilt_deg" not in flat
    assert MissionResult.from_result(flat).row()["deck_tilt_deg"] is None
