"""Damaged or unusable logs give one clear line and exit status 2, never a traceback or a hang; a short
run of the fuzzer (benchmarks/fuzz_logs.py) finds no crash."""

from __future__ import annotations

import json
import os
from pathlib import Path
from types import ModuleType

import pytest

from alight.cli import main
from alight.errors import ReplayError
from alight.interfaces.replay_readers import load_mapping, open_recording
from alight.interfaces.rosbag_writer import write_bag

_TESTDATA = Path(
    os.environ.get(
        "ALIGHT_TESTDATA", Path(__file__).resolve().parents[2] / ".." / "shared" / "testdata" / "real"
    )
)
ULOG = _TESTDATA / "px4_ulog" / "sample_log_small.ulg"


def _replay_fails(capsys: pytest.CaptureFixture[str], log: Path, *extra: str) -> str:
    code = main(["replay", str(log), "--out", str(log.parent / "out"), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("alight replay: ") and "\n" not in err and "Traceback" not in err
    return err


def test_missing_empty_and_unknown_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "no such file" in _replay_fails(capsys, tmp_path / "nope.ulg")
    (tmp_path / "empty.ulg").write_bytes(b"")
    assert "empty file" in _replay_fails(capsys, tmp_path / "empty.ulg")
    (tmp_path / "notes.txt").write_text("hello")
    assert "unknown log type" in _replay_fails(capsys, tmp_path / "notes.txt")


def test_garbage_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for name in ("garbage.ulg", "garbage.bag", "garbage.mcap", "garbage.db3"):
        (tmp_path / name).write_bytes(bytes(range(256)) * 8)
        err = _replay_fails(capsys, tmp_path / name)
        assert str(tmp_path / name) in err


def test_truncated_ulog(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    if not ULOG.is_file():
        pytest.skip(f"real test data not found at {ULOG} (set ALIGHT_TESTDATA)")
    data = ULOG.read_bytes()
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(data[:200])  # inside the header and definitions: nothing to replay
    err = _replay_fails(capsys, cut)
    assert "cut.ulg" in err
    # cut in the middle of the data: pyulog reads what is there (a ULog has no end marker, so a log
    # cut between two messages is a shorter log) and the replay covers that part
    half = tmp_path / "half.ulg"
    half.write_bytes(data[: len(data) // 2])
    assert main(["replay", str(half), "--out", str(tmp_path / "half_out")]) == 0
    r = json.loads((tmp_path / "half_out" / "result.json").read_text())
    assert 2.0 < r["duration_s"] < 5.0  # of the whole log's 6.5 s


def test_truncated_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str], fuzz_logs: ModuleType) -> None:
    fz = fuzz_logs
    bag = write_bag(tmp_path / "bag", fz.synthetic_log(), fz.synthetic_frames())
    storage = next(bag.glob("*.mcap"))
    storage.write_bytes(storage.read_bytes()[:5000])
    assert "not a readable ROS 2 bag" in _replay_fails(capsys, bag)


def test_bag_without_the_mapped_topics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fuzz_logs: ModuleType
) -> None:
    fz = fuzz_logs
    bag = write_bag(tmp_path / "bag", fz.synthetic_log(), fz.synthetic_frames())
    mapping = tmp_path / "m.yaml"
    mapping.write_text("ros: {odometry: [/elsewhere], image: [/nothing]}\n")
    err = _replay_fails(capsys, bag, "--mapping", str(mapping))
    assert "none of the mapped odometry or image topics" in err and "/alight/odometry" in err


def test_mapping_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("ros: {odometryy: [/odom]}\n")
    with pytest.raises(ReplayError, match="odometryy"):
        load_mapping(bad)
    bad.write_text("ros: [unclosed\n")
    with pytest.raises(ReplayError, match="not a YAML"):
        load_mapping(bad)
    with pytest.raises(ReplayError, match="cannot read"):
        load_mapping(tmp_path / "missing.yaml")
    # a file that names one section keeps the defaults of the other
    part = tmp_path / "part.yaml"
    part.write_text("ulog: {imu: sensor_accel}\n")
    m = load_mapping(part)
    assert m.ulog.imu == "sensor_accel" and m.ulog.position == "vehicle_local_position"
    assert "/mavros/local_position/pose" in m.ros.odometry


def test_ulog_without_the_mapped_topics(tmp_path: Path) -> None:
    if not ULOG.is_file():
        pytest.skip(f"real test data not found at {ULOG} (set ALIGHT_TESTDATA)")
    m = tmp_path / "m.yaml"
    m.write_text("ulog: {position: vehicle_gps_position_nope}\n")
    with pytest.raises(ReplayError, match="no ego state"):
        open_recording(ULOG, load_mapping(m))


@pytest.mark.slow
def test_short_fuzz_finds_no_crash_or_hang(tmp_path: Path, fuzz_logs: ModuleType) -> None:
    fz = fuzz_logs
    (tmp_path / "inputs").mkdir()
    inputs = fz.make_inputs(tmp_path / "inputs", ULOG if ULOG.is_file() else None)
    summary = fz.fuzz(inputs, tmp_path, cases_per_kind=3, seed=7, timeout_s=60.0)
    totals = summary["totals"]
    failures = [f for per in summary["inputs"].values() for k in per.values() for f in k["failures"]]
    assert totals["crash"] == 0 and totals["hang"] == 0, failures
    assert totals["clean"] > 0  # damage was found and reported, not only missed
    assert sum(totals.values()) == 3 * 2 * len(inputs)
    assert len(inputs) == (5 if ULOG.is_file() else 4)


def test_empty_unreadable_and_foreign_directories(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A directory that is not a ROS 2 bag: one line, not rosbags' 34-line traceback."""
    empty = tmp_path / "empty"
    empty.mkdir()
    assert "empty directory" in _replay_fails(capsys, empty)
    foreign = tmp_path / "photos"
    foreign.mkdir()
    (foreign / "a.txt").write_text("not a bag")
    assert "no metadata.yaml" in _replay_fails(capsys, foreign)
    if os.geteuid() != 0:  # root reads any directory
        locked = tmp_path / "locked"
        locked.mkdir(mode=0)
        assert "cannot read the directory" in _replay_fails(capsys, locked)


def test_a_ulog_cut_short_is_said(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A ULog cut to 10 % replays its first part, and says that the log ends early; the whole log does
    not (its messages end exactly at the end of the file)."""
    from alight.interfaces.replay_readers import ulog_cut_at

    if not ULOG.is_file():
        pytest.skip(f"real test data not found at {ULOG} (set ALIGHT_TESTDATA)")
    data = ULOG.read_bytes()
    assert ulog_cut_at(ULOG) is None
    cut = tmp_path / "tenth.ulg"
    cut.write_bytes(data[: len(data) // 10])
    at = ulog_cut_at(cut)
    assert at is not None and 16 < at < len(data) // 10
    assert main(["replay", str(cut), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "the log ends early" in err and f"byte {at} of {len(data) // 10}" in err
    assert main(["replay", str(ULOG), "--out", str(tmp_path / "whole")]) == 0
    assert "ends early" not in capsys.readouterr().err
