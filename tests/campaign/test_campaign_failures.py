"""What a campaign does when parts of it die: a real Dask worker SIGKILLed mid-campaign, a SIGKILLed
sandbox's scratch directory, a campaign whose missions all errored, refused option combinations, and the
warm-up that keeps numba's compile out of the first mission's clock."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import campaign_fakes
import pytest
import yaml

from alight.campaign import campaign_from_dict, run_campaign
from alight.campaign.engines import SCRATCH_PREFIX, sweep_stale_scratch
from alight.cli import main
from alight.errors import ConfigError

SRC = Path(__file__).resolve().parents[2] / "src"
HERE = Path(__file__).resolve().parent


def _rows(out: Path) -> list[dict[str, str]]:
    path = out / "results.csv"
    if not path.is_file():
        return []
    with path.open(newline="") as f:
        return [r for r in csv.DictReader(f) if r.get("mission_id")]


def _campaign(**over: object) -> dict[str, Any]:
    data: dict[str, Any] = {
        "name": "fakes",
        "base": {"duration_s": 10.0},
        "presets": ["groundtruth"],
        "seeds_per_condition": 1,
        "seed": 3,
    }
    data.update(over)
    return data


def _has_distributed() -> bool:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


# -- a real Dask worker killed mid-campaign ------------------------------------------------------------


def _spawn(args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as out:
        return subprocess.Popen(args, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)


@pytest.mark.skipif(not _has_distributed(), reason="needs dask.distributed")
@pytest.mark.parametrize("allowed_failures", [3, 0])
def test_a_killed_dask_worker_reflies_only_unrecorded_missions(tmp_path: Path, allowed_failures: int) -> None:
    """A scheduler and two workers on loopback (separate processes, no nanny: a killed worker stays
    dead); one worker is SIGKILLed once some rows are written. Every mission ends as exactly one row, and
    no mission that had its row when the worker died is flown again. With Dask's default retries the
    missions the worker was flying are flown again elsewhere; with none they are error rows.

    It was flaky (issue 15) two ways, both the engine's: (1) the killed worker's sandbox sees its socket
    close at once and exited without removing its scratch directory, which only its parent watcher (polling
    every 0.5 s) removed when it won the race; the sandbox now removes it on the way out. (2) Three missions
    were affected: the engine kept 2 missions per worker thread submitted, so with allowed-failures 0 the
    killed worker's running and waiting missions were two KilledWorker rows, and a third, finished there but
    not yet handed over, was flown again. The engine now submits one mission per worker thread."""
    from distributed import Client

    flights, scratch = tmp_path / "flights", tmp_path / "tmp"
    flights.mkdir()
    scratch.mkdir()
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(SRC), str(HERE)]),
        campaign_fakes.FLIGHT_LOG_ENV: str(flights),
        campaign_fakes.SLEEP_ENV: "0.4",
        "TMPDIR": str(scratch),
        "DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": str(allowed_failures),
    }
    sched_file = tmp_path / "scheduler.json"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [
        _spawn(
            [*dask, "--host", "127.0.0.1", "--port", "0", "--dashboard-address", ":0",
             "--scheduler-file", str(sched_file)],
            env,
            tmp_path / "scheduler.log",
        )
    ]  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not sched_file.is_file() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        worker = [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                  "--no-nanny", "--host", "127.0.0.1", "--no-dashboard"]  # fmt: skip
        workers = [_spawn(worker, env, tmp_path / f"worker{i}.log") for i in range(2)]
        procs += workers
        with Client(address, timeout="60s") as client:  # type: ignore[no-untyped-call]
            client.wait_for_workers(2, timeout=120)

        campaign = campaign_from_dict(_campaign(seeds_per_condition=14))
        out = tmp_path / "out"
        done: dict[str, Any] = {}

        def fly() -> None:
            try:
                done["result"] = run_campaign(
                    campaign, out, engine="dask", scheduler=address, mission_fn="campaign_fakes:logged",
                    report=False,
                )  # fmt: skip
            except BaseException as err:  # noqa: BLE001  (re-raised by the test below)
                done["error"] = err

        thread = threading.Thread(target=fly)
        thread.start()
        deadline = time.monotonic() + 120
        while len(_rows(out)) < 5 and thread.is_alive() and time.monotonic() < deadline:
            time.sleep(0.05)
        recorded_before = {r["mission_id"] for r in _rows(out)}
        assert 5 <= len(recorded_before) < 14, "the worker must die mid-campaign"
        victim = workers[0]
        os.kill(victim.pid, signal.SIGKILL)
        victim.wait()
        thread.join(timeout=180)
        assert not thread.is_alive()
        if "error" in done:
            raise done["error"]

        rows = _rows(out)
        ids = Counter(r["mission_id"] for r in rows)
        assert sorted(ids) == sorted(m.mission_id for m in campaign.missions)
        assert set(ids.values()) == {1}, "every planned mission is exactly one row"
        errors = {r["mission_id"]: r["error"] for r in rows if r["outcome"] == "error"}
        flown = Counter(p.name.split(".")[0] for p in flights.iterdir())
        again = {mid for mid, n in flown.items() if n > 1}
        assert not again & recorded_before, (
            f"recorded missions flown again: {sorted(again & recorded_before)}"
        )
        # Only what the killed worker held is affected. The engine submits one mission per worker thread
        # (2 here), so that is at most 2: the mission it was flying, and one it had finished whose result
        # had not reached the campaign yet (its result died with the worker).
        assert not errors.keys() & recorded_before and len(again) + len(errors) <= 2
        if allowed_failures:
            assert errors == {}
        else:
            # The mission being flown fails (KilledWorker). A finished one whose result was lost is not a
            # failure to Dask: it recomputes it whatever allowed-failures says, so it may be flown again
            # (it had no row yet, so nothing recorded is repeated). The worker has one thread, and the
            # engine gives it no mission to wait behind the one it flies: at most one KilledWorker.
            assert len(errors) <= 1, errors
            assert all(e.startswith("dask task failed: KilledWorker") for e in errors.values()), errors
        # the killed worker's sandbox removed its scratch directory when it saw its owner gone (it polls
        # every PARENT_POLL_S = 0.5 s; on a loaded 2-core machine the watcher thread may wait seconds for
        # the CPU, so the test allows 30 s)
        deadline = time.monotonic() + 30
        while list(scratch.glob(f"{SCRATCH_PREFIX}{victim.pid}-*")) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not list(scratch.glob(f"{SCRATCH_PREFIX}{victim.pid}-*"))
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()


# -- sandbox scratch directories ------------------------------------------------------------------------


def test_a_sigkilled_sandbox_leaves_no_scratch_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))
    monkeypatch.setattr(tempfile, "tempdir", None)  # re-read TMPDIR here; sandboxes inherit it
    campaign = campaign_from_dict(_campaign(seeds_per_condition=2))
    result = run_campaign(
        campaign, tmp_path / "out", workers=1, mission_fn=campaign_fakes.killed, report=False
    )
    assert result.n_errors == 2
    rows = _rows(tmp_path / "out")
    assert all(r["error"] == "the worker process died during the mission (killed by SIGKILL)" for r in rows)
    assert list(scratch.iterdir()) == []


def test_the_sweep_removes_only_directories_of_dead_owners(tmp_path: Path) -> None:
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    alive = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        dead_dir = tmp_path / f"{SCRATCH_PREFIX}{gone.pid}-abc"
        (dead_dir / "alight-c000-groundtruth-r000-xyz").mkdir(parents=True)
        (dead_dir / "alight-c000-groundtruth-r000-xyz" / "log.npz").write_bytes(b"x")
        live_dir = tmp_path / f"{SCRATCH_PREFIX}{alive.pid}-def"
        ours = tmp_path / f"{SCRATCH_PREFIX}{os.getpid()}-ghi"
        other = tmp_path / "alight-something-else"
        for d in (live_dir, ours, other):
            d.mkdir()
        assert sweep_stale_scratch(tmp_path) == [dead_dir]
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in (live_dir, ours, other))
    finally:
        alive.kill()
        alive.wait()


# -- exit status and refused combinations ---------------------------------------------------------------


def _write_campaign(tmp_path: Path, **over: object) -> Path:
    path = tmp_path / "camp.yaml"
    path.write_text(yaml.safe_dump(_campaign(**over)), encoding="utf-8")
    return path


def test_all_errored_campaign_exits_1_and_partial_errors_are_counted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write_campaign(tmp_path, seeds_per_condition=2)
    monkeypatch.setenv("ALIGHT_CAMPAIGN_MISSION_FN", "campaign_fakes:not_a_result")
    args = ["campaign", str(path), "--workers", "1", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "bad")]) == 1
    err = capsys.readouterr().err
    assert "alight campaign: all 2 recorded missions are errors" in err
    # rerunning the finished campaign flies nothing, and its results are still all errors
    assert main([*args, "--out", str(tmp_path / "bad")]) == 1

    path = _write_campaign(tmp_path, grid={"platform.speed_mps": [1.0, 2.0]}, seeds_per_condition=2)
    monkeypatch.setenv("ALIGHT_CAMPAIGN_MISSION_FN", "campaign_fakes:by_speed")
    assert main([*args, "--out", str(tmp_path / "partial")]) == 0
    captured = capsys.readouterr()
    assert "alight campaign: 2 of 4 recorded missions are errors" in captured.err
    assert "(4 flown now, 2 errors)" in captured.out


def test_workers_with_a_scheduler_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("distributed")
    campaign = campaign_from_dict(_campaign())
    with pytest.raises(ConfigError, match="--workers .* cannot be used with --scheduler"):
        run_campaign(
            campaign, tmp_path, engine="dask", scheduler="tcp://127.0.0.1:1", workers=2,
            mission_fn=campaign_fakes.instant,
        )  # fmt: skip
    path = _write_campaign(tmp_path)
    code = main(["campaign", str(path), "--out", str(tmp_path / "o"), "--engine", "dask",
                 "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "cannot be used with --scheduler" in err
    assert not (tmp_path / "o" / "results.csv").exists()


# -- compile time stays out of the mission clocks ------------------------------------------------------


@pytest.mark.slow
def test_first_mission_of_a_fresh_process_pays_no_compile(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An empty numba cache: the sandbox's warm-up compiles everything before its first mission, so the
    first mission's wall time per simulated second is like the second's (without the warm-up the first
    one took ~30 s of compile for ~1 s of flying)."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba-cache"))
    campaign = campaign_from_dict(
        {
            "name": "tiny",
            "base": {
                "duration_s": 20.0,
                "platform": {
                    "path": "straight",
                    "speed_mps": 1.0,
                    "start_xy": [6.0, 2.0],
                    "heading_rad": 3.14,
                },
            },
            "presets": ["groundtruth"],
            "seeds_per_condition": 2,
            "seed": 11,
            "timeout_s": 900.0,
        }
    )
    run_campaign(campaign, tmp_path / "out", workers=1, report=False)
    rows = {r["mission_id"]: r for r in _rows(tmp_path / "out")}
    first, second = (rows[m.mission_id] for m in campaign.missions)
    assert first["error"] == "" and second["error"] == ""
    per_s = [float(r["wall_time_s"]) / float(r["simulated_time_s"]) for r in (first, second)]
    assert per_s[0] < 3.0 * per_s[1] + 0.05, per_s
    assert any((tmp_path / "numba-cache").rglob("*.nbi")), "the warm-up compiled into the fresh cache"


# -- memory bound ---------------------------------------------------------------------------------------


def test_a_sandbox_over_the_memory_limit_is_replaced(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pids = tmp_path / "pids"
    pids.mkdir()
    monkeypatch.setenv(campaign_fakes.PID_DIR_ENV, str(pids))
    monkeypatch.setenv(campaign_fakes.SLEEP_ENV, "0")
    campaign = campaign_from_dict(_campaign(seeds_per_condition=3))
    # 1 MiB: every sandbox is over it after its mission (a Python process alone holds more)
    result = run_campaign(
        campaign,
        tmp_path / "low",
        workers=1,
        mission_fn=campaign_fakes.sleepy,
        report=False,
        memory_limit_mib=1,
    )
    assert result.n_errors == 0 and len(list(pids.iterdir())) == 3  # a fresh process for each mission
    for p in pids.iterdir():
        p.unlink()
    run_campaign(
        campaign, tmp_path / "high", workers=1, mission_fn=campaign_fakes.sleepy, report=False,
        memory_limit_mib=1e6,
    )  # fmt: skip
    assert len(list(pids.iterdir())) == 1
    with pytest.raises(ConfigError, match="memory_limit_mib must be > 0"):
        run_campaign(campaign, tmp_path / "bad", mission_fn=campaign_fakes.sleepy, memory_limit_mib=0)


# -- one row per mission, whatever an engine does --------------------------------------------------------


class _Sloppy:
    """An engine that repeats its first outcome and never answers for its last mission."""

    name = "sloppy"

    def run(self, tasks: Any) -> Any:
        from alight.campaign.engines import MissionOutcome
        from alight.scenario import Scenario

        tasks = list(tasks)
        outcomes = [
            MissionOutcome(t.mission_id, campaign_fakes.fake_result(Scenario.model_validate(t.scenario)))
            for t in tasks[:-1]
        ]
        yield from [outcomes[0], *outcomes]


def test_a_repeated_outcome_is_ignored_and_a_missing_one_is_an_error_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import alight.campaign.run as run_module

    monkeypatch.setattr(run_module, "make_engine", lambda *a, **k: _Sloppy())
    campaign = campaign_from_dict(_campaign(seeds_per_condition=3))
    result = run_campaign(campaign, tmp_path, mission_fn=campaign_fakes.instant, report=False)
    rows = _rows(tmp_path)
    assert [r["mission_id"] for r in rows] == [m.mission_id for m in campaign.missions]
    assert rows[-1]["outcome"] == "error" and rows[-1]["error"].startswith("lost: the engine ended")
    assert (result.n_run, result.n_errors, result.n_recorded, result.n_recorded_errors) == (3, 1, 3, 1)
