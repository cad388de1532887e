"""Write a simulated flight as a ROS 2 bag (rosbags' writer; MCAP or sqlite3 storage), so that the
flight can be replayed (``alight replay``), or looked at with ROS tools.

Use :class:`BagRecorder` as the runner's ``frame_sink`` (it writes each camera frame as it comes, so the
frames are never all held in memory), then call :meth:`BagRecorder.finish` with the mission log to write
the other topics and close the bag. Topics (ENU / FLU, REP-103; frame ids ``world``, ``base_link``,
``camera``, ``platform``):

=================================  ======================  ===============================================
topic                              type                    content
=================================  ======================  ===============================================
``/alight/camera/image_raw``       sensor_msgs/Image       every frame the detector saw (mono8 or bgr8,
                                                           lossless); stamp = capture time, bag time =
                                                           when it reached the Pipeline
``/alight/odometry``               nav_msgs/Odometry       the onboard ego estimate (50 Hz), twist in B
``/alight/imu``                    sensor_msgs/Imu         50 Hz: true body rates, and the specific force
                                                           from the true velocity's central difference
``/alight/range``                  sensor_msgs/Range       the range the Pipeline used (50 Hz)
``/alight/ground_truth/uav``       nav_msgs/Odometry       true pose and velocity of the vehicle
``/alight/ground_truth/platform``  nav_msgs/Odometry       true pad centre, heading along its velocity
=================================  ======================  ===============================================

The IMU and odometry topics come from the mission log (50 Hz), not from the simulator's 200 Hz / 40 Hz
sensors, which the runner does not expose: a replay of the bag re-runs estimation on these, and
reproduces the flight's detections frame for frame (the images are stored losslessly and the detectors
are functions of the image and the range).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from alight.errors import ReplayError
from alight.evaluation.log import log_channel
from alight.types import G_W, Observation, quat_to_rotmat

IMAGE_TOPIC = "/alight/camera/image_raw"
ODOMETRY_TOPIC = "/alight/odometry"
IMU_TOPIC = "/alight/imu"
RANGE_TOPIC = "/alight/range"
TRUTH_UAV_TOPIC = "/alight/ground_truth/uav"
TRUTH_PLATFORM_TOPIC = "/alight/ground_truth/platform"
RANGE_MAX_M = 40.0
"""``max_range`` written in every Range message (m), the simulated TeraRanger's."""


def _ns(t: float) -> int:
    return int(round(t * 1e9))


class BagRecorder:
    """A ``frame_sink`` that writes a flight into a ROS 2 bag at ``path`` (a directory, created).

    Args:
        path: the bag directory; it must not exist yet (rosbags' writer refuses to overwrite).
        storage: ``"mcap"`` (one ``.mcap`` file, the ROS 2 default since Iron) or ``"sqlite3"``.
        latency_s: the perception latency (s): a frame captured at t reached the Pipeline at t + this,
            which is the frame's bag time.
        compress: compress with zstd: MCAP storage compresses its chunks (MCAP's own compression, which
            every MCAP reader undoes: Foxglove and ``ros2 bag`` read the messages as plain CDR); sqlite3
            storage compresses each message (the bag's ``compression_mode: message``, which only bag
            readers that read ``metadata.yaml`` undo). Per-message compression in an MCAP made 4,179 of
            a flight's 4,227 messages fail in Foxglove's ROS 2 decoder: the MCAP declares plain CDR.
    """

    def __init__(
        self, path: str | Path, *, storage: str = "mcap", latency_s: float = 0.0, compress: bool = True
    ) -> None:
        from alight.interfaces.replay_readers import need

        need("rosbags")
        from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore

        plugins = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
        if storage not in plugins:
            raise ReplayError(f"bag storage must be 'mcap' or 'sqlite3', got {storage!r}")
        self.path = Path(path)
        if self.path.exists():
            raise ReplayError(f"{self.path}: already exists (a bag is written into a new directory)")
        self.latency_s = float(latency_s)
        self.frames = 0
        self._ts = get_typestore(Stores.ROS2_HUMBLE)
        self._types = self._ts.types
        self._writer = Writer(self.path, version=9, storage_plugin=plugins[storage])
        if compress:
            # zstd, lossless: MCAP chunks (storage-level), or each message in sqlite3 (no chunks there)
            mode = CompressionMode.STORAGE if storage == "mcap" else CompressionMode.MESSAGE
            self._writer.set_compression(mode, CompressionFormat.ZSTD)
        try:
            self._writer.open()
        except Exception as err:  # noqa: BLE001 - OSError, rosbags' WriterError
            raise ReplayError(f"{self.path}: cannot write a bag ({err})") from None
        self._conn: dict[str, Any] = {}
        self._closed = False

    # -- messages -----------------------------------------------------------------------------------
    def _connection(self, topic: str, msgtype: str) -> Any:
        conn = self._conn.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, msgtype, typestore=self._ts)
            self._conn[topic] = conn
        return conn

    def _write(self, topic: str, msg: Any, t_bag: float) -> None:
        conn = self._connection(topic, msg.__msgtype__)
        self._writer.write(conn, _ns(t_bag), self._ts.serialize_cdr(msg, msg.__msgtype__))

    def _header(self, t: float, frame_id: str) -> Any:
        ns = _ns(t)
        stamp = self._types["builtin_interfaces/msg/Time"](
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000
        )
        return self._types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def _vector3(self, v: Sequence[float] | NDArray[np.float64]) -> Any:
        return self._types["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def _odometry(
        self, t: float, p: NDArray[np.float64], q: NDArray[np.float64], v_W: Any, child: str
    ) -> Any:
        T = self._types
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=float(p[2])),
            orientation=T["geometry_msgs/msg/Quaternion"](
                x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
            ),
        )
        # REP-103: the twist of an Odometry is expressed in the child frame
        v_B = quat_to_rotmat(q).T @ v_W if v_W is not None and np.isfinite(v_W).all() else np.zeros(3)
        twist = T["geometry_msgs/msg/Twist"](
            linear=self._vector3(v_B), angular=self._vector3((0.0, 0.0, 0.0))
        )
        return T["nav_msgs/msg/Odometry"](
            header=self._header(t, "world"),
            child_frame_id=child,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
        )

    # -- the frame sink -----------------------------------------------------------------------------
    def __call__(self, t_capture: float, image: NDArray[np.uint8], observations: list[Observation]) -> None:
        img = np.ascontiguousarray(image)
        if img.dtype != np.uint8 or img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
            raise ValueError(f"camera frames must be uint8 (H, W) or (H, W, 3), got {img.dtype} {img.shape}")
        h, w = img.shape[:2]
        c = 1 if img.ndim == 2 else 3
        msg = self._types["sensor_msgs/msg/Image"](
            header=self._header(t_capture, "camera"),
            height=h,
            width=w,
            encoding="mono8" if c == 1 else "bgr8",  # the renderer's colour frames are OpenCV's BGR
            is_bigendian=0,
            step=w * c,
            data=img.reshape(-1),
        )
        self._write(IMAGE_TOPIC, msg, t_capture + self.latency_s)
        self.frames += 1

    # -- the rest, from the log ---------------------------------------------------------------------
    def finish(self, log: Mapping[str, np.ndarray]) -> Path:
        """Write odometry, IMU, range and ground truth from the mission log's arrays, and close the bag."""
        try:
            self._write_log(log)
        finally:
            self.close()
        return self.path

    def _write_log(self, log: Mapping[str, np.ndarray]) -> None:
        T = self._types
        t = np.asarray(log["t"], dtype=np.float64)
        n = t.shape[0]

        def ch(name: str, width: int) -> NDArray[np.float64]:
            return log_channel(log, name, width)

        p_WB, v_WB, q_WB = ch("p_WB", 3), ch("v_WB", 3), ch("q_WB", 4)
        p_est, v_est, q_est = ch("p_WB_est", 3), ch("v_WB_est", 3), ch("q_WB_est", 4)
        p_WP, v_WP = ch("p_WP", 3), ch("v_WP", 3)
        w_B, rng = ch("w_WB_B", 3), ch("range_m", 1)[:, 0]
        a_W = np.gradient(v_WB, t, axis=0) if n > 1 else np.zeros((n, 3))
        zero9 = np.zeros(9)
        for i in range(n):
            ti = float(t[i])
            if np.isfinite(p_est[i]).all() and np.isfinite(q_est[i]).all():
                self._write(ODOMETRY_TOPIC, self._odometry(ti, p_est[i], q_est[i], v_est[i], "base_link"), ti)
            if np.isfinite(q_WB[i]).all() and np.isfinite(w_B[i]).all() and np.isfinite(a_W[i]).all():
                f_B = quat_to_rotmat(q_WB[i]).T @ (a_W[i] - G_W)
                imu = T["sensor_msgs/msg/Imu"](
                    header=self._header(ti, "base_link"),
                    orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=np.array([-1.0, 0, 0, 0, 0, 0, 0, 0, 0]),  # -1: not given
                    angular_velocity=self._vector3(w_B[i]),
                    angular_velocity_covariance=zero9,
                    linear_acceleration=self._vector3(f_B),
                    linear_acceleration_covariance=zero9,
                )
                self._write(IMU_TOPIC, imu, ti)
            r = float(rng[i])
            msg = T["sensor_msgs/msg/Range"](
                header=self._header(ti, "base_link"),
                radiation_type=1,  # INFRARED
                field_of_view=0.05,
                min_range=0.0,
                max_range=RANGE_MAX_M,
                range=r if math.isfinite(r) else math.inf,  # +inf: no return (REP-117)
            )
            self._write(RANGE_TOPIC, msg, ti)
            if np.isfinite(p_WB[i]).all() and np.isfinite(q_WB[i]).all():
                self._write(TRUTH_UAV_TOPIC, self._odometry(ti, p_WB[i], q_WB[i], v_WB[i], "base_link"), ti)
            if np.isfinite(p_WP[i]).all():
                vx, vy = float(v_WP[i, 0]), float(v_WP[i, 1])
                yaw = math.atan2(vy, vx) if math.hypot(vx, vy) > 1e-3 else 0.0
                q = np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
                self._write(TRUTH_PLATFORM_TOPIC, self._odometry(ti, p_WP[i], q, v_WP[i], "platform"), ti)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._writer.close()


def write_bag(
    path: str | Path,
    log: Mapping[str, np.ndarray],
    frames: Sequence[tuple[float, NDArray[np.uint8], list[Observation]]] = (),
    *,
    storage: str = "mcap",
    latency_s: float = 0.0,
    compress: bool = True,
) -> Path:
    """Write a flight already in memory (its log arrays and frames) as a ROS 2 bag at ``path``."""
    rec = BagRecorder(path, storage=storage, latency_s=latency_s, compress=compress)
    try:
        for t, img, obs in frames:
            rec(t, img, obs)
    except BaseException:
        rec.close()
        raise
    return rec.finish(log)
