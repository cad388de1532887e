"""Export a flight as MCAP for Foxglove: ``alight fly SCENARIO --out DIR --mcap`` writes ``DIR/flight.mcap``.

Schemas: Foxglove's own, as protobuf (``foxglove-schemas-protobuf``), each channel's schema the
``FileDescriptorSet`` of its message, so any MCAP reader decodes it without ROS or alight. Protobuf
rather than Foxglove's JSON schemas: images are bytes (JSON would base64 them, a third larger and slow
to parse), and the schemas come compiled from Foxglove's package instead of being written by hand here.
The numeric series are one JSON channel (a flat object per log row, its JSON Schema generated from the
log's channels): Foxglove plots JSON fields directly, and the set of series follows the log without a
message definition of alight's own. Channels are listed in docs/export.md.

Use :class:`McapExporter` as the runner's ``frame_sink`` (frames are written as they come and never held
in memory), then :meth:`McapExporter.finish` with the mission log and the mode history. Times: the
simulated clock, ``log_time`` in ns; message timestamps the capture time (frames) or sample time.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from alight.cameras import CameraModel
from alight.cameras.pinhole import CameraMount, PinholeCamera
from alight.errors import ReplayError
from alight.evaluation.log import log_channel
from alight.types import Observation

MCAP_FILE = "flight.mcap"

WORLD_FRAME = "world"
UAV_FRAME = "uav"
PLATFORM_FRAME = "platform"
CAMERA_FRAME = "camera"

CH_UAV_POSE = "/uav/pose"
CH_UAV_POSE_EST = "/uav/pose_estimate"
CH_PLATFORM_POSE = "/platform/pose"
CH_PLATFORM_POSE_EST = "/platform/pose_estimate"
CH_MEASUREMENTS = "/platform/measurements"
CH_TF = "/tf"
CH_IMAGE = "/camera/image/compressed"
CH_ANNOTATIONS = "/camera/annotations"
CH_MODE = "/mission/mode"
CH_SERIES = "/alight/series"
CH_CALIBRATION = "/camera/calibration"

JPEG_QUALITY = 90
"""Quality of the exported camera frames (JPEG keeps a 60 s flight at 20 Hz to tens of MB; the MCAP is
for looking at, the bag of ``alight fly --bag`` is the lossless record)."""


def _ns(t: float) -> int:
    return int(round(t * 1e9))


def _file_descriptor_set(message_class: Any) -> bytes:
    """The serialized ``FileDescriptorSet`` of a protobuf message class and every file it depends on
    (the schema data MCAP's protobuf profile asks for)."""
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    fds = FileDescriptorSet()
    seen: set[str] = set()
    stack = [message_class.DESCRIPTOR.file]
    order = []
    while stack:
        fd = stack.pop()
        if fd.name in seen:
            continue
        seen.add(fd.name)
        order.append(fd)
        stack.extend(fd.dependencies)
    for fd in reversed(order):  # dependencies first
        fd.CopyToProto(fds.file.add())
    return bytes(fds.SerializeToString())


class McapExporter:
    """Writes a flight into ``path`` (an ``.mcap`` file, created or replaced).

    Args:
        path: the file.
        camera: the camera model; a pinhole camera (anything with ``width``, ``height``, ``K`` and ``dist``)
            gives a ``foxglove.CameraCalibration`` with every frame, so Foxglove can draw the frames in 3D.
        mount: the camera's mount (``R_BC``, ``p_BC``): a ``uav`` -> ``camera`` transform in ``/tf``.
    """

    def __init__(
        self, path: str | Path, *, camera: CameraModel | None = None, mount: CameraMount | None = None
    ) -> None:
        from alight.interfaces.replay_readers import need

        need("mcap")
        need("foxglove_schemas_protobuf")
        from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
        from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
        from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
        from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
        from foxglove_schemas_protobuf.Log_pb2 import Log
        from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
        from mcap.writer import Writer

        self.path = Path(path)
        try:
            self._file: IO[bytes] = open(self.path, "wb")  # noqa: SIM115 - closed in finish/close
        except OSError as err:
            raise ReplayError(f"{self.path}: cannot write ({err.strerror})") from None
        self._w = Writer(self._file)
        self._w.start(profile="", library="alight")
        self.counts: dict[str, int] = {}
        self._schema: dict[str, int] = {}
        self._channel: dict[str, int] = {}
        self._classes: dict[str, Any] = {
            "pose": PoseInFrame,
            "tf": FrameTransforms,
            "image": CompressedImage,
            "annotations": ImageAnnotations,
            "log": Log,
            "calibration": CameraCalibration,
        }
        self._calibration = self._calibration_msg(camera)
        self._mount = mount
        self._closed = False

    def _calibration_msg(self, camera: CameraModel | None) -> Any:
        if not isinstance(camera, PinholeCamera):
            return None  # not a pinhole camera (an omnidirectional model has no CameraCalibration)
        K = camera.K
        msg = self._classes["calibration"]()
        msg.frame_id = CAMERA_FRAME
        msg.width, msg.height = int(camera.width), int(camera.height)
        msg.distortion_model = "plumb_bob" if len(camera.dist) <= 5 else "rational_polynomial"
        msg.D.extend(float(x) for x in camera.dist)
        K = np.asarray(K, dtype=np.float64)
        msg.K.extend(K.reshape(-1).tolist())
        msg.R.extend(np.eye(3).reshape(-1).tolist())
        msg.P.extend(np.hstack([K, np.zeros((3, 1))]).reshape(-1).tolist())
        return msg

    # -- channels -----------------------------------------------------------------------------------
    def _proto_channel(self, topic: str, cls: Any) -> int:
        cid = self._channel.get(topic)
        if cid is None:
            name = cls.DESCRIPTOR.full_name
            sid = self._schema.get(name)
            if sid is None:
                sid = self._w.register_schema(name=name, encoding="protobuf", data=_file_descriptor_set(cls))
                self._schema[name] = sid
            cid = self._w.register_channel(topic=topic, message_encoding="protobuf", schema_id=sid)
            self._channel[topic] = cid
        return cid

    def _put(self, topic: str, msg: Any, t: float) -> None:
        cid = self._proto_channel(topic, type(msg))
        ns = _ns(t)
        self._w.add_message(channel_id=cid, log_time=ns, publish_time=ns, data=msg.SerializeToString())
        self.counts[topic] = self.counts.get(topic, 0) + 1

    @staticmethod
    def _stamp(msg: Any, t: float) -> None:
        ns = _ns(t)
        msg.timestamp.seconds, msg.timestamp.nanos = divmod(ns, 1_000_000_000)

    def _pose(self, t: float, p: NDArray[np.float64], q: NDArray[np.float64]) -> Any:
        msg = self._classes["pose"]()
        self._stamp(msg, t)
        msg.frame_id = WORLD_FRAME
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(x) for x in p)
        o = msg.pose.orientation
        o.x, o.y, o.z, o.w = (float(x) for x in q)
        return msg

    # -- the frame sink -----------------------------------------------------------------------------
    def __call__(self, t_capture: float, image: NDArray[np.uint8], observations: list[Observation]) -> None:
        ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(image), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        if not ok:
            raise ValueError(f"cannot encode a camera frame of shape {np.shape(image)}")
        img = self._classes["image"]()
        self._stamp(img, t_capture)
        img.frame_id = CAMERA_FRAME
        img.format = "jpeg"
        img.data = buf.tobytes()
        self._put(CH_IMAGE, img, t_capture)
        if self._calibration is not None:
            self._stamp(self._calibration, t_capture)
            self._put(CH_CALIBRATION, self._calibration, t_capture)
        ann = self._classes["annotations"]()
        for obs in observations:
            px = np.asarray(obs.pixels, dtype=np.float64).reshape(-1, 2)
            if px.shape[0] == 0:
                continue
            pts = ann.points.add()
            self._stamp(pts, t_capture)
            # a closed outline for a quad, the points themselves otherwise
            pts.type = pts.LINE_LOOP if px.shape[0] == 4 else pts.POINTS
            for u, v in px:
                pt = pts.points.add()
                pt.x, pt.y = float(u), float(v)
            pts.outline_color.r, pts.outline_color.g, pts.outline_color.b, pts.outline_color.a = (
                0.17,
                0.63,
                0.17,
                1.0,
            )
            pts.thickness = 3.0
            text = ann.texts.add()
            self._stamp(text, t_capture)
            text.position.x, text.position.y = float(px[0, 0]), float(px[0, 1])
            text.text = f"{obs.kind} {obs.quality:.2f}"
            text.font_size = 14.0
            text.text_color.r = text.text_color.g = text.text_color.b = text.text_color.a = 1.0
        self._put(CH_ANNOTATIONS, ann, t_capture)

    # -- the rest, from the log ---------------------------------------------------------------------
    def finish(
        self, log: Mapping[str, np.ndarray], mode_history: Sequence[tuple[float, str, str]] = ()
    ) -> Path:
        """Write poses, transforms, detections, mode events and the numeric series, and close the file."""
        try:
            self._write_log(log, mode_history)
        finally:
            self.close()
        return self.path

    def _write_log(
        self, log: Mapping[str, np.ndarray], mode_history: Sequence[tuple[float, str, str]]
    ) -> None:
        self._declare_channels()
        t = np.asarray(log["t"], dtype=np.float64)
        self._write_poses(t, log)
        self._write_measurements(log)
        self._write_modes(mode_history)
        self._write_series(t, log)

    def _declare_channels(self) -> None:
        # every channel is in the file, with no messages where the flight had none (no detection, no
        # camera), so a Foxglove layout made for one flight opens any other
        c = self._classes
        for topic, cls in (
            (CH_IMAGE, c["image"]),
            (CH_ANNOTATIONS, c["annotations"]),
            (CH_UAV_POSE, c["pose"]),
            (CH_UAV_POSE_EST, c["pose"]),
            (CH_PLATFORM_POSE, c["pose"]),
            (CH_PLATFORM_POSE_EST, c["pose"]),
            (CH_MEASUREMENTS, c["pose"]),
            (CH_TF, c["tf"]),
            (CH_MODE, c["log"]),
            *([(CH_CALIBRATION, c["calibration"])] if self._calibration is not None else []),
        ):
            self._proto_channel(topic, cls)

    def _write_poses(self, t: NDArray[np.float64], log: Mapping[str, np.ndarray]) -> None:
        """The vehicle's and the platform's poses (truth and estimate) and their transforms, per log row."""
        n = t.shape[0]

        def ch(name: str, width: int) -> NDArray[np.float64]:
            return log_channel(log, name, width)

        p_WB, q_WB, p_est, q_est = ch("p_WB", 3), ch("q_WB", 4), ch("p_WB_est", 3), ch("q_WB_est", 4)
        p_WP, v_WP, p_WP_est, v_WP_est = ch("p_WP", 3), ch("v_WP", 3), ch("p_WP_est", 3), ch("v_WP_est", 3)
        q_WP, q_WP_est = _heading_quat(v_WP), _heading_quat(v_WP_est)
        tf_cls = self._classes["tf"]
        for i in range(n):
            ti = float(t[i])
            tfs = tf_cls()
            for topic, p, q, child in (
                (CH_UAV_POSE, p_WB[i], q_WB[i], UAV_FRAME),
                (CH_UAV_POSE_EST, p_est[i], q_est[i], None),
                (CH_PLATFORM_POSE, p_WP[i], q_WP[i], PLATFORM_FRAME),
                (CH_PLATFORM_POSE_EST, p_WP_est[i], q_WP_est[i], None),
            ):
                if not (np.isfinite(p).all() and np.isfinite(q).all()):
                    continue
                self._put(topic, self._pose(ti, p, q), ti)
                if child is not None:
                    tr = tfs.transforms.add()
                    self._stamp(tr, ti)
                    tr.parent_frame_id, tr.child_frame_id = WORLD_FRAME, child
                    tr.translation.x, tr.translation.y, tr.translation.z = (float(x) for x in p)
                    tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w = (float(x) for x in q)
            if self._mount is not None:
                tr = tfs.transforms.add()
                self._stamp(tr, ti)
                tr.parent_frame_id, tr.child_frame_id = UAV_FRAME, CAMERA_FRAME
                p_BC = np.asarray(self._mount.p_BC, dtype=np.float64)
                x, y, z, w = Rotation.from_matrix(np.asarray(self._mount.R_BC, dtype=np.float64)).as_quat()
                tr.translation.x, tr.translation.y, tr.translation.z = (float(v) for v in p_BC)
                tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w = (
                    float(x),
                    float(y),
                    float(z),
                    float(w),
                )
            if len(tfs.transforms):
                self._put(CH_TF, tfs, ti)

    def _write_measurements(self, log: Mapping[str, np.ndarray]) -> None:
        t_det = np.asarray(log.get("t_det", np.zeros(0)), dtype=np.float64).reshape(-1)
        p_meas = np.asarray(log.get("p_WP_meas", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
        for k in np.argsort(t_det, kind="stable"):
            self._put(
                CH_MEASUREMENTS,
                self._pose(float(t_det[k]), p_meas[k], np.array([0.0, 0.0, 0.0, 1.0])),
                float(t_det[k]),
            )

    def _write_modes(self, mode_history: Sequence[tuple[float, str, str]]) -> None:
        log_cls = self._classes["log"]
        for tm, mode, reason in mode_history:
            msg = log_cls()
            self._stamp(msg, float(tm))
            msg.level = log_cls.INFO
            msg.name = "mission"
            msg.message = f"{mode}: {reason}" if reason else str(mode)
            self._put(CH_MODE, msg, float(tm))

    def _write_series(self, t: NDArray[np.float64], log: Mapping[str, np.ndarray]) -> None:
        from alight.evaluation.log import column_names

        n = t.shape[0]
        cols: list[tuple[str, NDArray[np.float64]]] = []
        for name, value in log.items():
            a = np.asarray(value)
            if name == "t" or a.dtype.kind != "f" or a.ndim not in (1, 2) or a.shape[0] != n:
                continue
            width = 1 if a.ndim == 1 else a.shape[1]
            block = a.reshape(n, width)
            cols += [(c, block[:, j]) for j, c in enumerate(column_names(name, width))]
        schema = {
            "title": "alight.Series",
            "type": "object",
            "properties": {"t": {"type": "number"}, "mode": {"type": "string"}}
            | {c: {"type": ["number", "null"]} for c, _ in cols},
        }
        sid = self._w.register_schema(
            name="alight.Series", encoding="jsonschema", data=json.dumps(schema).encode()
        )
        cid = self._w.register_channel(topic=CH_SERIES, message_encoding="json", schema_id=sid)
        modes = np.asarray(log.get("mode", np.full(n, "", dtype=np.str_))).astype(str)
        for i in range(n):
            row: dict[str, object] = {"t": float(t[i]), "mode": str(modes[i])}
            for c, a in cols:
                x = float(a[i])
                row[c] = x if math.isfinite(x) else None  # JSON has no NaN
            ns = _ns(float(t[i]))
            self._w.add_message(channel_id=cid, log_time=ns, publish_time=ns, data=json.dumps(row).encode())
        self.counts[CH_SERIES] = n

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            try:
                self._w.finish()  # type: ignore[no-untyped-call]
            finally:
                self._file.close()


def _heading_quat(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Yaw-only attitudes (x, y, z, w) along each velocity's horizontal direction (identity when still);
    NaN rows where the velocity is NaN."""
    yaw = np.where(np.hypot(v[:, 0], v[:, 1]) > 1e-3, np.arctan2(v[:, 1], v[:, 0]), 0.0)
    q = np.column_stack([np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2), np.cos(yaw / 2)])
    q[~np.isfinite(v).all(axis=1)] = np.nan
    return q
