"""Timing the final descent into a quiet window, and the gate the mission's landing runs: exact answers
on a synthetic deck (heave and roll sinusoids), and the state machine's hook."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import ConfigError
from alight.estimation.deck_estimator import DeckPrediction
from alight.mission.blocks import check_compatibility, resolve_blocks
from alight.mission.quiet_window import (
    QuietWindowConfig,
    QuietWindowGate,
    contact_times,
    plan_descent,
)
from alight.mission.state_machine import Mission, MissionConfig
from alight.scenario import scenario_from_dict
from alight.types import EgoState, Mode, PlatformEstimate

PERIOD = 6.0
W = 2.0 * math.pi / PERIOD
ROLL = math.radians(6.0)
HEAVE = 0.3
SINK = 0.5
CONFIG = QuietWindowConfig(settle_s=0.3, timing_tolerance_s=0.1, grid_step_s=0.01, replan_every_s=0.1)


class SyntheticDeck:
    """roll = 6 deg (or ``roll``) sin(w (t + shift)), heave = 0.3 m sin(w (t + shift)) (6 deg: within 3 deg
    within 0.5 s of each half period k * 3 s - shift; 4 deg: within 0.81 s), exact (zero covariance)."""

    def __init__(self, shift: float = 0.0, roll: float = ROLL) -> None:
        self.shift = shift
        self.roll = roll

    def predict_deck(self, times: np.ndarray) -> DeckPrediction:
        t = np.asarray(times, dtype=np.float64)
        ph = W * (t + self.shift)
        state = np.zeros((t.shape[0], 6))
        state[:, 0] = HEAVE * np.sin(ph)
        state[:, 1] = HEAVE * W * np.cos(ph)
        state[:, 2] = self.roll * np.sin(ph)
        state[:, 3] = self.roll * W * np.cos(ph)
        return DeckPrediction(t.copy(), state, np.zeros((t.shape[0], 6, 6)))


def test_contact_times_of_a_descent_onto_a_flat_deck_are_exact() -> None:
    t = np.arange(0.0, 10.0, 0.01)
    tc = contact_times(t, np.zeros_like(t), 2.0, 0.5)  # 2 m at 0.5 m/s: 4 s after each start
    ok = t <= 6.0 - 1e-9
    np.testing.assert_allclose(tc[ok], t[ok] + 4.0, atol=0.011)
    assert np.isnan(tc[~ok & (t > 6.02)]).all()


def test_the_descent_is_timed_to_meet_the_deck_in_the_middle_of_its_window() -> None:
    # hold at 1.0 m; a window around t = 3 s (roll crosses zero; the deck falls at 0.31 m/s: closing
    # 0.19 m/s, inside [0.1, 1.0]); feasible contacts at [2.6, 3.2], the middle 2.9 s
    pred = SyntheticDeck().predict_deck(np.arange(0.0, 10.0, 0.01))
    w = plan_descent(pred, 1.0, 0.0, CONFIG)
    assert w is not None
    assert w.t_open == pytest.approx(2.6, abs=0.02) and w.t_close == pytest.approx(3.2, abs=0.02)
    assert w.t_contact == pytest.approx(2.9, abs=0.03)
    # the descent meets the deck then: 1.0 - 0.5 (t_c - t_s) = 0.3 sin(w t_c)
    z_deck = HEAVE * math.sin(W * w.t_contact)
    assert 1.0 - SINK * (w.t_contact - w.t_start_descent) == pytest.approx(z_deck, abs=0.01)
    # from 0.4 m higher the descent starts 0.8 s earlier for the same contact
    w2 = plan_descent(pred, 1.4, 0.0, CONFIG)
    assert w2 is not None and w2.t_contact == pytest.approx(w.t_contact, abs=0.03)
    assert w2.t_start_descent == pytest.approx(w.t_start_descent - 0.8, abs=0.05)
    # from 1.5 m the middle (a start 0.04 s ago) is out of reach: the earliest reachable contact
    w3 = plan_descent(pred, 1.5, 0.0, CONFIG)
    assert w3 is not None and w3.t_start_descent == pytest.approx(0.0, abs=0.011) and w3.t_contact > 2.9


def test_the_gate_waits_above_the_highest_point_then_descends_and_goes_around_when_the_window_moves() -> None:
    deck = SyntheticDeck()
    cfg = QuietWindowConfig(settle_s=0.3, timing_tolerance_s=0.1, grid_step_s=0.05, replan_every_s=0.1)
    gate = QuietWindowGate(deck, cfg, SINK)
    top = HEAVE + cfg.hold_clearance_m
    assert gate.step(0.0, top + 0.5) == "descend"  # above the wait's height: approach it
    z_hold = top - 0.05
    decisions = []
    for t in np.arange(0.1, 3.0, 0.05):
        decisions.append(gate.step(float(t), z_hold))
        if decisions[-1] != "hold":
            break
    assert decisions[-1] == "descend" and len(decisions) > 1
    assert gate.window is not None
    # contact in the window's middle (2.9 s, as above), started when the plan said
    assert gate.window.t_contact == pytest.approx(2.9, abs=0.06)
    assert float(t) == pytest.approx(gate.window.t_start_descent, abs=0.06)
    # unchanged, the descent goes on
    assert gate.step(float(t) + 0.2, z_hold - SINK * 0.2) == "descend"
    # the deck's phase slips 0.4 s under the descent: the window closes before contact
    deck.shift = 0.4
    verdict = gate.step(float(t) + 0.4, z_hold - SINK * 0.4)
    assert verdict == "go_around"
    assert gate.reason == "the deck's quiet window closed before contact"


def test_the_gate_goes_around_when_no_window_comes() -> None:
    class Rough(SyntheticDeck):
        def predict_deck(self, times: np.ndarray) -> DeckPrediction:
            p = super().predict_deck(times)
            p.state[:, 2] += math.radians(10.0)  # a 10 deg list under the 6 deg roll: never within 3 deg
            return p

    gate = QuietWindowGate(Rough(), QuietWindowConfig(max_wait_s=2.0, grid_step_s=0.05), SINK)
    verdicts = [gate.step(t, 0.85) for t in np.arange(0.0, 2.5, 0.1)]
    assert verdicts[0] == "hold" and verdicts[-1] == "go_around"
    assert gate.reason == "no quiet window in the deck's motion"


def _ego(z: float) -> EgoState:
    return EgoState(
        t=0.0, p_WB=np.array([0.0, 0.0, z]), v_WB=np.zeros(3), q_WB=np.array([0.0, 0.0, 0.0, 1.0]),
        w_WB_B=np.zeros(3),
    )  # fmt: skip


def _target(t: float) -> PlatformEstimate:
    return PlatformEstimate(
        t=t, p_WP=np.zeros(3), v_WP=np.zeros(3), a_WP=np.zeros(3), yaw=0.0, cov_p_WP=np.eye(3) * 1e-4,
        t_last_measurement=t,
    )  # fmt: skip


def _landing_mission(deck: SyntheticDeck, **gate_kw: float) -> Mission:
    m = Mission(MissionConfig())
    m.attach_quiet_window(QuietWindowGate(deck, QuietWindowConfig(grid_step_s=0.05, **gate_kw), SINK))
    m.step(0.0, _ego(0.0), None)
    m.mode, m.mode_since = Mode.LAND, 0.0  # in the landing (not a transition of the table)
    return m


def test_the_mission_holds_for_the_window_then_releases_the_descent() -> None:
    # the default limits (3 deg over [t_c - 0.3, t_c + 1.0]) on a 4 deg roll: windows [3k - 0.51, 3k - 0.19]
    m = _landing_mission(SyntheticDeck(roll=math.radians(4.0)))
    holds = []
    for t in np.arange(0.02, 3.0, 0.02):
        m.step(float(t), _ego(0.85), _target(float(t)))
        holds.append(m.descent_hold)
    assert holds[0] and not holds[-1] and m.mode is Mode.LAND
    assert any(e.reason == "waiting above the deck for a quiet window" for e in m.events)


def test_the_mission_goes_around_when_the_window_closes_before_contact() -> None:
    deck = SyntheticDeck(roll=math.radians(4.0))
    m = _landing_mission(deck)
    t = 0.02
    while m.descent_hold or t < 0.1:
        m.step(t, _ego(0.85), _target(t))
        t += 0.02
    deck.shift = 0.4
    for _ in range(20):
        m.step(t, _ego(0.8), _target(t))
        t += 0.02
    assert m.mode is Mode.GO_AROUND and m.reason == "the deck's quiet window closed before contact"


def test_the_mission_goes_around_when_no_window_comes() -> None:
    class Rough(SyntheticDeck):
        def predict_deck(self, times: np.ndarray) -> DeckPrediction:
            p = super().predict_deck(times)
            p.state[:, 2] += math.radians(10.0)
            return p

    m = _landing_mission(Rough(), max_wait_s=1.0)
    for t in np.arange(0.02, 2.0, 0.02):
        m.step(float(t), _ego(0.85), _target(float(t)))
    assert m.mode is Mode.GO_AROUND and m.reason == "no quiet window in the deck's motion"


@pytest.mark.parametrize("preset, geolocator", [("kim_kaist", "flat_earth"), ("zamanakos_sdu", "homography")])
def test_the_level_pad_geolocators_are_refused_on_a_deck_in_one_line(preset: str, geolocator: str) -> None:
    eb = resolve_blocks(scenario_from_dict({"preset": preset}), load_camera=False)
    source = {stage: f"preset {preset}" for stage in eb.blocks}
    check_compatibility(eb.blocks, source, color=eb.color)  # level ground: flies
    with pytest.raises(ValueError, match=f"geolocator '{geolocator}' assumes a level pad") as err:
        check_compatibility(eb.blocks, source, color=eb.color, level_pad=False)
    assert "\n" not in str(err.value)
    # PnP measures the pad's pose, tilt included: it flies on a deck
    alight = resolve_blocks(scenario_from_dict({"preset": "alight"}), load_camera=False)
    check_compatibility(alight.blocks, source, color=alight.color, level_pad=False)


def test_a_sea_scenario_refuses_the_level_pad_geolocators_when_loaded() -> None:
    sea = {"sea_state": 3, "vessel": "patrol_boat"}
    for preset, geolocator in (("kim_kaist", "flat_earth"), ("zamanakos_sdu", "homography")):
        with pytest.raises(ConfigError, match=f"blocks.geolocator: geolocator '{geolocator}' assumes"):
            scenario_from_dict({"preset": preset, "platform": {"sea": sea}})
    resolve_blocks(scenario_from_dict({"preset": "alight", "platform": {"sea": sea}}), load_camera=False)
