"""The report of a replayed recorded flight: on the real PX4 log, the log's own warning and messages at
the top, the recorded time, the log's estimate against alight's with attitude and IMU panels full of the
log's data, and nothing that only a simulated mission has (landing tiles, simulated time, "truth"); on a
bag with ground truth and camera frames, the truth named as such and the frames with their detections."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from alight.cli import main
from alight.evaluation.recorded_flight import euler_rpy
from alight.evaluation.recorded_plots import plot_imu, plot_recorded_states
from alight.interfaces.replay import ReplayRun, replay_recording, replay_to_dir
from alight.interfaces.rosbag_writer import write_bag

_TESTDATA = Path(
    os.environ.get(
        "ALIGHT_TESTDATA", Path(__file__).resolve().parents[2] / ".." / "shared" / "testdata" / "real"
    )
)
ULOG = _TESTDATA / "px4_ulog" / "sample_log_small.ulg"
SIMULATED_ONLY = (
    "Simulated time",
    "Sim / wall",
    "Touchdown error",
    "Time to land",
    "Touchdown rel. speed",
    "Flight energy",
    "Compute energy",
)


@pytest.fixture(scope="module")
def ulog_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, ReplayRun]:
    if not ULOG.is_file():
        pytest.skip(f"real test data not found at {ULOG} (set ALIGHT_TESTDATA)")
    out = tmp_path_factory.mktemp("ulog_report")
    return out, replay_to_dir(ULOG, out)


def _page_above_the_result_table(out: Path) -> str:
    html = (out / "report.html").read_text()
    return html.split("<h2>Result</h2>")[0]


def _legend_labels(fig: Any) -> list[str]:
    return [t.get_text() for legend in fig.legends for t in legend.get_texts()] + [
        t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()
    ]


def test_the_px4_logs_warning_and_messages_open_the_report(ulog_report: tuple[Path, ReplayRun]) -> None:
    out, run = ulog_report
    page = _page_above_the_result_table(out)
    warning = page.index("vehicle_local_position: xy_valid is false in 636 of 636 samples")
    assert warning < page.index('<section class="cards">') < page.index("<h2>Top view</h2>")
    # PX4's own messages, with their time on the replay's clock and their level
    for text in (
        "[commander] Takeoff detected",
        "[commander] Landing detected",
        "[commander] Disarmed by landing",
    ):
        assert page.index(text) < page.index('<section class="cards">')
    assert [m.level for m in run.recorded.messages] == ["INFO"] * 3
    assert run.recorded.messages[0].t == pytest.approx(2.375, abs=1e-3)
    assert "PX4 on CUBEPILOT_CUBEORANGE" in page and run.result["vehicle"] == "PX4 on CUBEPILOT_CUBEORANGE"


def test_recorded_time_and_no_simulated_only_tiles(ulog_report: tuple[Path, ReplayRun]) -> None:
    out, run = ulog_report
    page = _page_above_the_result_table(out)
    duration = json.loads((out / "result.json").read_text())["duration_s"]
    assert re.search(rf'Recorded time</div><div class="v">{duration:.2f} s<', page)
    for label in SIMULATED_ONLY:
        assert label not in page
    # the log's odometry is PX4's estimate, never called truth above the raw result table
    assert "truth" not in page.lower()
    assert "recorded flight" in page and "Replay report" in page


def test_the_estimates_compared_are_the_replays_own_reference(ulog_report: tuple[Path, ReplayRun]) -> None:
    """Without ground truth the replay's reference is the log's odometry: the report's position RMS of
    alight against the log is the result's ego_estimate_rmse_m, computed the other way."""
    _, run = ulog_report
    r = run.result
    vs_log = r["ego_vs_log_estimate"]
    assert vs_log["position_rms_m"] == pytest.approx(r["ego_estimate_rmse_m"], rel=1e-12)
    assert 0 < vs_log["velocity_rms_mps"] < 0.5 and 0 < vs_log["attitude_rms_deg"] < 5
    assert r["ego_vs_truth"] is None and r["log_messages"] == 3


def test_attitude_and_imu_panels_hold_the_logs_data(ulog_report: tuple[Path, ReplayRun]) -> None:
    out, run = ulog_report
    rec = run.recorded
    page = _page_above_the_result_table(out)
    for stem in ("top_view", "estimates", "estimate_differences", "imu"):
        assert (out / f"{stem}.png").stat().st_size > 10_000 and f"{stem}.png</figcaption>" in page
    assert "camera_frames" not in page  # no camera in this log

    fig = plot_recorded_states(rec, run.log)
    yaw_ax = fig.axes[8]  # row 3 of the attitude column
    lines = [ln for ln in yaw_ax.get_lines() if len(ln.get_xdata()) > 0]
    log_yaw = np.degrees(euler_rpy(rec.odometry.q_W)[:, 2])
    assert np.array_equal(lines[0].get_ydata(), log_yaw) and np.isfinite(log_yaw).all()
    assert 70 < np.median(log_yaw) < 95  # ENU yaw = 90 deg - PX4's heading, about 0.1 rad here
    assert np.isfinite(lines[1].get_ydata()).sum() > 250  # alight's attitude at 50 Hz
    labels = _legend_labels(fig)
    assert labels == ["PX4's estimate (vehicle_local_position + vehicle_attitude)", "alight's ego estimate"]

    fig = plot_imu(rec)
    f_lines = [ln for ln in fig.axes[0].get_lines() if len(ln.get_xdata()) > 0]
    assert len(f_lines) == 3 and all(len(ln.get_ydata()) == run.result["messages"]["imu"] for ln in f_lines)
    assert np.median(f_lines[2].get_ydata()) == pytest.approx(9.81, abs=0.6)  # FLU z feels gravity up
    assert np.isfinite(fig.axes[1].get_lines()[0].get_ydata()).all()
    assert not any("truth" in label for label in _legend_labels(fig))


def test_a_bag_with_ground_truth_names_it_and_shows_its_frames(tmp_path: Path, fuzz_logs: ModuleType) -> None:
    log, frames = fuzz_logs.synthetic_log(), fuzz_logs.synthetic_frames()
    bag = write_bag(tmp_path / "bag", log, frames)
    out = tmp_path / "out"
    assert main(["replay", str(bag), "--out", str(out)]) == 0
    r = json.loads((out / "result.json").read_text())
    # the truth the replay compared with is the bag's, and the report's RMS is the result's
    assert r["ego_reference"] == "ground truth"
    assert r["ego_vs_truth"]["position_rms_m"] == pytest.approx(r["ego_estimate_rmse_m"], rel=1e-12)
    page = _page_above_the_result_table(out)
    assert "alight vs truth: position RMS" in page and "The log carries no text messages." in page
    assert "camera_frames.png</figcaption>" in page
    run = replay_recording(bag)
    assert len(run.recorded.frames) == 6 and run.recorded.truth is not None
    fig = plot_recorded_states(run.recorded, run.log)
    assert "ground truth (/alight/ground_truth/uav)" in _legend_labels(fig)


@pytest.mark.slow
def test_camera_frames_show_the_detections(vision_flight: Any, tmp_path: Path) -> None:
    """A simulated flight's bag: the frames the report shows are frames in which the detector found the
    pad, with the pixels it found."""
    bag = write_bag(tmp_path / "flight", vision_flight.log, vision_flight.frames, latency_s=0.1)
    run = replay_to_dir(bag, tmp_path / "out", scenario=vision_flight.scenario)
    shown = run.recorded.frames
    assert len(shown) == 6 and all(f.observations for f in shown)
    by_time = {t: obs for t, obs in run.frames}
    for f in shown:
        obs = by_time[f.t]
        assert [o.kind for o in f.observations] == [o.kind for o in obs]
        scale = f.image.shape[1] / vision_flight.frames[0][1].shape[1]
        assert np.allclose(f.observations[0].pixels, obs[0].pixels * scale)
    assert (tmp_path / "out" / "camera_frames.png").stat().st_size > 10_000


def _bag_with_rosout(path: Path) -> Path:
    """2 s of PoseStamped at 50 Hz and three /rosout messages (INFO, WARN, ERROR) on a wall clock."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    t0_ns = 1_700_000_000 * 10**9

    def stamp(t: float) -> Any:
        ns = t0_ns + round(t * 1e9)
        return T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)

    items: list[tuple[int, str, bytes]] = []
    for k in range(100):
        t = 0.02 * k
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=1.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        )
        header = T["std_msgs/msg/Header"](stamp=stamp(t), frame_id="map")
        msg = T["geometry_msgs/msg/PoseStamped"](header=header, pose=pose)
        items.append((t0_ns + round(t * 1e9), "pose", ts.serialize_cdr(msg, msg.__msgtype__)))
    for t, level, text in ((0.5, 20, "armed"), (1.0, 30, "EKF: GPS glitch"), (1.5, 40, "offboard lost")):
        log = T["rcl_interfaces/msg/Log"](
            stamp=stamp(t), level=level, name="px4", msg=text, file="f", function="g", line=1
        )
        items.append((t0_ns + round(t * 1e9), "log", ts.serialize_cdr(log, log.__msgtype__)))
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {
            "pose": w.add_connection("/pose", "geometry_msgs/msg/PoseStamped", typestore=ts),
            "log": w.add_connection("/rosout", "rcl_interfaces/msg/Log", typestore=ts),
        }
        for ns, which, raw in sorted(items, key=lambda x: x[0]):
            w.write(conns[which], ns, raw)
    return path


def test_a_bags_rosout_messages_open_the_report(tmp_path: Path) -> None:
    out = tmp_path / "out"
    run = replay_to_dir(_bag_with_rosout(tmp_path / "bag"), out)
    msgs = run.recorded.messages
    assert [(round(m.t, 6), m.level, m.text) for m in msgs] == [
        (0.5, "INFO", "[px4] armed"),
        (1.0, "WARN", "[px4] EKF: GPS glitch"),
        (1.5, "ERROR", "[px4] offboard lost"),
    ]
    assert run.result["log_messages"] == 3
    page = _page_above_the_result_table(out)
    assert "3 messages in the log, 2 at warning level or above." in page
    # warning levels first, marked, above the figures
    rows = re.findall(r"<tr( class=\"warn\")?><td class=\"num\">([0-9.]+)</td><td>(\w+)</td>", page)
    assert rows == [
        (' class="warn"', "1.000", "WARN"),
        (' class="warn"', "1.500", "ERROR"),
        ("", "0.500", "INFO"),
    ]
    assert page.index("offboard lost") < page.index('<section class="cards">')
