"""Camera sources: the emulator's TCP stream round-trips frames, verdict and truth log; a corrupt stream is
dropped without an exception; OpenCV reads a video file and refuses a missing one clearly."""

from __future__ import annotations

import math
import socket
import struct
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from alight.errors import InputError
from alight.interfaces.camera_source import (
    KIND_PLATFORM_FIX,
    FrameServer,
    OpenCvCameraSource,
    SocketCameraSource,
    decode_frame,
    decode_platform_fix,
    encode_frame,
    encode_message,
    encode_platform_fix,
    open_camera,
)


def _read(src: SocketCameraSource, timeout_s: float = 5.0) -> tuple[float, np.ndarray]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        frame = src.read()
        if frame is not None:
            return frame
        time.sleep(0.005)
    raise AssertionError("no frame")


def test_frame_codec_round_trip_and_malformed_payloads() -> None:
    img = np.random.default_rng(0).integers(0, 256, size=(48, 64, 3), dtype=np.uint8)
    data = encode_frame(7, 1.25, img)
    seq, t, out = decode_frame(data[8:]) or (None, None, None)
    assert seq == 7 and t == 1.25 and out is not None and np.array_equal(out, img)
    assert decode_frame(data[8:-1]) is None  # short
    assert decode_frame(struct.pack("<IdIII", 1, float("nan"), 2, 2, 1) + b"\0" * 4) is None
    assert decode_frame(struct.pack("<IdIII", 1, 0.0, 2, 2, 2) + b"\0" * 8) is None  # 2 channels


def _connected_stream() -> tuple[FrameServer, SocketCameraSource]:
    """An emulator's stream end and the bridge's, connected (within 5 s)."""
    server = FrameServer("127.0.0.1", 0)
    server.hello = None
    src = SocketCameraSource("127.0.0.1", server.port)
    deadline = time.monotonic() + 5.0
    while not server.connected and time.monotonic() < deadline:
        time.sleep(0.01)
    return server, src


def test_tcp_stream_delivers_frames_in_order_with_verdict_and_truth() -> None:
    server, src = _connected_stream()
    try:
        imgs = [np.full((480, 752), i, dtype=np.uint8) for i in range(3)]
        for i, img in enumerate(imgs):
            assert server.send_frame(0.05 * i, img)
        for i, img in enumerate(imgs):
            t, got = _read(src)
            assert t == pytest.approx(0.05 * i) and np.array_equal(got, img)
        server.send_result({"outcome": "landed"})
        server.send_truth_log({"t": np.arange(3.0), "p_WB": np.ones((3, 3))})
        src.wait_closed(5.0)
        assert src.result == {"outcome": "landed"}
        assert src.truth_log is not None and np.array_equal(src.truth_log["p_WB"], np.ones((3, 3)))
    finally:
        src.close()
        server.close()


def test_corrupt_stream_is_dropped_not_raised() -> None:
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    src = SocketCameraSource("127.0.0.1", listener.getsockname()[1])
    conn, _ = listener.accept()
    try:
        conn.sendall(b"JUNK" + struct.pack("<I", 5) + b"hello" + bytes(range(200)))
        time.sleep(0.1)
        assert src.read() is None and src.dropped_messages >= 1 and not src.open
        assert src.read() is None  # and stays quiet
    finally:
        conn.close()
        listener.close()
        src.close()


def test_opencv_reads_a_video_file_and_refuses_a_missing_one(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    for i in range(5):
        writer.write(np.full((48, 64, 3), 40 * i, dtype=np.uint8))
    writer.release()
    cam = OpenCvCameraSource(str(path))
    try:
        deadline = time.monotonic() + 5.0
        frame = None
        while frame is None and time.monotonic() < deadline:
            frame = cam.read()
            time.sleep(0.01)
        assert frame is not None and frame[1].shape == (48, 64, 3) and cam.clock == "companion"
    finally:
        cam.close()
    with pytest.raises(InputError, match="cannot open"):
        open_camera(str(tmp_path / "missing.avi"))
    with pytest.raises(InputError, match="tcp:HOST:PORT"):
        open_camera("tcp:nohostport")


def test_platform_fix_codec_round_trips_and_refuses_malformed_fixes() -> None:
    p, v = np.array([1.0, -2.0, 0.5]), np.array([6.0, 0.1, 0.0])
    cov = np.diag([0.25, 0.25, 0.3])
    data = encode_platform_fix(12.5, p, v, cov)
    fix = decode_platform_fix(data[8:])
    assert fix is not None and fix.t_stamp == 12.5
    assert np.array_equal(fix.p_WP, p) and np.array_equal(fix.v_WP, v) and np.array_equal(fix.cov_p_WP, cov)
    assert decode_platform_fix(data[8:-1]) is None  # short
    assert decode_platform_fix(encode_platform_fix(math.nan, p, v, cov)[8:]) is None
    assert decode_platform_fix(encode_platform_fix(1.0, p, np.array([math.inf, 0.0, 0.0]), cov)[8:]) is None
    skew = cov.copy()
    skew[0, 1] = 0.1
    assert decode_platform_fix(encode_platform_fix(1.0, p, v, skew)[8:]) is None  # not symmetric
    assert decode_platform_fix(encode_platform_fix(1.0, p, v, -cov)[8:]) is None  # negative variance


def test_platform_fixes_cross_the_stream_in_order_beside_the_frames() -> None:
    server, src = _connected_stream()
    try:
        deadline = time.monotonic() + 5.0
        cov = np.eye(3) * 0.25
        img = np.zeros((4, 4), dtype=np.uint8)
        assert server.send_platform_fix(0.1, np.zeros(3), np.ones(3), cov)
        assert server.send_frame(0.15, img)
        server._send(encode_message(KIND_PLATFORM_FIX, b"\0" * 7))  # a malformed fix: dropped, counted
        assert server.send_platform_fix(0.2, np.ones(3), np.ones(3), cov)
        fixes: list = []
        while len(fixes) < 2 and time.monotonic() < deadline:
            fixes += src.read_platform_fixes()
            time.sleep(0.005)
        assert [f.t_stamp for f in fixes] == [0.1, 0.2] and np.array_equal(fixes[1].p_WP, np.ones(3))
        assert _read(src)[0] == 0.15 and src.dropped_messages == 1 and src.open
        assert src.read_platform_fixes() == []
    finally:
        src.close()
        server.close()
