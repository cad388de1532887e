"""Results are never lost: resume after SIGKILL, a truncated last line, Ctrl-C, and refusing to mix two
different campaigns in one output directory."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import campaign_fakes
import pytest
import yaml

from alight.campaign import campaign_from_dict, load_campaign, run_campaign
from alight.campaign.store import ResultsStore, columns_for, read_rows
from alight.errors import ConfigError, InputError

HERE = Path(__file__).resolve().parent


def _campaign(**over: object) -> dict:
    data: dict = {
        "name": "resume",
        "base": {"duration_s": 10.0},
        "presets": ["groundtruth", "falanga2017"],
        "seeds_per_condition": 3,
        "seed": 5,
        "grid": {"platform.speed_mps": [1.0, 1.5]},
        "timeout_s": 60.0,
    }
    data.update(over)
    return data


def _lines(path: Path) -> list[str]:
    return path.read_text(encoding="utf-8").splitlines()


def test_truncated_last_line_is_dropped_and_the_mission_flown_again(tmp_path: Path) -> None:
    campaign = campaign_from_dict(_campaign())
    run_campaign(campaign, tmp_path, workers=2, limit=3, mission_fn=campaign_fakes.instant, report=False)
    results = tmp_path / "results.csv"
    before = _lines(results)
    assert len(before) == 1 + 3
    # a kill in the middle of writing the fourth row
    with results.open("a") as f:
        f.write("c000-falanga2017-r001,c000,falanga2017,1,12")
    run_campaign(campaign, tmp_path, workers=2, mission_fn=campaign_fakes.instant, report=False)
    after = _lines(results)
    assert after[: len(before)] == before
    ids = [line.split(",")[0] for line in after[1:]]
    assert sorted(ids) == sorted(m.mission_id for m in campaign.missions)
    assert results.read_bytes().endswith(b"\n")
    rows = read_rows(results)
    assert all(len(r) == len(columns_for(campaign.swept_parameters)) for r in rows)


def test_damage_other_than_a_cut_last_line_is_an_error(tmp_path: Path) -> None:
    columns = columns_for(["platform.speed_mps"])
    path = tmp_path / "results.csv"
    path.write_text(",".join(columns) + "\n" + "a,b\n" + "x," * (len(columns) - 1) + "y\n")
    with pytest.raises(InputError, match="line 2 has 2 cells"):
        ResultsStore.open(path, columns)
    path.write_text(",".join(columns[:3]))  # killed while writing the header: no rows yet, start afresh
    store = ResultsStore.open(path, columns)
    assert _lines(path) == [",".join(columns)]
    with pytest.raises(InputError, match="another campaign process is writing to this directory"):
        ResultsStore.open(path, columns)
    store.close()
    ResultsStore.open(path, columns).close()


def test_resume_refuses_a_changed_campaign_but_accepts_more_seeds(tmp_path: Path) -> None:
    run_campaign(
        campaign_from_dict(_campaign()), tmp_path, workers=1, limit=2, mission_fn=campaign_fakes.instant
    )
    changed = campaign_from_dict(_campaign(seed=6))
    with pytest.raises(ConfigError, match="use another --out") as info:
        run_campaign(changed, tmp_path, workers=1, mission_fn=campaign_fakes.instant)
    assert "\n" not in str(info.value)
    other_base = campaign_from_dict(_campaign(base={"duration_s": 11.0}))
    with pytest.raises(ConfigError, match="has a different scenario now"):
        run_campaign(other_base, tmp_path, workers=1, mission_fn=campaign_fakes.instant)
    swept = campaign_from_dict(
        _campaign(grid={"platform.path": ["straight"], "platform.speed_mps": [1.0, 1.5]})
    )
    with pytest.raises(InputError, match="columns are not this campaign's"):
        run_campaign(swept, tmp_path, workers=1, mission_fn=campaign_fakes.instant)

    more = campaign_from_dict(_campaign(seeds_per_condition=4))
    result = run_campaign(more, tmp_path, workers=2, mission_fn=campaign_fakes.instant, report=False)
    assert result.n_skipped == 2 and result.n_run == len(more.missions) - 2
    ids = [r["mission_id"] for r in read_rows(tmp_path / "results.csv")]
    assert sorted(ids) == sorted(m.mission_id for m in more.missions)


def _cli(campaign_file: Path, out: Path, env: dict[str, str], *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "alight.cli", "campaign", str(campaign_file), "--out", str(out), *extra],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _env(**extra: str) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(HERE), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["ALIGHT_CAMPAIGN_MISSION_FN"] = "campaign_fakes:sleepy"
    env.update(extra)
    return env


def _wait_rows(results: Path, n: int, proc: subprocess.Popen, limit_s: float = 120.0) -> None:
    t_end = time.monotonic() + limit_s
    while time.monotonic() < t_end:
        if proc.poll() is not None:
            raise AssertionError(f"campaign ended early: {proc.communicate()}")
        if results.is_file() and results.read_text().count("\n") >= n + 1:
            return
        time.sleep(0.05)
    raise AssertionError(f"fewer than {n} rows after {limit_s} s")


def _write_campaign(tmp_path: Path, **over: object) -> Path:
    path = tmp_path / "camp.yaml"
    path.write_text(yaml.safe_dump(_campaign(**over)))
    return path


def test_sigkill_then_rerun_records_every_mission_exactly_once(tmp_path: Path) -> None:
    camp = _write_campaign(tmp_path)
    out = tmp_path / "out"
    proc = _cli(camp, out, _env(), "--workers", "2")
    _wait_rows(out / "results.csv", 3, proc)
    proc.kill()
    proc.communicate()
    kept = read_rows(out / "results.csv")  # what survived, a possibly cut last line ignored
    assert 3 <= len(kept) < 12

    again = subprocess.run(
        [sys.executable, "-m", "alight.cli", "campaign", str(camp), "--out", str(out), "--workers", "2"],
        env=_env(),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert again.returncode == 0, again.stderr
    rows = read_rows(out / "results.csv")
    ids = [r["mission_id"] for r in rows]
    assert sorted(ids) == sorted(m.mission_id for m in load_campaign(camp).missions)
    assert len(ids) == len(set(ids))
    assert rows[: len(kept)] == kept
    assert f"12/12 missions recorded ({12 - len(kept)} flown now, 0 errors)" in again.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_missions"] == 12


def test_ctrl_c_stops_cleanly_and_keeps_what_finished(tmp_path: Path) -> None:
    camp = _write_campaign(tmp_path)
    out = tmp_path / "out"
    pids = tmp_path / "pids"
    pids.mkdir()
    proc = _cli(camp, out, _env(ALIGHT_FAKE_PID_DIR=str(pids)), "--workers", "2")
    _wait_rows(out / "results.csv", 2, proc)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130
    message = [line for line in stderr.splitlines() if not line.startswith("alight campaign: missions are")]
    assert len(message) == 1 and message[0].startswith("alight campaign: interrupted: ")
    assert "run the same command again to resume" in message[0]
    rows = read_rows(out / "results.csv")
    assert 2 <= len(rows) < 12
    assert json.loads((out / "summary.json").read_text())["n_missions"] == len(rows)
    for pid_file in pids.iterdir():  # every worker process is gone
        with pytest.raises(ProcessLookupError):
            os.kill(int(pid_file.name), 0)


def test_report_command_errors_are_one_line(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "alight.cli", "report", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert (
        done.stderr.strip() == f"alight report: {tmp_path}: no results.csv (not a campaign output directory)"
    )


def test_a_directory_flown_through_one_autopilot_is_not_resumed_through_another(tmp_path: Path) -> None:
    # alight campaign --autopilot records how the missions were flown; mixing PX4's results with the
    # simulator's (or the emulator's) in one results.csv would compare nothing with anything
    campaign = campaign_from_dict(_campaign())
    px4 = {"kind": "px4", "mode": "offboard", "setpoint": "position", "flavour": "px4", "speed": 1.0}
    run_campaign(campaign, tmp_path, workers=1, limit=2, mission_fn=campaign_fakes.instant, report=False,
                 flown_with=px4)  # fmt: skip
    assert json.loads((tmp_path / "campaign.lock.json").read_text())["flown_with"] == px4
    with pytest.raises(ConfigError, match="flown with .*px4.*now with alight sim"):
        run_campaign(campaign, tmp_path, workers=1, mission_fn=campaign_fakes.instant, report=False)
    with pytest.raises(ConfigError, match="now with .*landing-target"):
        run_campaign(campaign, tmp_path, workers=1, mission_fn=campaign_fakes.instant, report=False,
                     flown_with={**px4, "mode": "landing-target"})  # fmt: skip
    r = run_campaign(campaign, tmp_path, workers=1, limit=3, mission_fn=campaign_fakes.instant, report=False,
                     flown_with=dict(px4))  # fmt: skip
    assert r.n_skipped == 2 and r.n_run == 1
