"""Vessel classes and platform.sea settings: the packaged YAMLs, one-line errors for bad files and keys."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from pydantic import ValidationError

from alight.errors import ConfigError
from alight.sim.sea import SeaConfig, load_vessel, packaged_vessels
from alight.sim.sea.vessel import UNITS, read_vessel_file

PACKAGED = Path(__file__).resolve().parents[2] / "src" / "alight" / "sim" / "sea" / "vessels"


def test_three_packaged_classes_with_a_source_on_every_number():
    assert {"small_usv", "patrol_boat", "frigate"} <= set(packaged_vessels())
    for name in packaged_vessels():
        raw = yaml.safe_load((PACKAGED / f"{name}.yaml").read_text())
        for key in UNITS:
            assert isinstance(raw[key], dict) and raw[key]["source"].strip(), (name, key)
        v = load_vessel(name)
        assert v.name == name
    usv, patrol, frigate = (load_vessel(n) for n in ("small_usv", "patrol_boat", "frigate"))
    # bigger hulls roll and heave more slowly (sheet sec. 3.2: boats roll at 2-5 s, ships at 5-15 s)
    assert usv.roll_period_s < patrol.roll_period_s < frigate.roll_period_s
    assert 2.0 <= usv.roll_period_s <= 5.0 and 5.0 <= frigate.roll_period_s <= 15.0
    assert usv.heave_period_s < patrol.heave_period_s < frigate.heave_period_s
    for v in (usv, patrol, frigate):
        assert v.roll_damping < v.heave_damping  # roll is the lightly damped axis


@pytest.mark.parametrize(
    ("name", "c_b", "c_wp", "gm_m"),
    [("small_usv", 0.45, 0.75, 0.8), ("patrol_boat", 0.45, 0.75, 1.2), ("frigate", 0.507, 0.78, 2.0)],
)
def test_the_packaged_periods_follow_from_the_formulas_their_sources_name(name, c_b, c_wp, gm_m):
    # heave 2 pi sqrt(2 d C_B / (C_wp g)); roll (Weiss, IMO IS Code 2008 2.3.4) 2 C B / sqrt(GM) with
    # C = 0.373 + 0.023 B/d - 0.043 L/100; pitch = heave; the files round to 0.1 s
    v = load_vessel(name)
    t_heave = 2 * math.pi * math.sqrt(2 * v.draft_m * c_b / (c_wp * 9.81))
    c = 0.373 + 0.023 * v.beam_m / v.draft_m - 0.043 * v.length_m / 100
    t_roll = 2 * c * v.beam_m / math.sqrt(gm_m)
    assert v.heave_period_s == pytest.approx(t_heave, abs=0.05)
    assert v.pitch_period_s == v.heave_period_s
    assert v.roll_period_s == pytest.approx(t_roll, abs=0.05)


def test_a_vessel_file_by_path_round_trips(tmp_path):
    data = yaml.safe_load((PACKAGED / "patrol_boat.yaml").read_text())
    data["name"] = "my_boat"
    data["roll_period_s"] = 6.0  # a bare number in the table's unit is accepted
    f = tmp_path / "boat.yaml"
    f.write_text(yaml.safe_dump(data))
    v = load_vessel(str(f))
    assert v.name == "my_boat" and v.roll_period_s == 6.0 and v.length_m == 26.5
    assert load_vessel(f) == v


def _write(tmp_path: Path, **changes: object) -> Path:
    data = yaml.safe_load((PACKAGED / "small_usv.yaml").read_text())
    for key, value in changes.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = value
    f = tmp_path / "v.yaml"
    f.write_text(yaml.safe_dump(data))
    return f


@pytest.mark.parametrize(
    ("changes", "needle"),
    [
        ({"draught_m": 1.0}, "draught_m"),
        ({"roll_period_s": None}, "roll_period_s"),
        ({"roll_period_s": {"value": 2.0, "unit": "min"}}, "unit must be 's'"),
        ({"roll_period_s": {"value": 2.0, "units": "s"}}, "unknown key"),
        ({"roll_damping": 0.0}, "roll_damping"),
        ({"heave_period_s": -1.0}, "heave_period_s"),
        ({"length_m": math.nan}, "length_m"),
        ({"beam_m": 9.0}, "exceeds length_m"),
        ({"draft_m": 3.0}, "below beam_m"),
        ({"pad_offset_m": [4.0, 0.0, 0.5]}, "off the hull"),
        ({"pad_offset_m": [0.0, 0.0]}, "pad_offset_m"),
        ({"yaw_fraction": 1.5}, "yaw_fraction"),
    ],
)
def test_bad_vessel_files_are_one_line(tmp_path, changes, needle):
    f = _write(tmp_path, **changes)
    with pytest.raises(ConfigError, match=needle) as info:
        load_vessel(str(f))
    assert "\n" not in str(info.value) and str(f) in str(info.value)


def test_missing_unreadable_and_unknown_vessels_are_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("length_m: [1, 2\n")
    listed = tmp_path / "list.yaml"
    listed.write_text("- 1\n- 2\n")
    for ref, needle in (
        (str(tmp_path / "none.yaml"), "no such file"),
        (str(bad), "not valid YAML"),
        (str(listed), "expected a mapping"),
        ("trawler", "unknown vessel 'trawler'"),
    ):
        with pytest.raises(ConfigError, match=needle) as info:
            load_vessel(ref)
        assert "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="no such file"):
        read_vessel_file(tmp_path)


def test_sea_config_gives_hs_and_tp():
    assert SeaConfig(sea_state=4).hs_tp() == (1.88, 8.8)
    assert SeaConfig(sea_state=3, tp_s=4.0, vessel="small_usv").hs_tp() == (0.88, 4.0)
    assert SeaConfig(hs_m=0.3, tp_s=2.5, spectrum="pm").hs_tp() == (0.3, 2.5)
    assert SeaConfig(sea_state=0).hs_tp()[0] == 0.0
    cfg = SeaConfig(sea_state=5, vessel="frigate", pad_offset_m=(-60.0, 2.0, 6.0), gamma=2.0)
    assert cfg.load_vessel().name == "frigate" and cfg.wave_direction_deg == 180.0


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({}, "needs sea_state or hs_m"),
        ({"sea_state": 3, "hs_m": 1.0, "tp_s": 5.0}, "not both"),
        ({"hs_m": 1.0}, "hs_m needs tp_s"),
        ({"hs_m": -0.5, "tp_s": 5.0}, "hs_m must be in"),
        ({"hs_m": 1.0, "tp_s": 0.0}, "tp_s must be in"),
        ({"sea_state": 12}, "WMO code"),
        ({"sea_state": 1}, "give tp_s"),
        ({"sea_state": 3, "spectrum": "bretschneider"}, "spectrum must be one of"),
        ({"sea_state": 3, "spectrum": "pm", "gamma": 3.3}, "Pierson-Moskowitz has none"),
        ({"sea_state": 3, "gamma": 0.5}, "gamma must be in"),
        ({"sea_state": 3, "wave_direction_deg": math.inf}, "wave_direction_deg"),
        ({"hs_m": 3.0, "tp_s": 3.0}, "steeper"),
        ({"sea_state": 3, "vessel": "trawler"}, "unknown vessel"),
        (
            {"sea_state": 3, "vessel": "small_usv", "pad_offset_m": (3.0, 0.0, 0.5)},
            "off the small_usv's hull",
        ),
        ({"sea_state": 3, "pad_offset_m": (0.0, math.nan, 0.5)}, "three finite numbers"),
        ({"sea_state": 3, "vessel": ""}, "must name a vessel"),
    ],
)
def test_bad_sea_settings_are_one_line(kwargs, needle):
    with pytest.raises(ConfigError, match=needle) as info:
        SeaConfig(**kwargs)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"sea_state": 3, "pad_offset_m": 1.0},
        {"sea_state": 3, "pad_offset_m": ("a", 0.0, 0.0)},
        {"hs_m": "1.5", "tp_s": 6.0},
        {"sea_state": 3, "wave_direction_deg": True},
        {"sea_state": 3.0},
    ],
)
def test_sea_settings_of_the_wrong_type_are_refused_by_their_declaration(kwargs):
    # the types are the settings dataclass's (pydantic, strict numbers); a scenario file gets them as one
    # line (tests/sim/test_sea_world.py)
    with pytest.raises(ValidationError):
        SeaConfig(**kwargs)
