"""Fuzzer of the recorded-flight readers: damaged ULogs and bags must give one clean error, never a crash
or a hang.

Run: ``python benchmarks/fuzz_logs.py [--cases N] [--seed S] [--timeout S] [--ulog PATH]`` (prints JSON).

Inputs: the real PX4 ULog of the test data (``$ALIGHT_TESTDATA/px4_ulog/sample_log_small.ulg``, default
``<repo>/../shared/testdata/real``) when present, and three generated flights of 2 s (odometry, IMU,
range, ground truth at 50 Hz and 10 camera frames): ROS 2 bags with MCAP storage (zstd per message, and
uncompressed), one with sqlite3 storage (all through ``alight.interfaces.rosbag_writer``), and a ROS 1 bag
(rosbags' ROS 1 writer).
Each case damages one copy of an input, the log file itself (inside a bag's directory, its storage file,
the metadata kept): ``truncate`` cuts it at a uniformly drawn offset, ``flip`` sets 1 to 16 bytes at
uniformly drawn offsets to random values. The damaged copy is replayed in full (``replay_recording``:
read, then the falanga2017 Pipeline) and the outcome counted:

* ``ok``: replayed (the damage missed what is read, or only damaged values that were dropped);
* ``clean``: an ``AlightError`` (what the CLI prints as one line with exit status 2);
* ``crash``: any other exception (listed with its type and message);
* ``hang``: no answer within ``--timeout`` seconds (SIGALRM).

Deterministic: the damage comes from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
KINDS = ("truncate", "flip")


def testdata_dir() -> Path:
    env = os.environ.get("ALIGHT_TESTDATA")
    return Path(env) if env else ROOT.parent / "shared" / "testdata" / "real"


# --------------------------------------------------------------------------------------------------
# generated flights
# --------------------------------------------------------------------------------------------------


def synthetic_log(duration_s: float = 2.0, rate_hz: float = 50.0) -> dict[str, np.ndarray]:
    """Mission-log arrays of a slow climbing turn above a platform driving east (deterministic)."""
    t = np.arange(1, int(duration_s * rate_hz) + 1) / rate_hz
    n = t.size
    yaw = 0.3 * t
    p_WB = np.column_stack([0.5 * t, 0.2 * t, 1.0 + 0.5 * t])
    v_WB = np.tile([0.5, 0.2, 0.5], (n, 1))
    q_WB = np.column_stack([np.zeros(n), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)])
    return {
        "t": t,
        "p_WB": p_WB,
        "v_WB": v_WB,
        "q_WB": q_WB,
        "p_WB_est": p_WB + 0.01,
        "v_WB_est": v_WB,
        "q_WB_est": q_WB,
        "w_WB_B": np.tile([0.0, 0.0, 0.3], (n, 1)),
        "range_m": p_WB[:, 2] - 0.5,
        "p_WP": np.column_stack([3.0 + t, np.zeros(n), np.full(n, 0.5)]),
        "v_WP": np.tile([1.0, 0.0, 0.0], (n, 1)),
    }


def synthetic_frames(n: int = 10, rate_hz: float = 5.0) -> list[tuple[float, np.ndarray, list[Any]]]:
    """Small grey frames (120 x 160, a gradient with a dark square), capture times from 0.1 s."""
    frames = []
    for k in range(n):
        img = np.tile(np.linspace(40, 220, 160, dtype=np.uint8), (120, 1))
        img[40:80, 60 + 4 * k : 100 + 4 * k] = 10
        frames.append((0.1 + k / rate_hz, img, []))
    return frames


def write_ros1_bag(
    path: Path, log: dict[str, np.ndarray], frames: list[tuple[float, np.ndarray, list[Any]]]
) -> Path:
    """A ROS 1 bag with /alight/odometry (nav_msgs/Odometry), /alight/imu (sensor_msgs/Imu) and
    /alight/camera/image_raw (sensor_msgs/Image, mono8), through rosbags' ROS 1 writer."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    T = ts.types

    def header(t: float, frame: str) -> Any:
        ns = int(round(t * 1e9))
        return T["std_msgs/msg/Header"](
            seq=0, stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame
        )

    def vec(v: Any) -> Any:
        return T["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    with Writer(path) as w:
        c_odo = w.add_connection("/alight/odometry", "nav_msgs/msg/Odometry", typestore=ts)
        c_imu = w.add_connection("/alight/imu", "sensor_msgs/msg/Imu", typestore=ts)
        c_img = w.add_connection("/alight/camera/image_raw", "sensor_msgs/msg/Image", typestore=ts)
        items: list[tuple[int, Any, bytes]] = []
        for i, t in enumerate(log["t"]):
            p, q = log["p_WB_est"][i], log["q_WB_est"][i]
            pose = T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=float(p[2])),
                orientation=T["geometry_msgs/msg/Quaternion"](
                    x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
                ),
            )
            odo = T["nav_msgs/msg/Odometry"](
                header=header(t, "world"),
                child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=vec((0, 0, 0)), angular=vec((0, 0, 0))),
                    covariance=np.zeros(36),
                ),
            )
            imu = T["sensor_msgs/msg/Imu"](
                header=header(t, "base_link"),
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=vec(log["w_WB_B"][i]),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=vec((0.0, 0.0, 9.81)),
                linear_acceleration_covariance=np.zeros(9),
            )
            ns = int(round(t * 1e9))
            items.append((ns, c_odo, ts.serialize_ros1(odo, "nav_msgs/msg/Odometry")))
            items.append((ns, c_imu, ts.serialize_ros1(imu, "sensor_msgs/msg/Imu")))
        for t, img, _ in frames:
            h, wd = img.shape
            msg = T["sensor_msgs/msg/Image"](
                header=header(t, "camera"), height=h, width=wd, encoding="mono8", is_bigendian=0, step=wd,
                data=img.reshape(-1),
            )  # fmt: skip
            items.append((int(round(t * 1e9)), c_img, ts.serialize_ros1(msg, "sensor_msgs/msg/Image")))
        for ns, conn, raw in sorted(items, key=lambda x: x[0]):
            w.write(conn, ns, raw)
    return path


def make_inputs(workdir: Path, ulog: Path | None = None) -> dict[str, Path]:
    """The undamaged inputs: name -> path (a file, or a ROS 2 bag directory)."""
    from alight.interfaces.rosbag_writer import write_bag

    log, frames = synthetic_log(), synthetic_frames()
    inputs: dict[str, Path] = {}
    real = ulog if ulog is not None else testdata_dir() / "px4_ulog" / "sample_log_small.ulg"
    if real.is_file():
        inputs["ulog_real"] = real
    inputs["ros2_mcap"] = write_bag(workdir / "ros2_mcap", log, frames, storage="mcap")
    # uncompressed too, so that flips land in the messages' bytes, not only in zstd frames
    inputs["ros2_mcap_raw"] = write_bag(
        workdir / "ros2_mcap_raw", log, frames, storage="mcap", compress=False
    )
    inputs["ros2_sqlite3"] = write_bag(workdir / "ros2_sqlite3", log, frames, storage="sqlite3")
    inputs["ros1"] = write_ros1_bag(workdir / "ros1.bag", log, frames)
    return inputs


# --------------------------------------------------------------------------------------------------
# damage and replay
# --------------------------------------------------------------------------------------------------


def _storage_file(path: Path) -> Path:
    """The file to damage: the log itself, or a ROS 2 bag directory's storage file."""
    if path.is_file():
        return path
    files = sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3"))
    return files[0]


def damaged_copy(src: Path, dst: Path, kind: str, rng: np.random.Generator) -> str:
    """Copy ``src`` to ``dst`` and damage the copy's log file; returns a description of the damage."""
    if src.is_dir():
        shutil.copytree(src, dst)
    else:
        shutil.copyfile(src, dst)
    target = _storage_file(dst)
    data = bytearray(target.read_bytes())
    if kind == "truncate":
        cut = int(rng.integers(0, len(data)))
        target.write_bytes(bytes(data[:cut]))
        return f"truncate at {cut}/{len(data)}"
    k = int(rng.integers(1, 17))
    offsets = rng.integers(0, len(data), size=k)
    for o in offsets.tolist():
        data[o] = int(rng.integers(0, 256))
    target.write_bytes(bytes(data))
    return f"flip {k} bytes at {sorted(offsets.tolist())[:4]}..."


class _Timeout(Exception):
    pass


@contextmanager
def _deadline(seconds: float) -> Iterator[None]:
    def on_alarm(signum: int, frame: object) -> None:
        raise _Timeout

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def classify(path: Path, timeout_s: float, replay: Callable[[Path], object]) -> tuple[str, str]:
    """Replay ``path``: ('ok' | 'clean' | 'crash' | 'hang', detail)."""
    from alight.errors import AlightError

    try:
        with _deadline(timeout_s), warnings.catch_warnings():
            warnings.simplefilter("ignore")  # warnings are not failures here; exceptions are
            replay(path)
    except _Timeout:
        return "hang", f"no answer in {timeout_s} s"
    except AlightError as err:
        text = str(err)
        return ("clean", text) if "\n" not in text else ("crash", f"multi-line error: {text[:200]}")
    except Exception as err:  # noqa: BLE001 - this is what the fuzzer counts
        return "crash", f"{type(err).__name__}: {str(err)[:200]}"
    return "ok", ""


def _replay(path: Path) -> object:
    from alight.interfaces.replay import replay_recording

    return replay_recording(path)


def fuzz(
    inputs: dict[str, Path],
    workdir: Path,
    *,
    cases_per_kind: int = 25,
    seed: int = 0,
    timeout_s: float = 30.0,
    replay: Callable[[Path], object] = _replay,
) -> dict[str, Any]:
    """Damage every input ``cases_per_kind`` times per kind of damage and count the outcomes."""
    rng = np.random.default_rng(seed)
    summary: dict[str, Any] = {"seed": seed, "cases_per_kind": cases_per_kind, "inputs": {}}
    totals = dict.fromkeys(("ok", "clean", "crash", "hang"), 0)
    wall0 = time.perf_counter()
    for name, src in inputs.items():
        per: dict[str, Any] = {}
        for kind in KINDS:
            counts = dict.fromkeys(("ok", "clean", "crash", "hang"), 0)
            failures: list[str] = []
            t0 = time.perf_counter()
            for i in range(cases_per_kind):
                dst = workdir / f"{name}_{kind}_{i}{'' if src.is_dir() else src.suffix}"
                what = damaged_copy(src, dst, kind, rng)
                outcome, detail = classify(dst, timeout_s, replay)
                counts[outcome] += 1
                totals[outcome] += 1
                if outcome in ("crash", "hang") and len(failures) < 5:
                    failures.append(f"{what}: {detail}")
                shutil.rmtree(dst) if dst.is_dir() else dst.unlink()
            per[kind] = {**counts, "wall_s": round(time.perf_counter() - t0, 2), "failures": failures}
        summary["inputs"][name] = per
    summary["totals"] = totals
    summary["wall_s"] = round(time.perf_counter() - wall0, 2)
    summary["s_per_case"] = round(summary["wall_s"] / max(1, sum(totals.values())), 3)
    return summary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=25, help="cases per input and kind of damage")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=30.0, help="seconds before a case counts as a hang")
    ap.add_argument("--ulog", type=Path, default=None, help="the real ULog (default: the test data's)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="alight_fuzz_") as tmp:
        work = Path(tmp)
        inputs = make_inputs(work / "inputs", args.ulog) if (work / "inputs").mkdir() is None else {}
        summary = fuzz(inputs, work, cases_per_kind=args.cases, seed=args.seed, timeout_s=args.timeout)
    print(json.dumps(summary, indent=2))
    return 0 if summary["totals"]["crash"] == 0 and summary["totals"]["hang"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
