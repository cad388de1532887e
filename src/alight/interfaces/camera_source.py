"""Where the bridge's images come from: a real camera (OpenCV ``VideoCapture``) or the emulated autopilot.

Every source implements :class:`CameraSource`: ``read()`` returns the next ``(t_capture, image)`` or
``None`` when no new frame is ready (it never blocks for long), and ``close()``. ``clock`` says which
clock ``t_capture`` is on: ``"autopilot"`` (the emulated autopilot stamps frames with its simulated clock,
the same clock as its MAVLink messages) or ``"companion"`` (``time.monotonic()`` on the companion
computer, for a real camera; the bridge maps it onto the autopilot's clock).

Transport between the emulated autopilot and the bridge: a loopback **TCP** stream of length-prefixed
messages (:func:`encode_message`). Why TCP and not UDP or shared memory: a 752x480 frame is 361 kB,
above a UDP datagram's 64 kB, so UDP would need our own fragmentation and reassembly with loss
handling; shared memory needs a ring with its own synchronisation and does not cross machines. TCP on
loopback moves 7 MB/s (20 Hz) at negligible cost, keeps frames in order, and lets the bridge run on
another machine than the emulator. The same stream carries the emulator's verdict at the end of a
mission (``RSLT``, JSON) and its ground-truth log (``TLOG``, an ``.npz``), which are not MAVLink
traffic on a real vehicle and so do not belong on the MAVLink link.

Wire format, little endian: ``kind`` (4 ASCII bytes), ``length`` (uint32), then ``length`` bytes.
A ``FRAM`` payload is ``seq`` (uint32), ``t_capture`` (float64, s), ``height``, ``width``,
``channels`` (uint32 each), then ``height*width*channels`` uint8 pixels, row-major. A ``PFIX`` payload
(the platform's own GNSS fix, ``platform.telemetry``, which a real vehicle sends by a radio of its own,
not through the autopilot) is 16 float64: ``t_stamp`` (s, the stream's clock), ``p_WP``, ``v_WP`` (ENU,
m and m/s) and the receiver's 3x3 position covariance (m^2), row-major.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import select
import socket
import struct
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np

from alight.errors import InputError

Clock = Literal["autopilot", "companion"]

_HEAD = struct.Struct("<4sI")
_FRAME = struct.Struct("<IdIII")
MAX_MESSAGE_BYTES = 64 * 1024 * 1024
"""Largest message accepted (a 4K colour frame is 25 MB); anything larger is a corrupt stream."""
KIND_FRAME = b"FRAM"
KIND_RESULT = b"RSLT"
KIND_TRUTH_LOG = b"TLOG"
KIND_SCENARIO = b"SCEN"
KIND_PLATFORM_FIX = b"PFIX"
"""The platform's own GNSS fix (``platform.telemetry``): on a real vehicle it reaches the companion by
its own radio, not through the autopilot, so the simulator sends it on this side stream."""
_FIX = struct.Struct("<16d")  # t_stamp, p_WP (3), v_WP (3), cov_p_WP (3x3, row-major)
_KINDS = (KIND_FRAME, KIND_RESULT, KIND_TRUTH_LOG, KIND_SCENARIO, KIND_PLATFORM_FIX)


@dataclass(frozen=True, slots=True)
class PlatformFix:
    """A platform GNSS fix as it crossed the stream (the bridge stamps ``t_stamp`` on its clock)."""

    t_stamp: float
    p_WP: np.ndarray
    v_WP: np.ndarray
    cov_p_WP: np.ndarray


class CameraSource(Protocol):
    """A stream of images with their capture times."""

    clock: Clock

    def read(self) -> tuple[float, np.ndarray] | None:
        """The next frame ``(t_capture [s], image HxW or HxWx3 uint8)``, or None when none is ready."""
        ...

    def close(self) -> None: ...


def encode_message(kind: bytes, payload: bytes) -> bytes:
    if len(kind) != 4:
        raise ValueError("a message kind is 4 bytes")
    return _HEAD.pack(kind, len(payload)) + payload


def encode_frame(seq: int, t_capture: float, image: np.ndarray) -> bytes:
    img = np.ascontiguousarray(image, dtype=np.uint8)
    h, w = img.shape[:2]
    c = 1 if img.ndim == 2 else img.shape[2]
    return encode_message(KIND_FRAME, _FRAME.pack(seq & 0xFFFFFFFF, t_capture, h, w, c) + img.tobytes())


def encode_platform_fix(t_stamp: float, p_WP: np.ndarray, v_WP: np.ndarray, cov_p_WP: np.ndarray) -> bytes:
    values = np.concatenate(([t_stamp], np.ravel(p_WP), np.ravel(v_WP), np.ravel(cov_p_WP))).astype(float)
    return encode_message(KIND_PLATFORM_FIX, _FIX.pack(*values))


def decode_platform_fix(payload: bytes) -> PlatformFix | None:
    """The fix of a ``PFIX`` payload, or None when it is malformed (wrong size, a NaN or inf, a
    covariance that is not symmetric with a non-negative diagonal)."""
    if len(payload) != _FIX.size:
        return None
    v = np.array(_FIX.unpack(payload))
    if not np.isfinite(v).all():
        return None
    cov = v[7:16].reshape(3, 3)
    if not (np.allclose(cov, cov.T) and (np.diag(cov) >= 0.0).all()):
        return None
    return PlatformFix(float(v[0]), v[1:4].copy(), v[4:7].copy(), cov.copy())


def decode_frame(payload: bytes) -> tuple[int, float, np.ndarray] | None:
    """``(seq, t_capture, image)`` of a ``FRAM`` payload, or None when it is malformed."""
    if len(payload) < _FRAME.size:
        return None
    seq, t, h, w, c = _FRAME.unpack_from(payload)
    if not math.isfinite(t) or c not in (1, 3) or h == 0 or w == 0 or h > 8192 or w > 8192:
        return None
    if len(payload) - _FRAME.size != h * w * c:
        return None
    img = np.frombuffer(payload, dtype=np.uint8, offset=_FRAME.size).reshape((h, w) if c == 1 else (h, w, c))
    return seq, t, img.copy()


class FrameServer:
    """The emulated autopilot's end: listens on loopback TCP, serves one client at a time."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        self._listen = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listen.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._listen.bind((host, port))
        except OSError as err:
            self._listen.close()
            raise InputError(f"camera stream: cannot listen on {host}:{port} ({err.strerror})") from None
        self._listen.listen(1)
        self._listen.setblocking(False)
        self.port: int = self._listen.getsockname()[1]
        self._client: socket.socket | None = None
        self._seq = 0
        self.hello: bytes | None = None
        """Sent to each client as it connects (the emulator's scenario, ``SCEN``, JSON)."""

    @property
    def connected(self) -> bool:
        """A client holds the stream now: one that has closed its end is dropped here, not only when a
        send to it fails (the emulator waits for a companion without sending anything)."""
        self.accept()
        if self._client is not None and self._client_closed():
            self._client.close()
            self._client = None
        return self._client is not None

    def _client_closed(self) -> bool:
        assert self._client is not None
        try:
            # a client never sends on this stream: readable with no bytes means it closed its end
            readable, _, _ = select.select([self._client], [], [], 0.0)
            return bool(readable) and self._client.recv(1, socket.MSG_PEEK) == b""
        except InterruptedError:
            return False
        except OSError:  # reset by the peer
            return True

    def accept(self) -> None:
        """Take a waiting client, if there is none yet (non-blocking); it is sent ``hello`` at once."""
        if self._client is not None:
            return
        try:
            conn, _ = self._listen.accept()
        except (BlockingIOError, InterruptedError):
            return
        conn.setblocking(True)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._client = conn
        if self.hello is not None:
            self._send(self.hello)

    def _send(self, data: bytes) -> bool:
        self.accept()
        if self._client is None:
            return False
        try:
            self._client.sendall(data)
            return True
        except OSError:  # the client went away: drop it and wait for another
            self._client.close()
            self._client = None
            return False

    def send_frame(self, t_capture: float, image: np.ndarray) -> bool:
        """Send one frame; False when no client is connected (the frame is dropped, as a camera would)."""
        self._seq += 1
        return self._send(encode_frame(self._seq, t_capture, image))

    def send_platform_fix(
        self, t_stamp: float, p_WP: np.ndarray, v_WP: np.ndarray, cov_p_WP: np.ndarray
    ) -> bool:
        """Send one platform GNSS fix; False when no client is connected (lost, as a radio's would be)."""
        return self._send(encode_platform_fix(t_stamp, p_WP, v_WP, cov_p_WP))

    def send_result(self, result: dict[str, Any]) -> bool:
        return self._send(encode_message(KIND_RESULT, json.dumps(result).encode()))

    def send_truth_log(self, arrays: dict[str, np.ndarray]) -> bool:
        buf = io.BytesIO()
        np.savez(buf, **arrays)  # type: ignore[arg-type]  # numpy's stub types **kwds as its own flags
        return self._send(encode_message(KIND_TRUTH_LOG, buf.getvalue()))

    def close(self) -> None:
        if self._client is not None:
            with contextlib.suppress(OSError):
                self._client.shutdown(socket.SHUT_RDWR)
            self._client.close()
            self._client = None
        self._listen.close()


def _connected_to_itself(sock: socket.socket) -> bool:
    try:
        return bool(sock.getsockname() == sock.getpeername())
    except OSError:
        return False


class SocketCameraSource:
    """The bridge's end of the emulated autopilot's camera stream (``tcp:HOST:PORT``).

    ``read()`` returns every frame in order (none is skipped: the emulator runs in lockstep and its
    frames are the mission's camera). Malformed messages are dropped; a stream that loses message
    boundaries (a bad length) is closed, and ``read()`` then returns None for ever."""

    clock: Clock = "autopilot"

    def __init__(self, host: str, port: int, *, connect_timeout_s: float = 10.0) -> None:
        deadline = time.monotonic() + connect_timeout_s
        while True:
            try:
                sock = socket.create_connection((host, port), timeout=1.0)
                if _connected_to_itself(sock):
                    # Retrying a loopback port in the ephemeral range before the emulator listens can
                    # pick that same port as the source: TCP's simultaneous open then connects the
                    # socket to itself, which holds the port the emulator is about to bind.
                    sock.close()
                    raise ConnectionRefusedError("connected to itself; the emulator is not listening yet")
                self._sock: socket.socket | None = sock
                break
            except OSError as err:
                if time.monotonic() > deadline:
                    raise InputError(f"camera stream tcp:{host}:{port}: cannot connect ({err})") from None
                time.sleep(0.05)
        self._sock.setblocking(False)
        self._buf = bytearray()
        self._frames: deque[tuple[float, np.ndarray]] = deque()
        self.result: dict[str, Any] | None = None
        """The emulator's verdict (``result.json`` fields), once it has sent it."""
        self.truth_log: dict[str, np.ndarray] | None = None
        self.scenario: dict[str, Any] | None = None
        """The emulator's scenario, sent when the stream opens."""
        self._fixes: deque[PlatformFix] = deque()
        self.dropped_messages = 0
        self.last_seq = 0

    def _pump(self) -> None:
        if self._sock is None:
            return
        while True:
            try:
                chunk = self._sock.recv(1 << 20)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                chunk = b""
            if not chunk:  # closed by the peer
                self._sock.close()
                self._sock = None
                break
            self._buf += chunk
        while len(self._buf) >= _HEAD.size:
            kind, n = _HEAD.unpack_from(self._buf)
            if n > MAX_MESSAGE_BYTES or kind not in _KINDS:
                # Message boundaries are lost: nothing after this point can be trusted.
                self.dropped_messages += 1
                self._buf.clear()
                if self._sock is not None:
                    self._sock.close()
                    self._sock = None
                return
            if len(self._buf) < _HEAD.size + n:
                return
            payload = bytes(self._buf[_HEAD.size : _HEAD.size + n])
            del self._buf[: _HEAD.size + n]
            self._handle(kind, payload)

    def _handle(self, kind: bytes, payload: bytes) -> None:
        try:
            if kind == KIND_FRAME:
                frame = decode_frame(payload)
                if frame is None:
                    self.dropped_messages += 1
                    return
                self.last_seq = frame[0]
                self._frames.append((frame[1], frame[2]))
            elif kind == KIND_PLATFORM_FIX:
                fix = decode_platform_fix(payload)
                if fix is None:
                    self.dropped_messages += 1
                    return
                self._fixes.append(fix)
            elif kind in (KIND_RESULT, KIND_SCENARIO):
                value = json.loads(payload.decode())
                if isinstance(value, dict):
                    if kind == KIND_RESULT:
                        self.result = value
                    else:
                        self.scenario = value
            else:
                with np.load(io.BytesIO(payload), allow_pickle=False) as z:
                    self.truth_log = {k: z[k] for k in z.files}
        except (ValueError, UnicodeDecodeError, OSError, EOFError):
            self.dropped_messages += 1

    def read(self) -> tuple[float, np.ndarray] | None:
        self._pump()
        return self._frames.popleft() if self._frames else None

    def read_platform_fixes(self) -> list[PlatformFix]:
        """The platform fixes received since the last call, in the order sent."""
        self._pump()
        fixes = list(self._fixes)
        self._fixes.clear()
        return fixes

    def poll(self) -> None:
        """Receive what has arrived (frames stay queued for ``read``)."""
        self._pump()

    @property
    def open(self) -> bool:
        return self._sock is not None

    def wait_closed(self, timeout_s: float) -> None:
        """Keep reading (the verdict, the truth log) until the emulator closes the stream or the time
        is up."""
        deadline = time.monotonic() + timeout_s
        while self._sock is not None and time.monotonic() < deadline:
            self._pump()
            if self.result is not None and self.truth_log is not None:
                return
            time.sleep(0.01)

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


class OpenCvCameraSource:
    """A real camera, a video file or a stream URL through OpenCV's ``VideoCapture``.

    A background thread grabs frames as fast as the device gives them and keeps only the latest, stamped
    with ``time.monotonic()`` when ``read`` returned from the driver (the capture time is earlier by the
    driver's latency, which the bridge's ``camera_latency_s`` option subtracts)."""

    clock: Clock = "companion"

    def __init__(self, spec: int | str) -> None:
        import cv2

        self._cap = cv2.VideoCapture(spec)
        if not self._cap.isOpened():
            self._cap.release()
            raise InputError(f"camera {spec!r}: cannot open (no such device, file or stream)")
        self._lock = threading.Lock()
        self._latest: tuple[float, np.ndarray] | None = None
        self._running = True
        self.ended = False
        self._thread = threading.Thread(target=self._grab, name="alight-camera", daemon=True)
        self._thread.start()

    def _grab(self) -> None:
        while self._running:
            ok, image = self._cap.read()
            if not ok:
                self.ended = True  # end of a file, or the device went away
                return
            with self._lock:
                self._latest = (time.monotonic(), image)

    def read(self) -> tuple[float, np.ndarray] | None:
        with self._lock:
            frame, self._latest = self._latest, None
        return frame

    def close(self) -> None:
        self._running = False
        self._thread.join(timeout=1.0)
        self._cap.release()


def open_camera(spec: str) -> CameraSource:
    """A camera source from a command-line spec: ``tcp:HOST:PORT`` (the emulated autopilot's stream), a
    device index (``0``), a file path or a URL (``rtsp://...``)."""
    if spec.startswith("tcp:"):
        host, _, port = spec[4:].rpartition(":")
        if not host or not port.isdigit():
            raise InputError(f"camera {spec!r}: expected tcp:HOST:PORT")
        return SocketCameraSource(host, int(port))
    if spec.isdigit():
        return OpenCvCameraSource(int(spec))
    return OpenCvCameraSource(spec)


__all__ = [
    "CameraSource",
    "FrameServer",
    "OpenCvCameraSource",
    "SocketCameraSource",
    "decode_frame",
    "encode_frame",
    "open_camera",
]
