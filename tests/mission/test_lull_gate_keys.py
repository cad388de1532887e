"""The lull gate's scenario keys reach every preset's state machine (the gate itself is tested in
test_state_machine.py on the one Mission class every preset flies)."""

from __future__ import annotations

import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.presets import PRESETS, build_preset
from alight.scenario import scenario_from_dict


def _mission(preset: str, **keys: float):  # type: ignore[no-untyped-def]
    s = scenario_from_dict({"preset": preset, "seed": 1, "mission": keys})
    return build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline.mission


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_lull_gate_keys_act_on_every_preset(preset: str) -> None:
    cfg = _mission(preset, land_commit_max_tilt_rad=0.3, land_tilt_min_spread_rad=0.02).config
    assert (cfg.land_commit_max_tilt_rad, cfg.land_tilt_min_spread_rad) == (0.3, 0.02)
    default = _mission(preset).config
    if preset == "alight":
        assert (default.land_commit_max_tilt_rad, default.land_tilt_min_spread_rad) == (0.28, 0.087)
    else:
        assert default.land_commit_max_tilt_rad is None  # the papers commit on their position gates


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_turn_gate_key_acts_on_every_preset(preset: str) -> None:
    cfg = _mission(preset, land_commit_max_platform_accel_mps2=2.0).config
    assert cfg.land_commit_max_platform_accel_mps2 == 2.0
    default = _mission(preset).config.land_commit_max_platform_accel_mps2
    assert default == (1.5 if preset == "alight" else None)  # the papers commit on their position gates
    with pytest.raises(Exception, match="land_commit_max_platform_accel_mps2"):
        _mission(preset, land_commit_max_platform_accel_mps2=float("nan"))


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_steady_tilt_ceiling_key_acts_on_every_preset(preset: str) -> None:
    assert _mission(preset, land_steady_tilt_max_rad=0.4).config.land_steady_tilt_max_rad == 0.4
    default = _mission(preset).config.land_steady_tilt_max_rad
    assert default == (0.42 if preset == "alight" else None)
