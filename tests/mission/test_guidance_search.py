"""The search goes on around the area after a full pass without a sighting."""

from __future__ import annotations

import numpy as np

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.guidance import Guidance, GuidanceConfig
from alight.mission.state_machine import MissionConfig
from alight.planning.candidates import CandidatePlanner, PlannerConfig
from alight.types import EgoState, Mode


def _ego(t: float, p: np.ndarray) -> EgoState:
    return EgoState(t, p, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))


def test_after_a_full_pass_the_search_flies_a_ring_around_the_area() -> None:
    config = GuidanceConfig(search_area=(-20.0, 20.0, -20.0, 20.0), search_expansions=1, search_growth_m=20.0)
    g = Guidance(MissionConfig(), CandidatePlanner(PlannerConfig.from_airframe(DEFAULT_AIRFRAME)), config)
    hover = np.array([0.0, 0.0, 4.0])
    g.update(0.0, Mode.EXPLORE, _ego(0.0, hover), None, None, hover)
    first = g._route
    assert first is not None
    t_done = first.t_first_pass_end + 0.05
    p_done = first.reference(t_done)[0]
    g.update(t_done, Mode.EXPLORE, _ego(t_done, p_done), None, None, hover)
    ring = g._route
    assert ring is not first and ring is not None
    ts = np.linspace(ring.t_cycle_start, ring.t_first_pass_end, 400)
    xy = np.array([ring.reference(t)[0][:2] for t in ts])
    # the ring's loops stay outside the searched area
    # and inside the grown one
    assert np.all(np.max(np.abs(xy), axis=1) > 20.0)
    assert np.max(np.abs(xy)) < 40.0 + 4.0  # the turns between loops swing out a little
    # the reference is continuous at the switch
    np.testing.assert_allclose(ring.reference(t_done)[0], p_done, atol=1e-6)
    # no further expansion past search_expansions
    t_end = ring.t_first_pass_end + 0.05
    g.update(t_end, Mode.EXPLORE, _ego(t_end, ring.reference(t_end)[0]), None, None, hover)
    assert g._route is ring
