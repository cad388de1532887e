"""The touchdown tilt limit (``mission.land_touchdown_max_tilt_rad``, PX4's ``MPC_TILTMAX_LND``): in a
committed descent with the feet close to the deck, the mission limits the controller's tilt (the pipeline
sets the limit on it)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME
from alight.control import TiltLimited
from alight.mission.presets import PRESETS, build_preset
from alight.mission.state_machine import MissionConfig
from alight.scenario import scenario_from_dict
from alight.types import EgoState, Mode

LEVEL = EgoState(
    t=0.0, p_WB=np.array([0.0, 0.0, 1.0]), v_WB=np.zeros(3), q_WB=np.array([0, 0, 0, 1.0]), w_WB_B=np.zeros(3)
)


def _pipeline(preset: str, **mission: float):  # type: ignore[no-untyped-def]
    s = scenario_from_dict({"preset": preset, "seed": 1, "mission": mission})
    return build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline


def _limits_after(pipeline, committed: bool, readings: list[float | None], mode: Mode = Mode.LAND) -> list:  # type: ignore[no-untyped-def]
    """The tilt limits the mission asks of the controller while the range finder reads ``readings``, each
    one where it changes (as the pipeline sets them)."""
    changes: list[float | None] = []
    current: float | None = None
    pipeline.mission._committed_since = 1.0 if committed else None
    for k, r in enumerate(readings):
        pipeline.on_range(0.01 * k, r)
        limit = pipeline.mission.tilt_limit_rad(mode, LEVEL, pipeline.range_raw_m)
        if limit != current:
            changes.append(limit)
            current = limit
    return changes


def test_the_limit_applies_committed_and_close_only_and_is_lifted_again() -> None:
    p = _pipeline("alight", land_touchdown_max_tilt_rad=0.38, land_touchdown_clearance_m=0.1)
    # high above: nothing; 5 cm from the feet: limited; the range finder's "too close" (-inf): still; a
    # dropout (None, NaN) or a reading above the clearance lifts it
    calls = _limits_after(p, True, [0.3, 0.05, -math.inf, None, 0.05, math.nan, 0.05, 0.2])
    assert calls == [0.38, None, 0.38, None, 0.38, None]
    # not committed (the gates still hold the descent), or not landing: never limited
    assert _limits_after(_pipeline("alight", land_touchdown_max_tilt_rad=0.38), False, [0.05, 0.02]) == []
    p = _pipeline("alight", land_touchdown_max_tilt_rad=0.38)
    assert _limits_after(p, True, [0.05], mode=Mode.GO_AROUND) == []
    # off (the papers' descent): never limited
    assert _limits_after(_pipeline("falanga2017"), True, [0.05, 0.02]) == []


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_touchdown_tilt_keys_act_on_every_preset(preset: str) -> None:
    p = _pipeline(preset, land_touchdown_max_tilt_rad=0.3, land_touchdown_clearance_m=0.15)
    cfg = p.mission.config
    assert (cfg.land_touchdown_max_tilt_rad, cfg.land_touchdown_clearance_m) == (0.3, 0.15)
    assert isinstance(p.controller, TiltLimited)  # so the limit reaches the vehicle
    assert _limits_after(p, True, [0.1]) == [0.3]
    default = _pipeline(preset).mission.config.land_touchdown_max_tilt_rad
    assert default == (0.38 if preset == "alight" else None)  # the papers' descents lean as they need
    with pytest.raises(ValueError, match="land_touchdown_max_tilt_rad"):
        MissionConfig(land_touchdown_max_tilt_rad=1.6)
