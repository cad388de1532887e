"""``alight campaign --autopilot emulator|px4``: a mission through alight's emulated autopilot in a campaign
(the bridge in the sandbox, the emulator in its own process on ports the kernel picks, the platform's
GNSS fix across the side stream), the setting recorded in the lock and the result, and the settings
refused in one line. The campaign on real PX4 is measured beside the project (docs/px4.md); a stand-in
for PX4 is in test_px4_run.py."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from alight.cli import main
from alight.interfaces.autopilot_missions import AUTOPILOT_ENV, AutopilotSetting, fly_emulator_mission
from alight.scenario import load_scenario

DATA = Path(__file__).parent / "data"
CAMPAIGN = DATA / "emulator_campaign.yaml"


@pytest.mark.slow
def test_a_campaign_mission_through_the_emulator_lands_with_the_platforms_telemetry(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    argv = ["campaign", str(CAMPAIGN), "--autopilot", "emulator", "--setpoint", "rates", "--out", str(out)]
    assert main([*argv, "--no-progress"]) == 0
    rows = list(csv.DictReader((out / "results.csv").read_text().splitlines()))
    assert [r["outcome"] for r in rows] == ["landed"]
    assert float(rows[0]["touchdown_error_m"]) < 0.15
    lock = json.loads((out / "campaign.lock.json").read_text())
    assert lock["flown_with"]["kind"] == "emulator" and lock["flown_with"]["setpoint"] == "rates"
    (mission,) = (out / "missions").iterdir()
    assert sorted(p.name for p in mission.iterdir()) == ["result.json", "scenario.yaml"]  # landed: no log
    result = json.loads((mission / "result.json").read_text())
    assert result["autopilot"]["kind"] == "emulator" and result["sitl"]["flavour"] == "px4"
    fixes = result["bridge"]["accepted"]["platform_fix"]
    assert fixes > 100 and not result["bridge"]["rejected"].get("platform_fix")  # 10 Hz, 5 % lost
    # resuming the same directory with another autopilot is refused in one line
    capsys.readouterr()
    assert main(["campaign", str(CAMPAIGN), "--out", str(out), "--no-progress"]) == 2
    assert "flown with" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--autopilot", "px4", "--px4", "{tmp}/nothing"], "has no PX4 SITL build"),
        (["--autopilot", "emulator", "--engine", "dask"], "local engine only"),
        (["--setpoint", "rates"], "--setpoint acts only with --autopilot emulator or px4, not sim"),
        (["--autopilot", "emulator", "--px4-speed", "2"], "--px4-speed acts only with --autopilot px4"),
    ],
)
def test_autopilot_settings_are_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    argv = ["campaign", str(CAMPAIGN), "--out", str(tmp_path / "run"), "--no-progress"]
    assert main([*argv, *[a.replace("{tmp}", str(tmp_path)) for a in extra]]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "run" / "results.csv").exists()


def test_a_mission_function_without_its_setting_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(AUTOPILOT_ENV, raising=False)
    with pytest.raises(Exception, match=f"{AUTOPILOT_ENV} is not set"):
        fly_emulator_mission(load_scenario(CAMPAIGN.parent / "precland_slow.yaml"), Path("."))
    monkeypatch.setenv(AUTOPILOT_ENV, '{"kind": "rover"}')
    with pytest.raises(Exception, match="not a valid setting|must be one of"):
        AutopilotSetting.from_env()
    setting = AutopilotSetting(kind="px4", mode="landing-target", speed=2.0)
    monkeypatch.setenv(AUTOPILOT_ENV, setting.to_env())
    assert AutopilotSetting.from_env() == setting


def test_fly_through_the_emulator_refuses_the_simulators_own_outputs(tmp_path: Path) -> None:
    from types import SimpleNamespace

    from alight.errors import ConfigError
    from alight.interfaces.autopilot_missions import fly_through_command

    args = SimpleNamespace(autopilot="emulator", px4=None, px4_mode="offboard", px4_speed=1.0,
                           setpoint="rates", replay=False, mcap=True, bag=None)  # fmt: skip
    with pytest.raises(
        ConfigError, match="emulator: --replay, --mcap and --bag are for --autopilot sim only"
    ):
        fly_through_command(load_scenario(DATA / "precland_slow.yaml"), tmp_path, args)


def test_fly_refuses_an_autopilot_setting_that_would_not_act(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = str(DATA / "precland_slow.yaml")
    assert main(["fly", scenario, "--out", str(tmp_path), "--px4-mode", "landing-target"]) == 2
    err = capsys.readouterr().err.strip()
    assert (
        "--px4-mode acts only with --autopilot emulator or px4, not sim" in err and len(err.splitlines()) == 1
    )
    assert not (tmp_path / "result.json").exists()
