"""``alight replay`` on the real PX4 ULog of the test data: the ego trajectory it reports is the log's own
vehicle_local_position in ENU (z up), with the heading of vehicle_attitude."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from alight.cli import main

_TESTDATA = Path(
    os.environ.get(
        "ALIGHT_TESTDATA", Path(__file__).resolve().parents[2] / ".." / "shared" / "testdata" / "real"
    )
)
ULOG = _TESTDATA / "px4_ulog" / "sample_log_small.ulg"


@pytest.fixture(scope="module")
def replayed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not ULOG.is_file():
        pytest.skip(f"real test data not found at {ULOG} (set ALIGHT_TESTDATA)")
    out = tmp_path_factory.mktemp("ulog_replay")
    assert main(["replay", str(ULOG), "--out", str(out)]) == 0
    return out


def _local_position() -> dict[str, np.ndarray]:
    from pyulog import ULog

    ulog = ULog(str(ULOG), ["vehicle_local_position"])
    return ulog.get_dataset("vehicle_local_position").data  # type: ignore[no-any-return]


def test_report_and_result(replayed: Path) -> None:
    r = json.loads((replayed / "result.json").read_text())
    assert (replayed / "report.html").stat().st_size > 10_000
    assert r["format"] == "ulog" and r["preset"] == "falanga2017"
    assert r["topics"]["odometry"] == "vehicle_local_position + vehicle_attitude"
    lp = _local_position()
    assert r["messages"]["odometry"] == len(lp["timestamp"])  # every sample had an attitude to go with it
    assert r["messages"]["imu"] > 1000
    assert r["frames"] == 0 and r["detections"] == 0  # no camera in this log
    # the log's own span: first to last message of the mapped topics
    assert 6.0 < r["duration_s"] < 7.0
    # this log has no horizontal position (no GPS): PX4 says so, and so does the replay
    assert np.all(lp["xy_valid"] == 0)
    assert f"vehicle_local_position: xy_valid is false in {len(lp['xy_valid'])} of" in r["warnings"][0]


def test_trajectory_is_the_logs_local_position_with_z_up(replayed: Path) -> None:
    r = json.loads((replayed / "result.json").read_text())
    lp = _local_position()
    z_up = -np.asarray(lp["z"], dtype=float)
    # PX4's z points down, ours up: the heights are the negated z, about 0.1 to 1.2 m above the origin
    # (the replay's log samples at 50 Hz, so its extent can miss the first few ms of the log's)
    assert r["ego_extent_m"]["z"] == pytest.approx([z_up.min(), z_up.max()], abs=5e-3)
    assert z_up.max() - z_up.min() > 0.9
    assert r["ego_extent_m"]["x"] == pytest.approx([np.min(lp["y"]), np.max(lp["y"])], abs=5e-3)  # east
    assert r["ego_extent_m"]["y"] == pytest.approx([np.min(lp["x"]), np.max(lp["x"])], abs=5e-3)  # north
    # the ego estimator, fed with that odometry and the IMU, stays with it
    assert r["ego_reference"].startswith("odometry")
    assert r["ego_estimate_rmse_m"] < 0.2
    est = r["ego_estimate_extent_m"]["z"]
    assert est[1] == pytest.approx(z_up.max(), abs=0.15)


def test_each_logged_position_is_the_latest_ulog_sample_in_enu(replayed: Path) -> None:
    from pyulog import ULog

    from alight.evaluation.log import load_arrays

    log = load_arrays(replayed, "npz")
    t0 = ULog(str(ULOG), ["vehicle_local_position"]).start_timestamp
    lp = _local_position()
    t_lp = (np.asarray(lp["timestamp"], dtype=np.int64) - t0) * 1e-6
    k = np.searchsorted(t_lp, log["t"] + 1e-9, side="right") - 1  # the latest sample at each row
    assert (k >= 0).all() and log["t"].size > 250
    ned = np.column_stack([lp["x"], lp["y"], lp["z"]]).astype(float)[k]
    assert np.array_equal(log["p_WB"], np.column_stack([ned[:, 1], ned[:, 0], -ned[:, 2]]))


def test_logged_heading_matches_px4_heading(replayed: Path) -> None:
    """The attitude in the replay's log, turned to a heading, is PX4's own ``heading`` (NED yaw) of
    vehicle_local_position: ENU yaw = pi/2 - heading."""
    from alight.evaluation.log import load_arrays

    log = load_arrays(replayed, "csv")
    q = log["q_WB"]
    ok = np.isfinite(q).all(axis=1)
    assert ok.sum() > 100
    x, y, z, w = q[ok].T
    yaw_enu = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    lp = _local_position()
    heading = float(np.median(lp["heading"]))
    err = np.angle(np.exp(1j * (yaw_enu - (math.pi / 2 - heading))))
    assert np.median(np.abs(err)) < math.radians(3)


def test_imu_in_flu_measures_gravity_up() -> None:
    """The accelerometer of a hovering or resting vehicle reads about +g along FLU z (PX4's FRD z reads
    -g): the FRD -> FLU conversion of sensor_combined, checked on the real log."""
    if not ULOG.is_file():
        pytest.skip(f"real test data not found at {ULOG} (set ALIGHT_TESTDATA)")
    from alight.interfaces.replay_readers import ImuSample, open_recording

    rec = open_recording(ULOG)
    f = np.array([s.f_B for s in rec.samples() if isinstance(s, ImuSample)])
    assert f.shape[0] == rec.counts["imu"] > 1000
    assert np.median(f[:, 2]) == pytest.approx(9.81, abs=0.6)
    assert np.all(np.abs(np.median(f[:, :2], axis=0)) < 1.0)


def test_the_odometry_carries_px4s_reset_counters() -> None:
    """Each odometry sample carries xy_reset_counter + z_reset_counter as logged (constant in this log:
    1 + 0, so the replay never re-localises its ego estimator)."""
    if not ULOG.is_file():
        pytest.skip(f"real test data not found at {ULOG} (set ALIGHT_TESTDATA)")
    from alight.interfaces.replay_readers import OdometrySample, open_recording

    lp = _local_position()
    odometry = [s for s in open_recording(ULOG).samples() if isinstance(s, OdometrySample)]
    assert len(odometry) == len(lp["timestamp"])
    expected = np.asarray(lp["xy_reset_counter"], dtype=int) + np.asarray(lp["z_reset_counter"], dtype=int)
    assert [s.reset_counter for s in odometry] == expected.tolist()
