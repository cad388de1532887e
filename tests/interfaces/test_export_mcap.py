"""``alight fly --mcap``: the flight as MCAP with Foxglove's protobuf schemas, read back with the ``mcap``
reader (channels, schemas, message counts, a decoded pose)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from google.protobuf.descriptor_pb2 import FileDescriptorSet
from mcap.reader import make_reader
from scipy.spatial.transform import Rotation

from alight.cameras.pinhole import PinholeCamera
from alight.cli import main
from alight.interfaces import mcap_export as mx

EXPECTED = {
    mx.CH_IMAGE: ("foxglove.CompressedImage", "protobuf"),
    mx.CH_ANNOTATIONS: ("foxglove.ImageAnnotations", "protobuf"),
    mx.CH_UAV_POSE: ("foxglove.PoseInFrame", "protobuf"),
    mx.CH_UAV_POSE_EST: ("foxglove.PoseInFrame", "protobuf"),
    mx.CH_PLATFORM_POSE: ("foxglove.PoseInFrame", "protobuf"),
    mx.CH_PLATFORM_POSE_EST: ("foxglove.PoseInFrame", "protobuf"),
    mx.CH_MEASUREMENTS: ("foxglove.PoseInFrame", "protobuf"),
    mx.CH_TF: ("foxglove.FrameTransforms", "protobuf"),
    mx.CH_MODE: ("foxglove.Log", "protobuf"),
    mx.CH_SERIES: ("alight.Series", "jsonschema"),
    mx.CH_CALIBRATION: ("foxglove.CameraCalibration", "protobuf"),
}


@pytest.fixture(scope="module")
def exported(vision_flight: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    from alight.airframe import DEFAULT_AIRFRAME
    from alight.mission.presets import build_preset

    preset = build_preset(vision_flight.scenario, DEFAULT_AIRFRAME, np.random.default_rng(0))
    path = tmp_path_factory.mktemp("mcap") / mx.MCAP_FILE
    exporter = mx.McapExporter(path, camera=preset.camera, mount=preset.mount)
    for t, image, obs in vision_flight.frames:
        exporter(t, image, obs)
    exporter.finish(vision_flight.log, vision_flight.run.mode_history)
    return path


def _summary(path: Path) -> Any:
    with open(path, "rb") as f:
        return make_reader(f).get_summary()


@pytest.mark.slow
def test_channels_schemas_and_counts(vision_flight: Any, exported: Path) -> None:
    s = _summary(exported)
    got = {
        c.topic: (s.schemas[c.schema_id].name, s.schemas[c.schema_id].encoding) for c in s.channels.values()
    }
    assert got == EXPECTED
    counts = {c.topic: s.statistics.channel_message_counts[cid] for cid, c in s.channels.items()}
    log = vision_flight.log
    n = log["t"].size
    n_frames = len(vision_flight.frames)
    assert counts[mx.CH_IMAGE] == counts[mx.CH_ANNOTATIONS] == counts[mx.CH_CALIBRATION] == n_frames
    assert counts[mx.CH_UAV_POSE] == counts[mx.CH_UAV_POSE_EST] == counts[mx.CH_PLATFORM_POSE] == n
    assert counts[mx.CH_TF] == counts[mx.CH_SERIES] == n
    assert counts[mx.CH_PLATFORM_POSE_EST] == int(np.isfinite(log["p_WP_est"]).all(axis=1).sum()) > 0
    assert counts[mx.CH_MEASUREMENTS] == log["t_det"].size > 0
    assert counts[mx.CH_MODE] == len(vision_flight.run.mode_history) > 0
    # each protobuf schema is a FileDescriptorSet that holds its message's file and its dependencies
    for c in s.channels.values():
        schema = s.schemas[c.schema_id]
        if schema.encoding == "protobuf":
            fds = FileDescriptorSet.FromString(schema.data)
            names = {f.name for f in fds.file}
            assert f"foxglove/{schema.name.split('.')[1]}.proto" in names
            assert "google/protobuf/timestamp.proto" in names


@pytest.mark.slow
def test_decoded_messages_match_the_log(vision_flight: Any, exported: Path) -> None:
    log = vision_flight.log
    poses: list[tuple[int, Any]] = []
    annotations: list[Any] = []
    modes: list[str] = []
    series: list[dict[str, Any]] = []
    with open(exported, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=True):
            if channel.topic == mx.CH_UAV_POSE:
                poses.append((message.log_time, PoseInFrame.FromString(message.data)))
            elif channel.topic == mx.CH_ANNOTATIONS:
                annotations.append(ImageAnnotations.FromString(message.data))
            elif channel.topic == mx.CH_MODE:
                modes.append(Log.FromString(message.data).message)
            elif channel.topic == mx.CH_SERIES:
                series.append(json.loads(message.data))
    k = len(poses) // 2
    log_time, pose = poses[k]
    assert pose.frame_id == "world"
    assert log_time == round(log["t"][k] * 1e9)
    assert pose.timestamp.seconds + pose.timestamp.nanos * 1e-9 == pytest.approx(log["t"][k], abs=1e-9)
    p = [pose.pose.position.x, pose.pose.position.y, pose.pose.position.z]
    q = [pose.pose.orientation.x, pose.pose.orientation.y, pose.pose.orientation.z, pose.pose.orientation.w]
    assert p == list(log["p_WB"][k]) and q == list(log["q_WB"][k])
    # the detections are drawn on the frames that had them: a closed outline through their pixels
    for (_, _, obs), ann in zip(vision_flight.frames, annotations, strict=True):
        assert len(ann.points) == sum(1 for o in obs if o.pixels.shape[0])
        for o, pts in zip((o for o in obs if o.pixels.shape[0]), ann.points, strict=True):
            assert [(q.x, q.y) for q in pts.points] == [tuple(px) for px in o.pixels.tolist()]
    assert modes[0].startswith(vision_flight.run.mode_history[0][1])
    # the camera: its calibration is the preset's K, and /tf mounts it on the vehicle looking down
    with open(exported, "rb") as f:
        _, _, m = next(make_reader(f).iter_messages(topics=[mx.CH_CALIBRATION]))
    cal = CameraCalibration.FromString(m.data)
    K = PinholeCamera.default_downward().K
    assert (cal.width, cal.height) == (752, 480) and list(cal.K) == K.reshape(-1).tolist()
    with open(exported, "rb") as f:
        _, _, m = next(make_reader(f).iter_messages(topics=[mx.CH_TF]))
    tf = {t.child_frame_id: t for t in FrameTransforms.FromString(m.data).transforms}
    r = tf["camera"].rotation
    R_BC = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
    assert tf["camera"].parent_frame_id == "uav"
    assert np.allclose(R_BC @ [0.0, 0.0, 1.0], [0.0, 0.0, -1.0])  # the optical axis is the body's down
    assert series[k]["t"] == log["t"][k] and series[k]["q_WB_est_w"] == log["q_WB_est"][k, 3]


@pytest.mark.slow
def test_cli_fly_with_mcap_and_bag(tmp_path: Path) -> None:
    scenario = tmp_path / "s.yaml"
    scenario.write_text(
        "preset: falanga2017\nseed: 3\nduration_s: 3\n"
        "platform: {path: straight, speed_mps: 0.5, start_xy: [2.0, 1.0], heading_rad: 0.0}\n"
    )
    out, bag = tmp_path / "out", tmp_path / "bag"
    assert main(["fly", str(scenario), "--out", str(out), "--mcap", "--bag", str(bag)]) == 0
    assert (out / "report.html").is_file() and (out / "result.json").is_file()
    s = _summary(out / mx.MCAP_FILE)
    assert {c.topic for c in s.channels.values()} == set(EXPECTED)
    assert (bag / "metadata.yaml").is_file() and list(bag.glob("*.mcap"))
    # the bag written beside it replays
    assert main(["replay", str(bag), "--out", str(tmp_path / "replay")]) == 0
    header = (out / "log.csv").read_text().splitlines()[0].split(",")
    assert "q_WB_w" in header and "q_WB_est_w" in header
