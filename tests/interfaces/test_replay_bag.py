"""A simulated flight written as a ROS 2 bag (rosbag_writer) and replayed (alight replay) gives the same
detections, frame for frame; ROS 1 bags and the image encodings are read too."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType
from typing import Any

import cv2
import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from alight.cli import main
from alight.interfaces.replay import replay_recording
from alight.interfaces.replay_readers import decode_image
from alight.interfaces.rosbag_writer import write_bag


def _same_detections(flight: Any, replayed: list[tuple[float, list[Any]]]) -> None:
    assert len(replayed) == len(flight.frames)
    for (t, _, obs), (t2, obs2) in zip(flight.frames, replayed, strict=True):
        assert t2 == pytest.approx(t, abs=1e-9)
        assert [o.kind for o in obs2] == [o.kind for o in obs], f"frame at {t} s"
        for a, b in zip(obs, obs2, strict=True):
            assert np.array_equal(a.pixels, b.pixels), f"frame at {t} s"
            assert a.quality == b.quality


@pytest.mark.slow
@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_bag_replay_reproduces_the_flights_detections(
    vision_flight: Any, tmp_path: Path, storage: str
) -> None:
    bag = write_bag(
        tmp_path / "flight",
        vision_flight.log,
        vision_flight.frames,
        storage=storage,
        latency_s=vision_flight.scenario.perception.latency_s,
    )
    run = replay_recording(bag, scenario=vision_flight.scenario)
    n_obs = sum(len(o) for _, _, o in vision_flight.frames)
    assert n_obs > 20  # the flight saw the pad: the comparison below is about something
    _same_detections(vision_flight, run.frames)
    r = run.result
    assert r["format"] == "ros2" and r["frames"] == len(vision_flight.frames)
    assert r["messages"]["image"] == len(vision_flight.frames)
    assert r["messages"]["odometry"] == vision_flight.log["t"].size
    assert r["ego_reference"] == "ground truth" and r["platform_ground_truth"]
    # estimates against the bag's own ground truth
    assert r["ego_estimate_rmse_m"] < 0.1
    assert r["platform_estimate_rmse_m"] is not None and r["platform_estimate_rmse_m"] < 1.0
    assert r["detections"] == vision_flight.run.result["detections"]


@pytest.mark.slow
def test_cli_replay_of_a_bag_writes_the_report(vision_flight: Any, tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "flight", vision_flight.log, vision_flight.frames, latency_s=0.1)
    out = tmp_path / "out"
    assert main(["replay", str(bag), "--out", str(out)]) == 0
    r = json.loads((out / "result.json").read_text())
    assert r["frames_with_observations"] == sum(1 for _, _, o in vision_flight.frames if o)
    html = (out / "report.html").read_text()
    assert "Top view" in html and "replayed" in html
    rows = (out / "frames.csv").read_text().splitlines()
    assert len(rows) == 1 + len(vision_flight.frames)
    # the log of the replay has the ego trajectory from the bag's ground truth and the estimates
    from alight.evaluation.log import load_arrays

    log = load_arrays(out)
    assert np.isfinite(log["p_WB"]).all() and np.isfinite(log["p_WP_est"]).any()
    assert log["t_det"].size == r["detections"]


def test_ros1_bag_is_replayed(tmp_path: Path, fuzz_logs: ModuleType) -> None:
    fz = fuzz_logs
    log, frames = fz.synthetic_log(), fz.synthetic_frames()
    bag = fz.write_ros1_bag(tmp_path / "flight.bag", log, frames)
    run = replay_recording(bag)
    r = run.result
    assert r["format"] == "ros1"
    assert r["messages"] == {"image": len(frames), "imu": log["t"].size, "odometry": log["t"].size}
    assert r["frames"] == len(frames)
    z = log["p_WB_est"][:, 2]
    assert r["ego_extent_m"]["z"] == pytest.approx([z.min(), z.max()], abs=0.05)


def _image_msg(img: np.ndarray, encoding: str, step_pad: int = 0) -> Any:
    T = get_typestore(Stores.ROS2_HUMBLE).types
    h, w = img.shape[:2]
    c = 1 if img.ndim == 2 else img.shape[2]
    rows = img.reshape(h, w * c * img.itemsize // img.itemsize)
    raw = np.frombuffer(rows.tobytes(), dtype=np.uint8).reshape(h, -1)
    raw = np.hstack([raw, np.zeros((h, step_pad), np.uint8)])
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="c")
    return T["sensor_msgs/msg/Image"](
        header=header,
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=raw.shape[1],
        data=raw.reshape(-1),
    )


def test_image_encodings() -> None:
    rng = np.random.default_rng(0)
    bgr = rng.integers(0, 256, (6, 5, 3), dtype=np.uint8)
    assert np.array_equal(decode_image(_image_msg(bgr, "bgr8"), "sensor_msgs/msg/Image"), bgr)
    assert np.array_equal(
        decode_image(_image_msg(bgr[:, :, ::-1].copy(), "rgb8"), "sensor_msgs/msg/Image"), bgr
    )
    grey = rng.integers(0, 256, (6, 5), dtype=np.uint8)
    assert np.array_equal(decode_image(_image_msg(grey, "mono8", step_pad=3), "sensor_msgs/msg/Image"), grey)
    assert decode_image(_image_msg(grey, "32FC1"), "sensor_msgs/msg/Image") is None
    T = get_typestore(Stores.ROS2_HUMBLE).types
    ok, png = cv2.imencode(".png", bgr)
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="c")
    msg = T["sensor_msgs/msg/CompressedImage"](header=header, format="png", data=png.reshape(-1))
    assert ok and np.array_equal(decode_image(msg, "sensor_msgs/msg/CompressedImage"), bgr)
    bad = T["sensor_msgs/msg/CompressedImage"](
        header=header, format="jpeg", data=np.arange(50, dtype=np.uint8)
    )
    assert decode_image(bad, "sensor_msgs/msg/CompressedImage") is None


def test_a_lone_mcap_file_is_replayed(tmp_path: Path, fuzz_logs: ModuleType) -> None:
    """A ROS 2 MCAP file without its bag directory's metadata.yaml (as other recorders write them)."""
    log, frames = fuzz_logs.synthetic_log(), fuzz_logs.synthetic_frames()
    bag = write_bag(tmp_path / "bag", log, frames, compress=False)
    lone = tmp_path / "lone.mcap"
    lone.write_bytes(next(bag.glob("*.mcap")).read_bytes())
    r = replay_recording(lone).result
    assert r["format"] == "ros2" and r["frames"] == len(frames)
    assert r["messages"]["odometry"] == log["t"].size
    assert r["ego_reference"] == "ground truth" and r["ego_estimate_rmse_m"] < 0.1


def _mavros_style_bag(path: Path, *, frame_hw: tuple[int, int] = (48, 64), n_frames: int = 5) -> Path:
    """Default topic names of a typical PX4 + mavros + camera driver recording, written in time order as
    a recorder does: PoseStamped poses on /mavros/local_position/pose (2 s at 50 Hz, climbing at 1 m/s),
    JPEG frames on /camera/image_raw/compressed, stamped on a wall clock."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    t0_ns = 1_700_000_000 * 10**9  # a wall clock: times are made relative to the bag's start

    def header(t: float) -> Any:
        ns = t0_ns + round(t * 1e9)
        return T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), frame_id="map"
        )

    items: list[tuple[int, str, bytes]] = []
    for k in range(100):
        t = 0.02 * k
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=1.0 + t),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=2**-0.5, w=2**-0.5),
        )
        msg = T["geometry_msgs/msg/PoseStamped"](header=header(t), pose=pose)
        items.append((t0_ns + round(t * 1e9), "pose", ts.serialize_cdr(msg, msg.__msgtype__)))
    rng = np.random.default_rng(0)
    for k in range(n_frames):
        t = 1.5 * k / n_frames + 0.1
        # noise: JPEG cannot shrink it, so large frames make a file of several MCAP chunks
        ok, jpg = cv2.imencode(".jpg", rng.integers(0, 256, (*frame_hw, 3), dtype=np.uint8))
        msg = T["sensor_msgs/msg/CompressedImage"](header=header(t), format="jpeg", data=jpg.reshape(-1))
        items.append((t0_ns + round((t + 0.05) * 1e9), "img", ts.serialize_cdr(msg, msg.__msgtype__)))
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {
            "pose": w.add_connection(
                "/mavros/local_position/pose", "geometry_msgs/msg/PoseStamped", typestore=ts
            ),
            "img": w.add_connection(
                "/camera/image_raw/compressed", "sensor_msgs/msg/CompressedImage", typestore=ts
            ),
        }
        for ns, which, raw in sorted(items, key=lambda x: x[0]):
            w.write(conns[which], ns, raw)
    return path


def test_mavros_style_bag_with_compressed_images(tmp_path: Path) -> None:
    r = replay_recording(_mavros_style_bag(tmp_path / "bag")).result
    assert r["topics"] == {"odometry": "/mavros/local_position/pose", "image": "/camera/image_raw/compressed"}
    assert r["messages"] == {"odometry": 100, "image": 5} and r["frames"] == 5 and r["bad_frames"] == 0
    assert r["t_start_s"] == pytest.approx(0.0, abs=1e-9) and r["duration_s"] == pytest.approx(1.98, abs=0.06)
    assert r["ego_extent_m"]["x"] == pytest.approx([1.0, 1.0]) and r["ego_extent_m"]["y"] == pytest.approx(
        [2.0, 2.0]
    )
    assert r["ego_extent_m"]["z"][1] == pytest.approx(2.98, abs=0.03)
    assert r["warnings"] == []


def test_an_mcap_bag_cut_short_replays_what_was_written(tmp_path: Path) -> None:
    """A recorder killed mid-write leaves an MCAP without its summary: rosbags refuses it, the replay
    reads the messages before the cut and says so."""
    bag = _mavros_style_bag(tmp_path / "bag", frame_hw=(480, 640), n_frames=20)  # about 8 chunks
    storage = next(bag.glob("*.mcap"))
    data = storage.read_bytes()
    storage.write_bytes(data[: len(data) // 2])
    r = replay_recording(bag).result
    assert 20 < r["messages"]["odometry"] < 100 and 0 < r["frames"] < 20
    assert r["warnings"] and "the MCAP file is damaged" in r["warnings"][0]
    # what was read is the start of the flight, unchanged
    assert r["t_start_s"] == pytest.approx(0.0, abs=1e-9)
    assert r["ego_extent_m"]["z"][0] == pytest.approx(1.0, abs=0.03)


def test_a_damaged_compressed_frame_is_dropped() -> None:
    # a JPEG frame whose entropy-coded data has wrong bytes decodes in OpenCV to blocks of shifted colour;
    # the replay drops it as undecodable (perception/image_decode.py)
    T = get_typestore(Stores.ROS2_HUMBLE).types
    grid = np.indices((96, 128)).sum(axis=0) % 2 * 200
    bgr = np.dstack([grid, grid // 2, 255 - grid]).astype(np.uint8)
    ok, jpg = cv2.imencode(".jpg", bgr)
    data = bytearray(jpg.tobytes())
    for i in range(len(data) // 2, len(data) - 2, 97):
        data[i] = 0xFF if data[i] != 0xFF else 0x00
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id="c")
    good = T["sensor_msgs/msg/CompressedImage"](header=header, format="jpeg", data=jpg.reshape(-1))
    bad = T["sensor_msgs/msg/CompressedImage"](
        header=header, format="jpeg", data=np.frombuffer(bytes(data), np.uint8)
    )
    assert ok and decode_image(good, "sensor_msgs/msg/CompressedImage") is not None
    assert cv2.imdecode(np.frombuffer(bytes(data), np.uint8), cv2.IMREAD_UNCHANGED) is not None
    assert decode_image(bad, "sensor_msgs/msg/CompressedImage") is None
