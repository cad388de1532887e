"""Robustness harness: corrupt frames through every detector, bad measurements through every estimator.

    PYTHONPATH=src python benchmarks/robustness_harness.py [--frames 1000] [--measurements 1000] [--seed 0]

prints a JSON summary. Every frame is garbage (empty, tiny, NaN, float, 16-bit, 12-bit, int16, wrong
channel counts, non-contiguous, oversized, not an array, uniform colours, per-pixel noise; some with a
non-finite capture time), so any observation is a false detection. Each estimator gets a valid stream
(a platform at 1.5 m/s, measurements at 10 Hz with 5 cm noise) with bad measurements mixed in (NaN, inf,
1e12 m, negative or asymmetric covariance, stamped 1,000 s in the future or 1e300 s, far out of order,
50 m outliers; zero quaternions and 1e12 m odometry for the ego filter), and after each bad one a good one.

Counted per block: ``crashes`` (an exception other than the documented ``ImageError`` /
``EstimationError``), ``hangs`` (a call over the per-call limit, interrupted by SIGALRM),
``false_detections``, ``nan_states`` (a non-finite estimate), ``refused`` (documented errors or a False
return) and, for the platform estimators, the final position error (m) and the share of good measurements
after a bad one that were used (``good_used_frac``: 1.0 means nothing was blocked). The test
``tests/meta/test_robustness.py`` runs a short version (50 each).
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import time
from collections.abc import Callable, Iterator
from functools import partial
from typing import Any

import numpy as np

from alight.cameras import CameraMount, MountedCamera
from alight.errors import EstimationError, ImageError
from alight.estimation import PLATFORM_ESTIMATORS as ESTIMATORS
from alight.estimation import EgoEkf, EgoEkfConfig
from alight.perception.detect_cli import detector_names, make_detector
from alight.perception.image_input import MAX_PIXELS
from alight.types import PlatformMeasurement


class _Hang(Exception):
    pass


def _on_alarm(signum: int, frame: Any) -> None:
    raise _Hang


def _call(
    fn: Callable[[], Any],
    limit_s: float,
    refused: tuple[type[Exception], ...] = (ImageError, EstimationError),
) -> tuple[str, Any]:
    """``("ok", value)``, ``("refused", error)`` for the documented refusals ``refused``, ``("crash",
    error)`` for any other exception, or ``("hang", None)`` after ``limit_s`` (s; SIGALRM must be
    handled by :func:`_on_alarm`). The one watchdog of the fuzz harnesses."""
    signal.setitimer(signal.ITIMER_REAL, limit_s)
    try:
        return "ok", fn()
    except _Hang:
        return "hang", None
    except refused as err:
        return "refused", err
    except Exception as err:  # the harness counts what a block should never raise
        return "crash", err
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)


def corrupt_frames(rng: np.random.Generator) -> Iterator[tuple[str, Any, float]]:
    """Endless garbage: ``(kind, image, capture time)``."""
    H, W = 120, 160
    kinds: list[tuple[str, Callable[[], Any]]] = [
        ("empty", lambda: np.zeros((0, 0), np.uint8)),
        ("1x1", lambda: np.zeros((1, 1, 3), np.uint8)),
        ("nan", lambda: np.full((H, W), np.nan)),
        ("nan_bgr", lambda: np.where(rng.random((H, W, 3)) < 0.5, np.nan, rng.random((H, W, 3)))),
        ("float_noise", lambda: rng.random((H, W, 3)).astype(np.float32)),
        ("uint16_noise", lambda: rng.integers(0, 65536, (H, W), dtype=np.uint16)),
        ("12bit_noise", lambda: rng.integers(0, 4096, (H, W, 3), dtype=np.uint16)),
        ("int16_noise", lambda: rng.integers(-32768, 32768, (H, W), dtype=np.int16)),
        ("two_channels", lambda: rng.integers(0, 256, (H, W, 2), dtype=np.uint8)),
        ("five_channels", lambda: rng.integers(0, 256, (H, W, 5), dtype=np.uint8)),
        ("four_dims", lambda: np.zeros((4, 4, 4, 4), np.uint8)),
        ("non_contiguous", lambda: rng.integers(0, 256, (2 * H, 3 * W, 3), dtype=np.uint8)[::2, ::3]),
        ("huge", lambda: np.broadcast_to(np.uint8(0), (MAX_PIXELS // 4000 + 1, 4000))),
        ("none", lambda: None),
        ("string", lambda: "frame.png"),
        ("ragged_list", lambda: [[1, 2, 3], [4]]),
        ("uniform_red", lambda: np.broadcast_to(np.array([20, 20, 220], np.uint8), (H, W, 3)).copy()),
        ("uniform_grey", lambda: np.full((H, W), int(rng.integers(0, 256)), np.uint8)),
        ("noise_grey", lambda: rng.integers(0, 256, (H, W), dtype=np.uint8)),
        ("noise_bgr", lambda: rng.integers(0, 256, (H, W, 3), dtype=np.uint8)),
        (
            "noise_reddish",
            lambda: np.dstack(
                [
                    rng.integers(0, 256, (H, W), dtype=np.uint8),
                    rng.integers(0, 256, (H, W), dtype=np.uint8),
                    rng.integers(200, 256, (H, W), dtype=np.uint8),
                ]
            ),
        ),
        ("bool", lambda: rng.random((H, W)) < 0.5),
    ]
    while True:
        kind, make = kinds[int(rng.integers(len(kinds)))]
        t = float("nan") if rng.random() < 0.05 else float(rng.uniform(0, 100))
        yield kind, make(), t


def run_detectors(n_frames: int, seed: int, limit_s: float, names: list[str] | None = None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in sorted(detector_names()) if names is None else names:
        det = make_detector(name)
        rng = np.random.default_rng(seed)
        counts = {"frames": 0, "crashes": 0, "hangs": 0, "refused": 0, "false_detections": 0}
        examples: list[str] = []
        t0 = time.perf_counter()
        for kind, image, t in _take(corrupt_frames(rng), n_frames):
            counts["frames"] += 1
            status, value = _call(partial(det.detect, image, t), limit_s)
            if status == "ok" and value:
                counts["false_detections"] += 1
                examples.append(f"false:{kind}")
            elif status == "crash":
                counts["crashes"] += 1
                examples.append(f"crash:{kind}:{type(value).__name__}")
            elif status in ("hang", "refused"):
                counts["hangs" if status == "hang" else "refused"] += 1
        out[name] = {**counts, "wall_s": round(time.perf_counter() - t0, 2), "examples": examples[:5]}
    return out


def _take(it: Iterator[Any], n: int) -> Iterator[Any]:
    for _ in range(n):
        yield next(it)


def _measurement(t: float, p: Any, cov: Any) -> Any:
    # PlatformMeasurement refuses non-finite arrays itself; build bad ones past its check, as a buggy
    # upstream block could
    m = object.__new__(PlatformMeasurement)
    for k, v in {
        "t": t,
        "p_WP": np.asarray(p, float),
        "cov_p_WP": np.asarray(cov, float),
        "yaw": None,
    }.items():
        object.__setattr__(m, k, v)
    for f in PlatformMeasurement.__dataclass_fields__:
        if not hasattr(m, f):
            object.__setattr__(m, f, None)
    return m


BAD_MEASUREMENTS = [
    "nan",
    "inf",
    "far",
    "neg_cov",
    "asym_cov",
    "future",
    "far_future",
    "out_of_order",
    "outlier",
]


def _bad(kind: str, t: float, p: Any, cov: Any) -> Any:
    if kind == "nan":
        return _measurement(t, [math.nan, 0, 0], cov)
    if kind == "inf":
        return _measurement(t, p, np.full((3, 3), math.inf))
    if kind == "far":
        return _measurement(t, [1e12, 0, 0], cov)
    if kind == "neg_cov":
        return _measurement(t, p, -cov)
    if kind == "asym_cov":
        c = cov.copy()
        c[0, 1] = 1.0
        return _measurement(t, p, c)
    if kind == "future":
        return _measurement(t + 1000.0, p, cov)
    if kind == "far_future":
        return _measurement(1e300, p, cov)
    if kind == "out_of_order":
        return _measurement(t - 50.0, p, cov)
    return _measurement(t, np.asarray(p) + [50.0, 0.0, 0.0], cov)  # outlier


def _count_bad(counts: dict[str, int], examples: list[str], kind: str, status: str, value: Any) -> None:
    """Tally one bad input's fate: a crash (kept as an example), a hang, or a refusal (an exception the
    block raised on purpose, or a False return)."""
    counts["bad"] += 1
    if status == "crash":
        counts["crashes"] += 1
        examples.append(f"crash:{kind}:{type(value).__name__}:{value}")
    elif status == "hang":
        counts["hangs"] += 1
    elif status == "refused" or value is False:
        counts["refused"] += 1


def run_platform_estimators(n_bad: int, seed: int, limit_s: float) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in sorted(ESTIMATORS):
        rng = np.random.default_rng(seed)
        est = ESTIMATORS[name].build_default(MountedCamera(camera=None, mount=CameraMount.downward()))
        counts = {"bad": 0, "crashes": 0, "hangs": 0, "refused": 0, "nan_states": 0, "good_after_bad": 0}
        good_used = 0
        examples: list[str] = []
        cov = np.diag([0.05**2, 0.05**2, 0.05**2])
        t = 0.0
        t0 = time.perf_counter()

        def truth(t: float) -> Any:
            return np.array([1.5 * t, 0.0, 0.5])

        def good(t: float, rng: np.random.Generator = rng, cov: Any = cov) -> Any:
            return _measurement(t, truth(t) + rng.normal(0, 0.05, 3), cov)

        for _ in range(20):  # a track first
            t += 0.1
            est.predict(t)
            est.update(good(t))
        for i in range(n_bad):
            kind = BAD_MEASUREMENTS[i % len(BAD_MEASUREMENTS)]
            t += 0.1
            _call(partial(est.predict, t), limit_s)
            status, value = _call(partial(est.update, _bad(kind, t, truth(t), cov)), limit_s)
            _count_bad(counts, examples, kind, status, value)
            # a huge-gap query must cost bounded work
            _call(partial(est.state, t + 1e7), limit_s)
            t += 0.1
            _call(partial(est.predict, t), limit_s)
            status, value = _call(partial(est.update, good(t)), limit_s)
            counts["good_after_bad"] += 1
            good_used += status == "ok" and value is True
            status, st = _call(partial(est.state, t), limit_s)
            if status == "ok" and not (np.isfinite(st.p_WP).all() and np.isfinite(st.cov_p_WP).all()):
                counts["nan_states"] += 1
            elif status != "ok":
                counts["crashes" if status == "crash" else "hangs" if status == "hang" else "refused"] += 1
        for _ in range(20):  # a clean tail: the track must be back
            t += 0.1
            est.predict(t)
            est.update(good(t))
        err = float(np.linalg.norm(est.state(t).p_WP - truth(t)))
        out[name] = {
            **counts,
            "good_used_frac": round(good_used / max(1, counts["good_after_bad"]), 3),
            "final_error_m": round(err, 3),
            "wall_s": round(time.perf_counter() - t0, 2),
            "examples": examples[:5],
        }
    return out


def run_ego(n_bad: int, seed: int, limit_s: float) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in ("eskf",):  # the flight's ego estimator
        rng = np.random.default_rng(seed)
        ekf: Any = EgoEkf(EgoEkfConfig())
        q = np.array([0.0, 0.0, 0.0, 1.0])
        ekf.initialize(0.0, np.zeros(3), np.zeros(3), q)
        counts = {"bad": 0, "crashes": 0, "hangs": 0, "refused": 0, "nan_states": 0}
        examples: list[str] = []
        f_hover = np.array([0.0, 0.0, 9.81])
        t = 0.0
        t0 = time.perf_counter()
        kinds = ["nan", "far", "zero_quat", "nan_quat", "imu_rows", "future", "huge_time", "jump"]
        for i in range(n_bad):
            kind = kinds[i % len(kinds)]
            ts = t + 0.005 * np.arange(1, 6)
            ekf.predict_imu_many(ts, np.tile(f_hover, (5, 1)), np.zeros((5, 3)))
            t = float(ts[-1])
            p, qq, tt = np.zeros(3) + rng.normal(0, 0.01, 3), q.copy(), t
            if kind == "nan":
                p = np.array([math.nan, 0, 0])
            elif kind == "far":
                p = np.array([1e12, 0, 0])
            elif kind == "zero_quat":
                qq = np.zeros(4)
            elif kind == "nan_quat":
                qq = np.array([math.nan, 0, 0, 1])
            elif kind == "future":
                tt = t + 1000.0
            elif kind == "huge_time":
                tt = 1e300
            elif kind == "jump":
                p = np.array([500.0, 0, 0])
            if kind == "imu_rows":  # more time stamps than IMU rows
                many = partial(
                    ekf.predict_imu_many, t + 0.005 * np.arange(1, 11), np.zeros((3, 3)), np.zeros((3, 3))
                )
                status, value = _call(many, limit_s)
            else:
                status, value = _call(partial(ekf.update_odometry, tt, p, qq), limit_s)
            _count_bad(counts, examples, kind, status, value)
            t = max(t, ekf.t)
            # a good message after each bad one
            _call(partial(ekf.update_odometry, t, rng.normal(0, 0.01, 3), q), limit_s)
            s = ekf.state()
            if not (np.isfinite(s.p_WB).all() and np.isfinite(ekf.covariance).all()):
                counts["nan_states"] += 1
        out[name] = {
            **counts,
            "final_error_m": round(float(np.linalg.norm(ekf.state().p_WB)), 3),
            "wall_s": round(time.perf_counter() - t0, 2),
            "examples": examples[:5],
        }
    return out


def run(
    n_frames: int = 1000,
    n_measurements: int = 1000,
    seed: int = 0,
    limit_s: float = 5.0,
    detectors: list[str] | None = None,
) -> dict[str, Any]:
    """The whole harness; the JSON summary as a dict."""
    signal.signal(signal.SIGALRM, _on_alarm)
    t0 = time.perf_counter()
    summary: dict[str, Any] = {
        "frames_per_detector": n_frames,
        "bad_measurements_per_estimator": n_measurements,
        "seed": seed,
        "per_call_limit_s": limit_s,
        "detectors": run_detectors(n_frames, seed, limit_s, detectors),
        "platform_estimators": run_platform_estimators(n_measurements, seed, limit_s),
        "ego_estimators": run_ego(n_measurements, seed, limit_s),
    }
    blocks = [
        *summary["detectors"].values(),
        *summary["platform_estimators"].values(),
        *summary["ego_estimators"].values(),
    ]
    summary["totals"] = {
        k: sum(int(b.get(k, 0)) for b in blocks)
        for k in ("crashes", "hangs", "false_detections", "nan_states")
    }
    summary["wall_s"] = round(time.perf_counter() - t0, 1)
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--measurements", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--limit-s", type=float, default=5.0, help="per-call time limit (s)")
    parser.add_argument("--detectors", nargs="*", default=None, help="registry names (default: all)")
    args = parser.parse_args(argv)
    summary = run(args.frames, args.measurements, args.seed, args.limit_s, args.detectors)
    print(json.dumps(summary, indent=2))
    return 0 if not any(summary["totals"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
