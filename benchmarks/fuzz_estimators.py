"""Estimator fuzz harness (issue 39): bad inputs on every boundary of every estimator.

    PYTHONPATH=src python benchmarks/fuzz_estimators.py [--cases 2000] [--seed 0] [--limit-s 10]

prints a JSON summary. Each estimator (the platform registry's, the ego EKF, and Kim's UKF on its pixel
path) follows a good stream (a platform at 1.5 m/s seen at 10 Hz with 5 cm noise; a hovering vehicle
with a 200 Hz IMU and 20 Hz odometry; the pad's pixel through the kim_kaist lens at 20 Hz with 1 px
noise, from a vehicle following 10 m above); every case is one bad input on one boundary (a camera
measurement, telemetry fix, clock, query, pixel prediction, IMU sample or batch, odometry,
relocalisation, a first IMU sample or odometry message after ``initialize``, a run of IMU samples after
a clock jump of 2 s to 1e8 s, a pixel, the ego state and ``n_sigma`` of the pixel path, a second of a
false lock: non-numbers, None, strings, complex, wrong shapes, NaN, inf, 1e300, 1e12 m, far-future and
far-past stamps, covariances that are not symmetric positive definite, rotations that are not, absurd
IMU magnitudes and a stretch of 190 g), each call under a watchdog (SIGALRM,
``robustness_harness._call``). After each bad input the estimator gets 5 s of good data.

Counted per estimator: ``crashes`` (an exception other than the documented
:class:`~alight.errors.EstimationError` / ``MeasurementError``; on the pixel path only
``MeasurementError``), ``hangs`` (a call over the limit), ``nan`` (a non-finite state or output after the
bad input), ``wedged`` (after the 5 s of good data, the last second's data were not used or the estimate
is more than 2 m off), ``warnings`` (the bad input's call raised a numpy or Python warning, such as an
overflow on the way to its refusal), ``refused`` (documented refusals or a False return). The test
``tests/estimation/test_estimator_fuzz.py`` runs a short version.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import signal
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from robustness_harness import _call, _on_alarm  # noqa: E402  (the harness's watchdog)

from alight.cameras import CameraMount, MountedCamera  # noqa: E402
from alight.cameras.omni import OmniCamera  # noqa: E402
from alight.errors import MeasurementError  # noqa: E402
from alight.estimation import PLATFORM_ESTIMATORS, EgoEkf, EgoEkfConfig  # noqa: E402
from alight.estimation.ego_ekf import IMU_RUN  # noqa: E402
from alight.estimation.kim_ukf import camera_state_W  # noqa: E402
from alight.types import EgoState, PlatformMeasurement  # noqa: E402

GOOD_S = 5.0
"""Seconds of good data after each bad input."""
MAX_ERROR_M = 2.0
"""An estimate further than this from the truth after the good data is wedged."""

WARMUP_LIMIT_S = 600.0
"""The warm-up's per-call limit (the first calls compile numba kernels)."""

_COV = np.diag([0.05**2] * 3)
_Q0 = np.array([0.0, 0.0, 0.0, 1.0])
_F_HOVER = np.array([0.0, 0.0, 9.81])


def _bad_time(kind: str, now: float) -> Any:
    return {
        "nan": math.nan, "inf": math.inf, "-inf": -math.inf, "none": None, "str": "x", "1e300": 1e300,
        "1e12": 1e12, "future_1e3": now + 1e3, "future_1e6": now + 1e6, "past_50": now - 50.0,
        "past_1e6": now - 1e6, "complex": 1j, "array2": np.array([now, now]), "list": [now],
    }[kind]  # fmt: skip


BAD_TIMES = [
    "nan", "inf", "-inf", "none", "str", "1e300", "1e12", "future_1e3", "future_1e6", "past_50",
    "past_1e6", "complex", "array2", "list",
]  # fmt: skip
BAD_VECTORS: list[tuple[str, Callable[[Any], Any]]] = [
    ("nan", lambda p: [math.nan, 0.0, 0.0]),
    ("inf", lambda p: [math.inf, 0.0, 0.0]),
    ("1e12", lambda p: [1e12, 0.0, 0.0]),
    ("1e300", lambda p: [1e300, 1e300, 0.0]),
    ("complex", lambda p: np.asarray(p) + 1j),
    ("short", lambda p: [0.0, 0.0]),
    ("2d", lambda p: np.zeros((3, 3))),
    ("none", lambda p: None),
    ("str", lambda p: "p"),
    ("outlier_50m", lambda p: np.asarray(p) + [50.0, 0.0, 0.0]),
]
BAD_COVS: list[tuple[str, Callable[[], Any]]] = [
    ("neg", lambda: -_COV),
    ("asym", lambda: _COV + np.array([[0, 1.0, 0], [0, 0, 0], [0, 0, 0]])),
    ("nan", lambda: np.full((3, 3), math.nan)),
    ("inf", lambda: np.diag([math.inf] * 3)),
    ("huge", lambda: np.eye(3) * 1e20),
    ("indefinite", lambda: np.diag([1.0, -1.0, 1.0])),
    ("2x2", lambda: np.eye(2)),
    ("complex", lambda: _COV + 1j),
    ("none", lambda: None),
]


class Counts:
    """The per-estimator counts. ``refusals``: the documented errors (default: the harness's
    ``EstimationError`` and ``ImageError``); any other raised by a bad input's call is a crash."""

    def __init__(self, refusals: tuple[type[BaseException], ...] | None = None) -> None:
        self.c = {"cases": 0, "crashes": 0, "hangs": 0, "nan": 0, "wedged": 0, "warnings": 0, "refused": 0}
        self.examples: list[str] = []
        self.refusals = refusals

    def call(self, kind: str, fn: Callable[[], Any], limit_s: float) -> tuple[str, Any]:
        """The bad input's call under the watchdog; a numpy or Python warning it raises is counted (a
        refusal is clean: no overflow on the way to it)."""
        with warnings.catch_warnings(record=True) as caught, np.errstate(all="warn"):
            warnings.simplefilter("always")
            status, value = _call(fn, limit_s)
        if status == "refused" and self.refusals is not None and not isinstance(value, self.refusals):
            status = "crash"
        if caught:
            self.c["warnings"] += 1
            self.examples.append(f"warning:{kind}:{str(caught[0].message)[:60]}")
        if status == "crash":
            self.c["crashes"] += 1
            self.examples.append(f"crash:{kind}:{type(value).__name__}:{str(value)[:80]}")
        elif status == "hang":
            self.c["hangs"] += 1
            self.examples.append(f"hang:{kind}")
        elif status == "refused" or value is False:
            self.c["refused"] += 1
        return status, value

    def flag(self, what: str, kind: str) -> None:
        self.c[what] += 1
        self.examples.append(f"{what}:{kind}")


def _measurement(t: Any, p: Any, cov: Any) -> PlatformMeasurement:
    """A measurement holding exactly these values (``robustness_harness._measurement`` makes arrays of
    them): past the constructor's checks, as a buggy upstream block could."""
    m = object.__new__(PlatformMeasurement)
    for f in PlatformMeasurement.__dataclass_fields__:
        object.__setattr__(m, f, None)
    for k, v in {"t": t, "p_WP": p, "cov_p_WP": cov}.items():
        object.__setattr__(m, k, v)
    return m


def _finite(*arrays: Any) -> bool:
    return all(np.isfinite(np.asarray(a, dtype=np.float64)).all() for a in arrays)


# ---- platform estimators ------------------------------------------------------------------------------


def _truth(t: float) -> Any:
    return np.array([1.5 * t, 0.0, 0.5])


def _ego_at(t: float, p: Any) -> EgoState:
    return EgoState(t=t, p_WB=p + [0.0, 0.0, 10.0], v_WB=np.zeros(3), q_WB=_Q0, w_WB_B=np.zeros(3))


def _platform_case(est: Any, kind: str, t: float, rng: np.random.Generator) -> Callable[[], Any]:
    """One bad input at time ``t`` (the good stream's clock) as a call."""
    where, _, what = kind.partition(":")
    p, cov = _truth(t), _COV
    if where == "meas_t":
        return partial(est.update, _measurement(_bad_time(what, t), p, cov))
    if where == "meas_p":
        make = dict(BAD_VECTORS)[what]
        return partial(est.update, _measurement(t, make(p), cov))
    if where == "meas_cov":
        return partial(est.update, _measurement(t, p, dict(BAD_COVS)[what]()))
    if where == "predict":
        return partial(est.predict, _bad_time(what, t))
    if where == "state":
        return partial(est.state, _bad_time(what, t))
    if where == "ahead":
        return partial(est.predict_ahead, _bad_times_array(what, t))
    if where == "telemetry_t":
        return partial(est.update_telemetry, _bad_time(what, t), p, np.array([1.5, 0, 0]), cov)
    if where == "telemetry_p":
        return partial(est.update_telemetry, t, dict(BAD_VECTORS)[what](p), np.array([1.5, 0, 0]), cov)
    if where == "telemetry_v":
        return partial(est.update_telemetry, t, p, dict(BAD_VECTORS)[what]([1.5, 0, 0]), cov)
    if where == "telemetry_cov":
        return partial(est.update_telemetry, t, p, np.array([1.5, 0, 0]), dict(BAD_COVS)[what]())
    if where == "pixel":
        return partial(est.predict_pixel, _bad_time(what, t), _ego_at(t, p))
    raise ValueError(kind)


def _bad_times_array(kind: str, t: float) -> Any:
    return {
        "nan": [math.nan], "inf": [t, math.inf], "2d": np.full((2, 2), t), "str": ["a"], "1e300": [1e300],
        "none": None, "complex": [t + 1j], "far": [t + 1e7, t - 1e7], "empty": [],
    }[kind]  # fmt: skip


def platform_kinds(est: Any) -> list[str]:
    kinds = [f"meas_t:{k}" for k in BAD_TIMES]
    kinds += [f"meas_p:{k}" for k, _ in BAD_VECTORS] + [f"meas_cov:{k}" for k, _ in BAD_COVS]
    kinds += [f"predict:{k}" for k in BAD_TIMES] + [f"state:{k}" for k in BAD_TIMES]
    kinds += [f"ahead:{k}" for k in ("nan", "inf", "2d", "str", "1e300", "none", "complex", "far", "empty")]
    if hasattr(est, "update_telemetry"):
        kinds += [f"telemetry_t:{k}" for k in BAD_TIMES] + [f"telemetry_cov:{k}" for k, _ in BAD_COVS]
        kinds += [f"telemetry_p:{k}" for k, _ in BAD_VECTORS] + [f"telemetry_v:{k}" for k, _ in BAD_VECTORS]
    if hasattr(est, "predict_pixel"):
        kinds += [f"pixel:{k}" for k in BAD_TIMES]
    return kinds


def _platform_good(est: Any, t: float, rng: np.random.Generator, seconds: float, limit_s: float) -> tuple:
    """``seconds`` of good measurements from ``t``; the new time, and whether any of the last second's
    were used."""
    used_late = False
    n = int(round(seconds / 0.1))
    for i in range(n):
        t += 0.1
        _call(partial(est.predict, t), limit_s)
        status, value = _call(
            partial(est.update, _measurement(t, _truth(t) + rng.normal(0, 0.05, 3), _COV)), limit_s
        )
        if i >= n - 10 and status == "ok" and value is True:
            used_late = True
    return t, used_late


def run_platform(name: str, n_cases: int, seed: int, limit_s: float) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    est = PLATFORM_ESTIMATORS[name].build_default(MountedCamera(camera=None, mount=CameraMount.downward()))
    counts = Counts()
    kinds = platform_kinds(est)
    # a track first, without the watchdog's limit: numba compiles the kernels on first use
    t, _ = _platform_good(est, 0.0, rng, 2.0, WARMUP_LIMIT_S)
    _call(partial(est.predict_ahead, [t, t + 1.0]), WARMUP_LIMIT_S)
    if hasattr(est, "update_telemetry"):
        _call(partial(est.update_telemetry, t, _truth(t), np.array([1.5, 0, 0]), _COV), WARMUP_LIMIT_S)
    t0 = time.perf_counter()
    for i in range(n_cases):
        kind = kinds[int(rng.integers(len(kinds)))] if i >= len(kinds) else kinds[i]
        counts.c["cases"] += 1
        t += 0.05
        status, value = counts.call(kind, _platform_case(est, kind, t, rng), limit_s)
        st_status, st = _call(partial(est.state, t), limit_s)
        if st_status == "ok" and not _finite(st.p_WP, st.v_WP, st.cov_p_WP):
            counts.flag("nan", kind)
        elif status == "ok" and isinstance(value, tuple) and not _finite(*value[:2]):  # outputs
            counts.flag("nan", kind)
        t, used_late = _platform_good(est, t, rng, GOOD_S, limit_s)
        st_status, st = _call(partial(est.state, t), limit_s)
        off = st_status != "ok" or not float(np.linalg.norm(st.p_WP - _truth(t))) <= MAX_ERROR_M
        if not used_late or off:
            counts.flag("wedged", kind)
    return {**counts.c, "wall_s": round(time.perf_counter() - t0, 1), "examples": counts.examples[:8]}


# ---- Kim's UKF on pixels (paper 003's path) --------------------------------------------------------

_PIXEL_OFFSET = np.array([1.0, 0.5, 10.0])
"""The vehicle follows the target at this offset (m, W): the target stays in view, off the centre."""


class _PixelEgo:
    """What :meth:`KimUkf.update_pixel` reads of an ego state, holding whatever values a case gives."""

    def __init__(self, p: Any, v: Any, R: Any) -> None:
        self.p_WB, self.v_WB, self.R_WB = p, v, R


def _pixel_ego(t: float) -> _PixelEgo:
    return _PixelEgo(_truth(t) + _PIXEL_OFFSET, np.array([1.5, 0.0, 0.0]), np.eye(3))


def _true_pixel(est: Any, t: float) -> Any:
    """The target's pixel from the vehicle at ``t`` through the filter's own lens."""
    p_WC, R_WC, _ = camera_state_W(_pixel_ego(t), est.mount)
    return est.lens.project_exact((R_WC.T @ (_truth(t) - p_WC))[None])[0]


def _bad_ego(what: str, t: float) -> Any:
    good = _pixel_ego(t)
    p, v, R = good.p_WB, good.v_WB, good.R_WB
    return {
        "p_nan": _PixelEgo([math.nan, 0, 10], v, R), "p_1e300": _PixelEgo([1e300, 0, 1e300], v, R),
        "p_short": _PixelEgo([0.0, 10.0], v, R), "p_str": _PixelEgo("p", v, R),
        "p_complex": _PixelEgo(p + 1j, v, R), "below_deck": _PixelEgo(p * [1, 1, -1], v, R),
        "v_nan": _PixelEgo(p, [math.nan, 0, 0], R), "v_1e300": _PixelEgo(p, [1e300, 0, 0], R),
        "v_none": _PixelEgo(p, None, R), "R_zero": _PixelEgo(p, v, np.zeros((3, 3))),
        "R_1e300": _PixelEgo(p, v, np.eye(3) * 1e300), "R_nan": _PixelEgo(p, v, np.full((3, 3), math.nan)),
        "R_2x2": _PixelEgo(p, v, np.eye(2)), "R_none": _PixelEgo(p, v, None), "none": None, "str": "ego",
    }[what]  # fmt: skip


PIXEL_EGOS = [
    "p_nan", "p_1e300", "p_short", "p_str", "p_complex", "below_deck", "v_nan", "v_1e300", "v_none",
    "R_zero", "R_1e300", "R_nan", "R_2x2", "R_none", "none", "str",
]  # fmt: skip
PIXEL_VALUES: list[tuple[str, Callable[[Any], Any]]] = [
    ("nan", lambda z: [math.nan, z[1]]), ("inf", lambda z: [math.inf, z[1]]),
    ("1e300", lambda z: [1e300, 1e300]),
    ("1e12", lambda z: [1e12, 0.0]), ("negative", lambda z: [-1e4, -1e4]), ("complex", lambda z: z + 1j),
    ("short", lambda z: z[:1]), ("three", lambda z: [*z, 0.0]), ("2d", lambda z: np.zeros((2, 2))),
    ("none", lambda z: None), ("str", lambda z: "px"), ("off_150px", lambda z: z + [150.0, 0.0]),
]  # fmt: skip
PIXEL_KINDS = (
    [f"px_t:{k}" for k in BAD_TIMES]
    + [f"px_z:{k}" for k, _ in PIXEL_VALUES]
    + [f"px_ego:{k}" for k in PIXEL_EGOS]
    + [f"pred_t:{k}" for k in BAD_TIMES]
    + [f"pred_ego:{k}" for k in PIXEL_EGOS]
    + [f"pred_sigma:{k}" for k in ("nan", "inf", "-1", "1e300", "str", "none")]
    + [f"lock:{k}" for k in ("off_150px_1s", "off_40px_1s", "still_1s")]
)


def _pixel_case(est: Any, kind: str, t: float) -> Callable[[], Any]:
    where, _, what = kind.partition(":")
    z = _true_pixel(est, t)
    if where == "px_t":
        return partial(est.update_pixel, _bad_time(what, t), z, _pixel_ego(t))
    if where == "px_z":
        return partial(est.update_pixel, t, dict(PIXEL_VALUES)[what](z), _pixel_ego(t))
    if where == "px_ego":
        return partial(est.update_pixel, t, z, _bad_ego(what, t))
    if where == "pred_t":
        return partial(est.predict_pixel, _bad_time(what, t), _pixel_ego(t))
    if where == "pred_ego":
        return partial(est.predict_pixel, t, _bad_ego(what, t))
    if where == "pred_sigma":
        n_sigma = {"nan": math.nan, "inf": math.inf, "-1": -1.0, "1e300": 1e300, "str": "3", "none": None}
        return partial(est.predict_pixel, t, _pixel_ego(t), n_sigma[what])
    if where == "lock":
        return partial(_false_lock, est, what, t)
    raise ValueError(kind)


def _false_lock(est: Any, what: str, t: float) -> None:
    """A second of consistent wrong pixels at 20 Hz (a distractor the detector locked on): offset from the
    target, or a target that stopped while the vehicle flies on."""
    for k in range(20):
        tk = t + 0.05 * k
        est.predict(tk)
        z = _true_pixel(est, t if what == "still_1s" else tk)
        z = z + {"off_150px_1s": [150.0, 0.0], "off_40px_1s": [0.0, 40.0]}.get(what, [0.0, 0.0])
        est.update_pixel(tk, z, _pixel_ego(tk))


def _pixel_good(est: Any, t: float, rng: np.random.Generator, seconds: float, limit_s: float) -> tuple:
    """``seconds`` of good pixels at 20 Hz (1 px noise) from ``t``, each after the detector's
    prediction; the new time, and whether any of the last second's were used."""
    used_late = False
    n = int(round(seconds / 0.05))
    for i in range(n):
        t += 0.05
        _call(partial(est.predict, t), limit_s)
        _call(partial(est.predict_pixel, t, _pixel_ego(t)), limit_s)
        z = _true_pixel(est, t) + rng.normal(0, 1.0, 2)
        status, value = _call(partial(est.update_pixel, t, z, _pixel_ego(t)), limit_s)
        used_late |= i >= n - 20 and status == "ok" and value is True
    return t, used_late


def _pixel_output_finite(value: Any) -> bool:
    if value is None or value is False or value is True:
        return True
    zhat, radius = value
    return _finite(zhat) and math.isfinite(radius) and radius > 0


def run_kim_pixel(n_cases: int, seed: int, limit_s: float) -> dict[str, Any]:
    """Kim's UKF with the kim_kaist lens (a synthetic 186 deg fisheye) on its pixel path: ``update_pixel``
    and ``predict_pixel``, each bad input followed by 5 s of good pixels. A refusal is a False return or
    a :class:`~alight.errors.MeasurementError` (any other error, ``EstimationError`` included, counts)."""
    rng = np.random.default_rng(seed)
    lens = OmniCamera.synthetic(640, 480, fov_deg=186.0)
    spec = PLATFORM_ESTIMATORS["kim_ukf"]
    # the kim_kaist flight's values: the quartic lens model, a track confirmed by 5 updates
    params = replace(spec.default_params(), measurement_model="quartic", confirm_updates=5)
    est = spec.build(params, MountedCamera(camera=lens, mount=CameraMount.downward()))
    counts = Counts(refusals=(MeasurementError,))
    t, _ = _pixel_good(est, 0.0, rng, 2.0, WARMUP_LIMIT_S)  # numba compiles on first use
    t0 = time.perf_counter()
    for i in range(n_cases):
        kind = PIXEL_KINDS[int(rng.integers(len(PIXEL_KINDS)))] if i >= len(PIXEL_KINDS) else PIXEL_KINDS[i]
        counts.c["cases"] += 1
        t += 0.05
        _call(partial(est.predict, t), limit_s)
        status, value = counts.call(kind, _pixel_case(est, kind, t), limit_s)
        if kind.startswith("lock:"):
            t += 1.0
        st_status, st = _call(partial(est.state, t), limit_s)
        if st_status == "ok" and not _finite(st.p_WP, st.v_WP, st.cov_p_WP):
            counts.flag("nan", kind)
        elif status == "ok" and not _pixel_output_finite(value):
            counts.flag("nan", kind)
        t, used_late = _pixel_good(est, t, rng, GOOD_S, limit_s)
        st_status, st = _call(partial(est.state, t), limit_s)
        off = st_status != "ok" or not float(np.linalg.norm(st.p_WP[:2] - _truth(t)[:2])) <= MAX_ERROR_M
        if not used_late or off:
            counts.flag("wedged", kind)
    return {**counts.c, "wall_s": round(time.perf_counter() - t0, 1), "examples": counts.examples[:8]}


# ---- the ego EKF ---------------------------------------------------------------------------------------

EGO_KINDS = (
    [f"imu_t:{k}" for k in BAD_TIMES]
    + [f"imu_f:{k}" for k in ("nan", "inf", "1e12", "1e300", "complex", "short", "2d", "none", "str")]
    + [f"imu_w:{k}" for k in ("nan", "1e3", "1e300", "complex", "none")]
    + [f"many:{k}" for k in ("list", "2d", "n_too_big", "nan_mid", "future_mid", "past_mid", "str", "1e300")]
    + [f"odo_t:{k}" for k in BAD_TIMES]
    + [f"odo_p:{k}" for k, _ in BAD_VECTORS]
    + [f"odo_q:{k}" for k in ("zero", "nan", "huge", "short", "complex")]
    + [f"odo_v:{k}" for k in ("nan", "1e6", "complex")]
    + [f"reloc_t:{k}" for k in BAD_TIMES]
    + [f"reloc_p:{k}" for k, _ in BAD_VECTORS if k != "outlier_50m"]
    + ["stretch:190g_1s", "stretch:spin_90rads_1s", "stretch:gap_1000s"]
    + [f"first_imu:{k}" for k in ("future_1e3", "future_1e6", "1e300", "inf", "nan", "past_50", "str")]
    + [f"first_odo:{k}" for k in ("future_1e3", "future_1e6", "1e12")]
    + [f"jump_run:{k}" for k in ("2", "1e3", "1e6", "1e8")]
    + [f"first_run:{k}" for k in ("1e3", "1e6")]
    + [f"reloc_q:{k}" for k in ("1e300", "zero", "nan")]
    + [f"reloc_v:{k}" for k in ("1e300", "1e6", "nan")]
)


def _bad_quat(kind: str) -> Any:
    return {
        "zero": np.zeros(4), "nan": [math.nan, 0, 0, 1], "huge": [0, 0, 0, 1e6], "short": [0, 0, 1],
        "complex": _Q0 + 1j,
    }[kind]  # fmt: skip


def _imu_block(t: float, n: int) -> tuple[Any, Any, Any]:
    return t + 0.005 * np.arange(1, n + 1), np.tile(_F_HOVER, (n, 1)), np.zeros((n, 3))


def _many_case(ekf: EgoEkf, what: str, t: float) -> Callable[[], Any]:
    ts, fs, ws = _imu_block(t, 10)
    if what == "list":
        return partial(ekf.predict_imu_many, ts.tolist(), fs, ws)
    if what == "2d":
        return partial(ekf.predict_imu_many, ts[None, :], fs, ws)
    if what == "n_too_big":
        return partial(ekf.predict_imu_many, ts, fs[:3], ws[:3], 10)
    if what == "str":
        return partial(ekf.predict_imu_many, ["a"] * 10, fs, ws)
    if what == "nan_mid":
        fs[4, 0] = math.nan
    elif what == "future_mid":
        ts[5:] += 1e3
    elif what == "past_mid":
        ts[5:] -= 1.0
    elif what == "1e300":
        ts[3] = 1e300
    return partial(ekf.predict_imu_many, ts, fs, ws)


def _stretch(ekf: EgoEkf, what: str, t: float) -> Callable[[], Any]:
    """A plausible-looking but absurd stretch of IMU samples (within the per-sample bounds)."""

    def go() -> None:
        if what == "gap_1000s":
            ekf.predict_imu(t + 1000.0, _F_HOVER, np.zeros(3))
            return
        ts, fs, ws = _imu_block(t, 200)
        if what == "190g_1s":
            fs[:] = [1860.0, 0.0, 9.81]
        else:
            ws[:] = [90.0, 0.0, 0.0]
        ekf.predict_imu_many(ts, fs, ws)

    return go


def _restarted(ekf: EgoEkf, t: float) -> None:
    """The filter initialised again at ``t`` from its own estimate: the next IMU sample is its first."""
    s = ekf.state()
    ekf.initialize(t, s.p_WB, s.v_WB, s.q_WB)


def _first_case(ekf: EgoEkf, where: str, what: str, t: float) -> Callable[[], Any]:
    """A bad first sample or message after :meth:`EgoEkf.initialize` (``first_*``), or a run of
    ``IMU_RUN`` samples in order after a jump of the clock (``*_run``): the filter may believe the run,
    and must then go on from it."""

    def go() -> Any:
        if where != "jump_run":
            _restarted(ekf, t)
        if where == "first_imu":
            return ekf.predict_imu(_bad_time(what, t), _F_HOVER, np.zeros(3))
        if where == "first_odo":
            t_odo = 1e12 if what == "1e12" else _bad_time(what, t)
            return ekf.update_odometry(t_odo, np.zeros(3), _Q0)
        jump = float(what)
        for k in range(IMU_RUN):  # all but the last refused, unless the jump is within the tolerance
            with contextlib.suppress(MeasurementError):
                ekf.predict_imu(t + jump + 0.005 * k, _F_HOVER, np.zeros(3))
        return None

    return go


def _ego_case(ekf: EgoEkf, kind: str, t: float) -> Callable[[], Any]:
    where, _, what = kind.partition(":")
    if where.startswith("first_") or where.endswith("_run"):
        return _first_case(ekf, where, what, t)
    if where in ("reloc_q", "reloc_v"):
        bad = {"1e300": [1e300, 0.0, 0.0], "1e6": [1e6, 0.0, 0.0], "zero": [0.0] * 3, "nan": [math.nan] * 3}
        if where == "reloc_q":
            return partial(
                ekf.relocalize, t, np.zeros(3), np.array([*bad[what], 1.0 if what != "zero" else 0.0])
            )
        return partial(ekf.relocalize, t, np.zeros(3), _Q0, bad[what])
    dt = t + 0.005
    if where == "imu_t":
        return partial(ekf.predict_imu, _bad_time(what, t), _F_HOVER, np.zeros(3))
    if where == "imu_f":
        f = {"1e12": [1e12, 0, 0], "1e300": [1e300, 0, 0]}.get(what) or dict(BAD_VECTORS)[what](_F_HOVER)
        return partial(ekf.predict_imu, dt, f, np.zeros(3))
    if where == "imu_w":
        w = {"1e3": [1e3, 0, 0], "1e300": [0, 1e300, 0]}.get(what) or dict(BAD_VECTORS)[what](np.zeros(3))
        return partial(ekf.predict_imu, dt, _F_HOVER, w)
    if where == "many":
        return _many_case(ekf, what, t)
    if where == "odo_t":
        return partial(ekf.update_odometry, _bad_time(what, t), np.zeros(3), _Q0)
    if where == "odo_p":
        return partial(ekf.update_odometry, t, dict(BAD_VECTORS)[what](np.zeros(3)), _Q0)
    if where == "odo_q":
        return partial(ekf.update_odometry, t, np.zeros(3), _bad_quat(what))
    if where == "odo_v":
        v = {"1e6": [1e6, 0, 0]}.get(what) or dict(BAD_VECTORS)[what](np.zeros(3))
        return partial(ekf.update_odometry, t, np.zeros(3), _Q0, v)
    if where == "reloc_t":
        return partial(ekf.relocalize, _bad_time(what, t), np.zeros(3), _Q0)
    if where == "reloc_p":
        return partial(ekf.relocalize, t, dict(BAD_VECTORS)[what](np.zeros(3)), _Q0)
    if where == "stretch":
        return _stretch(ekf, what, t)
    raise ValueError(kind)


def _ego_good(ekf: EgoEkf, rng: np.random.Generator, seconds: float, limit_s: float) -> bool:
    """``seconds`` of a hovering vehicle at the origin from the filter time (20 Hz odometry between 10
    IMU samples); whether any odometry of the last second was fused."""
    used_late = False
    n = int(round(seconds * 20))
    for i in range(n):
        t = ekf.t
        _call(partial(ekf.predict_imu_many, *_imu_block(t, 10)), limit_s)
        status, value = _call(
            partial(ekf.update_odometry, ekf.t, rng.normal(0, 0.01, 3), _Q0, np.zeros(3)), limit_s
        )
        used_late |= i >= n - 20 and status == "ok" and value is True
    return used_late


def run_ego(n_cases: int, seed: int, limit_s: float) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    ekf = EgoEkf(EgoEkfConfig())
    ekf.initialize(0.0, np.zeros(3), np.zeros(3), _Q0)
    _ego_good(ekf, rng, 1.0, WARMUP_LIMIT_S)  # numba compiles on first use: no watchdog's limit
    counts = Counts()
    t0 = time.perf_counter()
    for i in range(n_cases):
        kind = EGO_KINDS[int(rng.integers(len(EGO_KINDS)))] if i >= len(EGO_KINDS) else EGO_KINDS[i]
        counts.c["cases"] += 1
        counts.call(kind, _ego_case(ekf, kind, ekf.t), limit_s)
        s = ekf.state()
        if not _finite(s.p_WB, s.v_WB, s.q_WB, ekf.covariance):
            counts.flag("nan", kind)
        used_late = _ego_good(ekf, rng, GOOD_S, limit_s)
        off = not float(np.linalg.norm(ekf.state().p_WB)) <= MAX_ERROR_M
        if not used_late or off or not _finite(ekf.nominal, ekf.covariance):
            counts.flag("wedged", kind)
    return {**counts.c, "wall_s": round(time.perf_counter() - t0, 1), "examples": counts.examples[:8]}


def run(n_cases: int = 2000, seed: int = 0, limit_s: float = 10.0) -> dict[str, Any]:
    """The whole harness; the JSON summary as a dict."""
    signal.signal(signal.SIGALRM, _on_alarm)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        # the good data's calls; a bad input's own call counts its warnings (Counts.call)
        warnings.simplefilter("ignore")
        return _run(n_cases, seed, limit_s)


def _run(n_cases: int, seed: int, limit_s: float) -> dict[str, Any]:
    t0 = time.perf_counter()
    per: dict[str, Any] = {
        name: run_platform(name, n_cases, seed, limit_s) for name in sorted(PLATFORM_ESTIMATORS)
    }
    per["ego_ekf"] = run_ego(n_cases, seed, limit_s)
    per["kim_ukf_pixel"] = run_kim_pixel(n_cases, seed, limit_s)
    totals = {
        k: sum(int(b[k]) for b in per.values()) for k in ("crashes", "hangs", "nan", "wedged", "warnings")
    }
    return {
        "cases_per_estimator": n_cases,
        "seed": seed,
        "per_call_limit_s": limit_s,
        "estimators": per,
        "totals": totals,
        "wall_s": round(time.perf_counter() - t0, 1),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=2000, help="bad inputs per estimator")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--limit-s", type=float, default=10.0, help="watchdog per call (s)")
    args = parser.parse_args(argv)
    summary = run(args.cases, args.seed, args.limit_s)
    print(json.dumps(summary, indent=2))
    return 0 if not any(summary["totals"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
