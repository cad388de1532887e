"""The exports open in Foxglove: every message of ``alight fly --bag`` (ROS 2, CDR in MCAP) decodes with
Foxglove's own ROS 2 decoder (``mcap-ros2-support``), and every message of ``alight fly --mcap`` with its
protobuf decoder (``mcap-protobuf-support``), 0 failures; the decoded values are the flight's."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader

from alight.interfaces import mcap_export as mx
from alight.interfaces import rosbag_writer as rw


def _decode_all(path: Path, factory: Any) -> tuple[Counter[str], list[str], dict[str, list[Any]]]:
    """Decode every message of the MCAP at ``path``: counts per topic, failures, decoded per topic."""
    ok: Counter[str] = Counter()
    failures: list[str] = []
    decoded: dict[str, list[Any]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        for chunk in summary.chunk_indexes:
            assert chunk.compression == "zstd"  # MCAP's own chunk compression
        for schema, channel, message in reader.iter_messages():
            try:
                decoder = factory.decoder_for(channel.message_encoding, schema)
                assert decoder is not None, f"no decoder for {channel.message_encoding}"
                value = decoder(message.data)
            except Exception as err:  # noqa: BLE001 - what the test counts
                failures.append(f"{channel.topic}: {type(err).__name__}: {err}")
                continue
            ok[channel.topic] += 1
            decoded.setdefault(channel.topic, []).append(value)
    return ok, failures, decoded


@pytest.mark.slow
def test_bag_decodes_with_foxglove_ros2_decoder(vision_flight: Any, tmp_path: Path) -> None:
    from mcap_ros2.decoder import DecoderFactory

    latency = vision_flight.scenario.perception.latency_s
    bag = rw.write_bag(tmp_path / "bag", vision_flight.log, vision_flight.frames, latency_s=latency)
    (mcap_file,) = bag.glob("*.mcap")
    ok, failures, decoded = _decode_all(mcap_file, DecoderFactory())
    assert failures == []
    n = vision_flight.log["t"].size
    assert ok[rw.IMAGE_TOPIC] == len(vision_flight.frames) > 10
    assert ok[rw.ODOMETRY_TOPIC] == ok[rw.IMU_TOPIC] == ok[rw.RANGE_TOPIC] == n
    # the values are the flight's, not garbage: the images pixel for pixel, the true positions
    for (_, image, _), msg in zip(vision_flight.frames, decoded[rw.IMAGE_TOPIC], strict=True):
        got = np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.height, msg.width, -1)
        assert np.array_equal(got.reshape(image.shape), image)
    p = np.array([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z]
                  for m in decoded[rw.TRUTH_UAV_TOPIC]])  # fmt: skip
    assert p.shape[0] > 0 and np.all(np.isfinite(p)) and float(p[:, 2].max()) > 1.0


@pytest.mark.slow
def test_mcap_export_decodes_with_foxglove_protobuf_decoder(vision_flight: Any, tmp_path: Path) -> None:
    from mcap_protobuf.decoder import DecoderFactory

    from alight.airframe import DEFAULT_AIRFRAME
    from alight.mission.presets import build_preset

    preset = build_preset(vision_flight.scenario, DEFAULT_AIRFRAME, np.random.default_rng(0))
    path = tmp_path / mx.MCAP_FILE
    exporter = mx.McapExporter(path, camera=preset.camera, mount=preset.mount)
    for t, image, obs in vision_flight.frames:
        exporter(t, image, obs)
    exporter.finish(vision_flight.log, vision_flight.run.mode_history)
    ok, failures, _ = _decode_all_any_compression(path, DecoderFactory())
    assert failures == [] and sum(ok.values()) > 1000


def _decode_all_any_compression(path: Path, factory: Any) -> tuple[Counter[str], list[str], Any]:
    ok: Counter[str] = Counter()
    failures: list[str] = []
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            try:
                decoder = factory.decoder_for(channel.message_encoding, schema)
                if decoder is None:  # JSON channels (the mode history, the result): not protobuf
                    assert channel.message_encoding == "json", channel.topic
                    continue
                decoder(message.data)
            except Exception as err:  # noqa: BLE001 - what the test counts
                failures.append(f"{channel.topic}: {type(err).__name__}: {err}")
                continue
            ok[channel.topic] += 1
    return ok, failures, None
