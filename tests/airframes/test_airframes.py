"""Airframes as data (``alight.airframes``): the packaged files, their validation, the scenario key,
and a hover of the heavy airframe in the closed loop."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from alight.airframe import DEFAULT_AIRFRAME, Airframe
from alight.airframes import UNITS, load_airframe, packaged_airframes, read_airframe_file
from alight.control import (
    HighLevelController,
    HighLevelGains,
    low_level,
    pack_high_level_params,
    pack_low_level_params,
)
from alight.control.high_level import HL_TAN_TILT
from alight.errors import ConfigError
from alight.scenario import scenario_from_dict
from alight.sim.quadrotor import IX_W, initial_state, pack_params, step
from alight.types import EgoState, Reference

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "alight" / "airframes"


def _physical(af: Airframe) -> dict[str, object]:
    return {f.name: getattr(af, f.name) for f in dataclasses.fields(af) if f.init}


def _file_keys(af: Airframe) -> dict[str, object]:
    """The keys of an airframe file for ``af`` (plain numbers; the tilt in degrees)."""
    out = {k: (list(v) if isinstance(v, tuple) else v) for k, v in _physical(af).items()}
    out["max_tilt_deg"] = math.degrees(float(out.pop("max_tilt_rad")))  # type: ignore[arg-type]
    return out


def test_f450_file_is_the_default_airframe_exactly() -> None:
    f450 = load_airframe("f450")
    assert f450 == DEFAULT_AIRFRAME == Airframe()
    assert _physical(f450) == _physical(Airframe())  # every field, bit for bit
    np.testing.assert_array_equal(pack_params(f450), pack_params(Airframe()))
    gains = HighLevelGains()
    np.testing.assert_array_equal(
        pack_high_level_params(f450, gains), pack_high_level_params(Airframe(), gains)
    )
    # the controller's tilt limit is still the 45 deg it always was
    assert pack_high_level_params(f450, gains)[HL_TAN_TILT] == math.tan(math.radians(45.0))


def test_controller_takes_the_tilt_limit_from_the_airframe_unless_the_gains_set_it() -> None:
    m100 = load_airframe("matrice100")
    assert pack_high_level_params(m100, HighLevelGains())[HL_TAN_TILT] == pytest.approx(
        math.tan(math.radians(35))
    )
    gains = HighLevelGains(max_tilt=0.5)
    assert pack_high_level_params(m100, gains)[HL_TAN_TILT] == pytest.approx(math.tan(0.5))


@pytest.mark.parametrize("name", ["f450", "matrice100"])
def test_packaged_files_state_unit_and_source_of_every_number(name: str) -> None:
    assert name in packaged_airframes()
    raw = yaml.safe_load((PACKAGE / f"{name}.yaml").read_text(encoding="utf-8"))
    assert set(UNITS) <= set(raw)
    for key in UNITS:
        assert raw[key]["unit"] == UNITS[key], key
        assert len(str(raw[key]["source"])) > 10, key


@pytest.mark.parametrize("name", ["f450", "matrice100"])
def test_round_trip_through_a_user_file(tmp_path: Path, name: str) -> None:
    af = load_airframe(name)
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(_file_keys(af)), encoding="utf-8")
    assert load_airframe(str(path)) == af
    assert read_airframe_file(path).airframe() == af


def test_heavy_airframe_is_heavier_and_has_more_thrust() -> None:
    m100, f450 = load_airframe("matrice100"), load_airframe("f450")
    assert 2.4 <= m100.mass <= 3.6
    assert m100.thrust_to_weight > f450.thrust_to_weight
    assert m100.collective_accel_limits[1] > f450.collective_accel_limits[1]


def _file(tmp_path: Path, **changes: object) -> str:
    data = _file_keys(Airframe())
    data.update(changes)
    data = {k: v for k, v in data.items() if v is not None}
    path = tmp_path / "af.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"mass": -1.0}, "mass: Input should be greater than 0"),
        ({"thrust_to_weight": 1.1}, "thrust_to_weight: Input should be greater than or equal to 1.2"),
        ({"rotor_drg": 0.3}, "rotor_drg: Extra inputs are not permitted"),
        ({"arm_length": None}, "arm_length: Field required"),
        ({"inertia_diag": [0.01, 0.01, 0.05]}, "largest moment exceeds the sum"),
        ({"motor_thrust_min_N": 5.0}, "must be below the largest rotor thrust"),
        ({"mass": {"value": 1.0, "unit": "g", "source": "x"}}, "mass: unit must be 'kg', got 'g'"),
        ({"mass": {"value": 1.0, "units": "kg"}}, "unknown key(s) ['units']"),
        ({"max_tilt_deg": 89.0}, "max_tilt_deg: Input should be less than or equal to 80"),
        ({"body_drag_area_m2": float("nan")}, "body_drag_area_m2: Input should be a finite number"),
    ],
)
def test_bad_files_give_one_line(tmp_path: Path, changes: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        load_airframe(_file(tmp_path, **changes))
    text = str(err.value)
    assert message in text and "\n" not in text and "af.yaml" in text


def test_unknown_name_and_missing_file() -> None:
    with pytest.raises(
        ConfigError, match=r"unknown airframe 'f451': expected one of \['f450', 'matrice100'\]"
    ):
        load_airframe("f451")
    with pytest.raises(ConfigError, match="no such airframe file"):
        load_airframe("nowhere/af.yaml")


def test_scenario_key_selects_and_validates(tmp_path: Path) -> None:
    assert scenario_from_dict({}).airframe == "f450"
    assert scenario_from_dict({"airframe": "matrice100"}).airframe == "matrice100"
    with pytest.raises(ConfigError, match=r"^s.yaml: airframe: .*unknown airframe 'x'"):
        scenario_from_dict({"airframe": "x"}, "s.yaml")
    with pytest.raises(ConfigError, match="thrust_to_weight"):
        scenario_from_dict({"airframe": _file(tmp_path, thrust_to_weight=1.0)}, "s.yaml")


def test_cli_fly_with_a_bad_airframe_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from alight.cli import main

    scenario = tmp_path / "s.yaml"
    scenario.write_text("preset: groundtruth\nairframe: f999\n", encoding="utf-8")
    assert main(["fly", str(scenario), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown airframe 'f999'" in err and "\n" not in err


def _hover(af: Airframe, f_ext_W: np.ndarray, v_wind_W: np.ndarray, ki: float, seconds: float) -> np.ndarray:
    """Hold the origin with the controller (100 Hz) and the rate loop + dynamics (1 kHz); positions."""
    ctl = HighLevelController(af, HighLevelGains.from_bandwidth(3.0, ki=(ki, ki, ki), integral_limit=6.0))
    ll, sp = pack_low_level_params(af), pack_params(af)
    x = initial_state(np.zeros(3), 0.0, af.weight_N / 4.0)
    z = np.zeros(3)
    out = []
    for i in range(int(seconds * 100)):
        t = i * 0.01
        ego = EgoState(t=t, p_WB=x[0:3], v_WB=x[3:6], q_WB=x[6:10], w_WB_B=x[10:13])
        cmd = ctl.command(ego, Reference(t=t, p=z, v=z, a=z, j=z, yaw=0.0))
        for _ in range(10):
            u = low_level(cmd.thrust_N, np.array(cmd.w_WB_B_cmd), x[IX_W : IX_W + 3], ll)
            x = step(x, u, f_ext_W, v_wind_W, sp, 0.001)
        out.append(x[0:3].copy())
    return np.array(out)


def test_heavy_airframe_hovers_in_still_air_and_holds_in_12_mps_wind() -> None:
    m100 = load_airframe("matrice100")
    still = _hover(m100, np.zeros(3), np.zeros(3), 0.0, 5.0)
    assert np.abs(still).max() < 1e-6  # hover is an equilibrium: nothing moves
    # 12 m/s steady wind on the body drag area (held constant at the hover value) and the rotor drag
    v_wind = np.array([12.0, 0.0, 0.0])
    f_body = 0.5 * 1.2 * m100.body_drag_area_m2 * 144.0 * np.array([1.0, 0.0, 0.0])
    held = _hover(m100, f_body, v_wind, 2.0, 20.0)
    assert np.linalg.norm(held[-100:], axis=1).max() < 0.05  # the integral removes the offset
