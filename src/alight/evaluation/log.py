"""The per-mission log: time series of truth, estimates, commands and mode, recorded at a fixed rate.

The runner calls :meth:`MissionLog.append` once per logging tick (e.g. 50 Hz) and
:meth:`MissionLog.add_detection` for every geolocated platform measurement; :meth:`MissionLog.finalize`
turns the record into plain numpy arrays and :meth:`MissionLog.save` writes ``log.npz`` (compressed),
``log.csv`` (one row per sample) and ``log_detections.csv`` (one row per detection).

Channels (all float64, NaN where a channel was not given in an append; N samples, M detections):

==================  ========  ===========================================================
name                shape     meaning
==================  ========  ===========================================================
``t``               (N,)      simulated time (s)
``p_WB, v_WB``      (N, 3)    vehicle position (m) / velocity (m/s) in W, ground truth
``p_WB_est``        (N, 3)    vehicle position from the ego estimator (m)
``v_WB_est``        (N, 3)    vehicle velocity from the ego estimator (m/s)
``q_WB``            (N, 4)    vehicle attitude, ground truth, quaternion (x, y, z, w) as SciPy stores it
``q_WB_est``        (N, 4)    vehicle attitude from the ego estimator, quaternion (x, y, z, w)
``p_WP, v_WP``      (N, 3)    platform (pad centre) position / velocity in W, ground truth
``p_WP_est``        (N, 3)    platform position from the platform estimator (NaN when none)
``v_WP_est``        (N, 3)    platform velocity from the platform estimator (NaN when none)
``p_ref, v_ref``    (N, 3)    reference position / velocity handed to the controller
``thrust_N``        (N,)      commanded collective thrust (N)
``w_cmd``           (N, 3)    commanded body rates, expressed in B (rad/s)
``w_WB_B``          (N, 3)    true body rates, expressed in B (rad/s)
``range_m``         (N,)      range-finder reading (m), NaN when none
``f_wind_W``        (N, 3)    wind force on the centre of mass, in W (N)
``motor_N``         (N, 4)    motor thrusts (N)
``mode``            (N,)      mission mode as a short string ('' when not given)
``t_det``           (M,)      capture time of each platform measurement (s)
``p_WP_meas``       (M, 3)    geolocated platform position of each measurement, in W (m)
==================  ========  ===========================================================

The log is an evaluation artefact: it may read ground truth, and it does file I/O.
"""

from __future__ import annotations

import csv
import enum
import math
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from alight.errors import InputError

FloatArray = NDArray[np.float64]

CHANNELS: dict[str, int] = {
    "p_WB": 3,
    "v_WB": 3,
    "p_WB_est": 3,
    "v_WB_est": 3,
    "q_WB": 4,
    "q_WB_est": 4,
    "p_WP": 3,
    "v_WP": 3,
    "p_WP_est": 3,
    "v_WP_est": 3,
    "p_ref": 3,
    "v_ref": 3,
    "thrust_N": 1,
    "w_cmd": 3,
    "w_WB_B": 3,
    "range_m": 1,
    "f_wind_W": 3,
    "motor_N": 4,
}
"""The standard numeric channels and their width (1 means a scalar per sample)."""

LOG_NPZ = "log.npz"
LOG_CSV = "log.csv"
DETECTIONS_CSV = "log_detections.csv"

_INITIAL_CAPACITY = 1024
_XYZ = ("x", "y", "z")
_XYZW = ("x", "y", "z", "w")


def log_channel(log: Mapping[str, np.ndarray], name: str, width: int) -> NDArray[np.float64]:
    """Channel ``name`` of a finalised mission log as an (N, width) float64 array, all NaN when the log
    does not have it (a channel a preset never fills); N is the length of ``log["t"]``."""
    n = np.asarray(log["t"]).shape[0]
    a = log.get(name)
    return np.full((n, width), np.nan) if a is None else np.asarray(a, dtype=np.float64).reshape(n, width)


def column_names(name: str, width: int) -> list[str]:
    """CSV column names of a channel: ``p_WB -> p_WB_x, p_WB_y, p_WB_z``; a quaternion ``q_WB -> q_WB_x,
    q_WB_y, q_WB_z, q_WB_w``; ``motor_N -> motor_N_0 ..``."""
    if width == 1:
        return [name]
    if width == 3:
        return [f"{name}_{a}" for a in _XYZ]
    if width == 4 and name.startswith("q_"):
        return [f"{name}_{a}" for a in _XYZW]
    return [f"{name}_{i}" for i in range(width)]


class MissionLog:
    """Recorder of one mission's time series, backed by one preallocated, growing float64 buffer.

    Every sample is a row of a ``(capacity, n_columns)`` array that starts as NaN, so a channel that an
    append leaves out costs nothing and reads back as NaN. The buffer doubles when full, which keeps
    the amortised cost of an append at a handful of numpy slice assignments.

    Args:
        capacity: initial number of samples to allocate room for (grows as needed).
        extra_channels: further numeric channels, name -> width (1 for a scalar), beyond
            :data:`CHANNELS`; they are logged, saved and loaded like the standard ones.
    """

    def __init__(self, capacity: int = _INITIAL_CAPACITY, extra_channels: Mapping[str, int] | None = None):
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        widths = dict(CHANNELS)
        for name, width in (extra_channels or {}).items():
            if name in widths or name in ("t", "mode", "t_det", "p_WP_meas"):
                raise ValueError(f"extra channel {name!r} clashes with a standard channel")
            if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
                raise ValueError(f"extra channel name {name!r} must be an identifier")
            if int(width) < 1:
                raise ValueError(f"extra channel {name!r} must have width >= 1, got {width}")
            widths[name] = int(width)
        self._widths = widths
        # Column 0 is t; then each channel's columns in order. A scalar channel gets an int index
        # (row[i] = x), a vector channel a slice (row[a:b] = v): both are single numpy setitems.
        self._index: dict[str, int | slice] = {}
        col = 1
        for name, width in widths.items():
            self._index[name] = col if width == 1 else slice(col, col + width)
            col += width
        self._n_cols = col
        self._scalar = {k: j for k, j in self._index.items() if type(j) is int}
        self._vec = {k: (j, widths[k]) for k, j in self._index.items() if type(j) is slice}
        self._buf = np.full((capacity, col), np.nan)
        self._n = 0
        # Modes are interned to small integer codes: a dict lookup per append instead of a string array.
        self._t_last = -math.inf
        self._mode_codes: dict[object, int] = {"": 0}
        self._mode_names: list[str] = [""]
        self._mode = np.zeros(capacity, dtype=np.int32)
        self._det = np.full((64, 4), np.nan)
        self._n_det = 0

    # ---------------------------------------------------------------------------------------------
    # recording
    # ---------------------------------------------------------------------------------------------

    @property
    def channels(self) -> dict[str, int]:
        """Numeric channels of this log (name -> width), standard ones first."""
        return dict(self._widths)

    def __len__(self) -> int:
        return self._n

    @property
    def n_detections(self) -> int:
        return self._n_det

    def _grow(self) -> None:
        cap = self._buf.shape[0]
        buf = np.full((2 * cap, self._n_cols), np.nan)
        buf[:cap] = self._buf
        self._buf = buf
        mode = np.zeros(2 * cap, dtype=np.int32)
        mode[:cap] = self._mode
        self._mode = mode

    def append(self, t: float, mode: str | None = None, **channels: object) -> None:
        """Record one sample at time ``t`` (s).

        Args:
            t: simulated time (s); must not decrease from one append to the next.
            mode: the mission mode (a string or a ``str`` enum such as :class:`alight.types.Mode`).
            **channels: any of :data:`CHANNELS` (and the extra channels), each a float or an
                array-like of the channel's width. ``None`` or a left-out channel is stored as NaN.

        Raises:
            ValueError: unknown channel, a value of the wrong size, or time going backwards.
        """
        i = self._n
        if i == self._buf.shape[0]:
            self._grow()
        row = self._buf[i]
        t = float(t)
        if not (t >= self._t_last and math.isfinite(t)):
            raise ValueError(f"log time must be finite and not decrease: t={t} after t={self._t_last}")
        row[0] = t
        vec = self._vec
        try:
            for name, value in channels.items():
                if value is None:
                    continue
                j = vec.get(name)
                if j is None:
                    row[self._scalar[name]] = value
                # Without the length check numpy would broadcast a scalar over a vector channel.
                elif len(value) == j[1]:  # type: ignore[arg-type]
                    row[j[0]] = value
                else:
                    raise ValueError
        except (KeyError, TypeError, ValueError):
            row[:] = np.nan  # the sample is not committed; leave the row clean for the next append
            self._raise_bad_channel(channels)
        if mode is not None:
            # Keyed by the object given (a str or a Mode member), so the common case is one dict hit.
            code = self._mode_codes.get(mode)
            if code is None:
                code = self._intern_mode(mode.value if isinstance(mode, enum.Enum) else str(mode))
                self._mode_codes[mode] = code
            self._mode[i] = code
        self._t_last = t
        self._n = i + 1

    def _raise_bad_channel(self, channels: Mapping[str, object]) -> None:
        """Find the channel that made an append fail and raise a ValueError naming it."""
        for name, value in channels.items():
            if value is None:
                continue
            if name not in self._index:
                known = ", ".join(self._index)
                raise ValueError(f"unknown log channel {name!r}; known: {known}")
            width = self._widths[name]
            a = np.asarray(value, dtype=object)
            if (width == 1 and a.ndim != 0) or (width > 1 and a.shape != (width,)):
                raise ValueError(f"log channel {name!r} needs {width} value(s), got shape {a.shape}")
            try:
                np.asarray(value, dtype=np.float64)
            except (TypeError, ValueError):
                raise ValueError(f"log channel {name!r}: not numeric: {value!r}") from None
        raise ValueError(f"cannot log channels {sorted(channels)}")

    def _intern_mode(self, m: str) -> int:
        code = self._mode_codes.get(m)
        if code is None:
            code = len(self._mode_names)
            self._mode_codes[m] = code
            self._mode_names.append(m)
        return code

    def add_detection(self, t: float, p_WP_meas: object) -> None:
        """Record one geolocated platform measurement: capture time ``t`` (s), position in W (m), (3,)."""
        p = np.asarray(p_WP_meas, dtype=np.float64)
        if p.shape != (3,):
            raise ValueError(f"p_WP_meas must have shape (3,), got {p.shape}")
        if self._n_det == self._det.shape[0]:
            det = np.full((2 * self._n_det, 4), np.nan)
            det[: self._n_det] = self._det
            self._det = det
        self._det[self._n_det, 0] = float(t)
        self._det[self._n_det, 1:] = p
        self._n_det += 1

    # ---------------------------------------------------------------------------------------------
    # output
    # ---------------------------------------------------------------------------------------------

    def finalize(self) -> dict[str, np.ndarray]:
        """The record as arrays (copies; the log can keep recording). See the module docstring for keys."""
        n = self._n
        out: dict[str, np.ndarray] = {"t": self._buf[:n, 0].copy()}
        for name, j in self._index.items():
            out[name] = self._buf[:n, j].copy()
        names = np.array(self._mode_names, dtype=np.str_)
        out["mode"] = names[self._mode[:n]]
        det = self._det[: self._n_det]
        out["t_det"] = det[:, 0].copy()
        out["p_WP_meas"] = det[:, 1:].copy()
        return out

    def save(self, out_dir: str | Path) -> dict[str, Path]:
        """Write ``log.npz``, ``log.csv`` and ``log_detections.csv`` into ``out_dir`` (created if needed).

        Returns:
            The paths written, keyed ``npz``, ``csv``, ``detections_csv``.
        """
        return save_arrays(self.finalize(), out_dir, channels=self._widths)

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> MissionLog:
        """Rebuild a log from :meth:`finalize` output (non-standard numeric keys become extra channels)."""
        t = np.asarray(arrays["t"], dtype=np.float64)
        n = t.shape[0]
        extra: dict[str, int] = {}
        for key, value in arrays.items():
            if key in CHANNELS or key in ("t", "mode", "t_det", "p_WP_meas"):
                continue
            a = np.asarray(value)
            if a.ndim not in (1, 2) or a.shape[0] != n:
                raise InputError(f"log array {key!r} has shape {a.shape}, expected ({n}, ...)")
            extra[key] = 1 if a.ndim == 1 else a.shape[1]
        log = cls(capacity=max(n, 1), extra_channels=extra)
        log._buf[:n, 0] = t
        for name, j in log._index.items():
            if name in arrays:
                a = np.asarray(arrays[name], dtype=np.float64)
                expected = (n,) if type(j) is int else (n, j.stop - j.start)  # type: ignore[union-attr]
                if a.shape != expected:
                    raise InputError(f"log array {name!r} has shape {a.shape}, expected {expected}")
                log._buf[:n, j] = a
        if "mode" in arrays:
            modes = np.asarray(arrays["mode"]).astype(str)
            if modes.shape != (n,):
                raise InputError(f"log array 'mode' has shape {modes.shape}, expected ({n},)")
            for k, m in enumerate(modes.tolist()):
                log._mode[k] = log._intern_mode(m)
        log._n = n
        t_det = np.asarray(arrays.get("t_det", np.zeros(0)), dtype=np.float64).reshape(-1)
        p_meas = np.asarray(arrays.get("p_WP_meas", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
        if t_det.shape[0] != p_meas.shape[0]:
            raise InputError(f"t_det has {t_det.shape[0]} entries but p_WP_meas has {p_meas.shape[0]}")
        for k in range(t_det.shape[0]):
            log.add_detection(t_det[k], p_meas[k])
        return log

    @classmethod
    def load(cls, log_dir: str | Path, source: str = "npz") -> MissionLog:
        """Load a saved log (see :func:`load_arrays`) back into a recorder."""
        return cls.from_arrays(load_arrays(log_dir, source=source))


# --------------------------------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------------------------------


def save_arrays(
    arrays: Mapping[str, np.ndarray], out_dir: str | Path, channels: Mapping[str, int] | None = None
) -> dict[str, Path]:
    """Write finalized log arrays as ``log.npz``, ``log.csv`` and ``log_detections.csv`` in ``out_dir``.

    CSV floats are written with Python's shortest round-trip repr, so reading the CSV back gives the
    same float64 values as the npz (NaN as ``nan``).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if channels is None:
        channels = _channels_of(arrays)
    t = np.asarray(arrays["t"], dtype=np.float64)
    n = t.shape[0]
    modes = np.asarray(arrays.get("mode", np.full(n, "", dtype=np.str_))).astype(np.str_)
    t_det = np.asarray(arrays.get("t_det", np.zeros(0)), dtype=np.float64)
    p_meas = np.asarray(arrays.get("p_WP_meas", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)

    npz_path = out / LOG_NPZ
    payload: dict[str, np.ndarray] = {"t": t}
    for name in channels:
        payload[name] = np.asarray(arrays[name], dtype=np.float64)
    payload["mode"] = modes  # a unicode array, so loading needs no pickle
    payload["t_det"] = t_det
    payload["p_WP_meas"] = p_meas
    np.savez_compressed(npz_path, **payload)  # type: ignore[arg-type]

    header = ["t"]
    blocks = [t.reshape(n, 1)]
    for name, width in channels.items():
        header += column_names(name, width)
        blocks.append(np.asarray(arrays[name], dtype=np.float64).reshape(n, width))
    header.append("mode")
    numeric = np.hstack(blocks) if blocks else np.zeros((n, 0))
    csv_path = out / LOG_CSV
    with open(csv_path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(header)
        # csv writes floats with str(), which for Python floats is the shortest exact repr.
        for values, m in zip(numeric.tolist(), modes.tolist(), strict=True):
            values.append(m)
            w.writerow(values)

    det_path = out / DETECTIONS_CSV
    with open(det_path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["t_det", *column_names("p_WP_meas", 3)])
        for row in np.column_stack([t_det, p_meas]).tolist():
            w.writerow(row)
    return {"npz": npz_path, "csv": csv_path, "detections_csv": det_path}


def load_arrays(log_dir: str | Path, source: str = "npz") -> dict[str, np.ndarray]:
    """Read a saved log as arrays, from ``log.npz`` (``source='npz'``) or the CSV files (``'csv'``).

    Raises:
        InputError: the files are missing or malformed.
        ValueError: unknown ``source``.
    """
    d = Path(log_dir)
    if source == "npz":
        path = d / LOG_NPZ
        if not path.is_file():
            raise InputError(f"{path}: no such log file")
        try:
            with np.load(path, allow_pickle=False) as z:
                out = {k: z[k] for k in z.files}
        except (OSError, ValueError) as exc:
            raise InputError(f"{path}: cannot read log: {exc}") from None
        if "t" not in out:
            raise InputError(f"{path}: no 't' array")
        out["mode"] = out.get("mode", np.full(out["t"].shape[0], "", dtype=np.str_)).astype(np.str_)
        return out
    if source == "csv":
        return _load_csv(d)
    raise ValueError(f"source must be 'npz' or 'csv', got {source!r}")


def _load_csv(d: Path) -> dict[str, np.ndarray]:
    path = d / LOG_CSV
    if not path.is_file():
        raise InputError(f"{path}: no such log file")
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    if not rows or not rows[0] or rows[0][0] != "t" or rows[0][-1] != "mode":
        raise InputError(f"{path}: header must start with 't' and end with 'mode'")
    header = rows[0]
    body = rows[1:]
    if any(len(r) != len(header) for r in body):
        raise InputError(f"{path}: every row must have {len(header)} fields")
    try:
        numeric = np.array([r[:-1] for r in body], dtype=np.str_).astype(np.float64)
    except ValueError as exc:
        raise InputError(f"{path}: non-numeric value: {exc}") from None
    numeric = numeric.reshape(len(body), len(header) - 1)
    out: dict[str, np.ndarray] = {"t": numeric[:, 0].copy()}
    for name, cols in _group_columns(header[1:-1]):
        block = numeric[:, cols]
        out[name] = block[:, 0].copy() if len(cols) == 1 else block.copy()
    out["mode"] = np.array([r[-1] for r in body], dtype=np.str_)

    det_path = d / DETECTIONS_CSV
    t_det = np.zeros(0)
    p_meas = np.zeros((0, 3))
    if det_path.is_file():
        with open(det_path, newline="", encoding="utf-8") as f:
            det_rows = list(csv.reader(f))[1:]
        if det_rows:
            try:
                det = np.array(det_rows, dtype=np.str_).astype(np.float64)
            except ValueError as exc:
                raise InputError(f"{det_path}: non-numeric value: {exc}") from None
            if det.ndim != 2 or det.shape[1] != 4:
                raise InputError(f"{det_path}: expected 4 columns")
            t_det, p_meas = det[:, 0].copy(), det[:, 1:].copy()
    out["t_det"] = t_det
    out["p_WP_meas"] = p_meas
    return out


def _group_columns(names: list[str]) -> list[tuple[str, list[int]]]:
    """Columns of the CSV (after ``t``, before ``mode``) grouped back into channels.

    Standard channels are matched by their known column names; any other run of columns sharing a
    base name with suffixes ``_x,_y,_z`` (``_x.._w`` for a ``q_`` quaternion) or ``_0.._k`` forms one
    extra channel, anything else a scalar.
    """
    groups: list[tuple[str, list[int]]] = []
    k = 1  # numeric column index; 0 is t
    i = 0
    while i < len(names):
        matched = False
        for name, width in CHANNELS.items():
            cols = column_names(name, width)
            if names[i : i + width] == cols:
                groups.append((name, list(range(k, k + width))))
                i += width
                k += width
                matched = True
                break
        if matched:
            continue
        m = re.fullmatch(r"(.+)_(x|0)", names[i])
        if m:
            base = m.group(1)
            for width in (4, 3) if m.group(2) == "x" else range(len(names) - i, 1, -1):
                if names[i : i + width] == column_names(base, width):
                    groups.append((base, list(range(k, k + width))))
                    i += width
                    k += width
                    matched = True
                    break
        if not matched:
            groups.append((names[i], [k]))
            i += 1
            k += 1
    return groups


def _channels_of(arrays: Mapping[str, np.ndarray]) -> dict[str, int]:
    """Numeric channels present in an array dict, standard ones first (in :data:`CHANNELS` order)."""
    n = np.asarray(arrays["t"]).shape[0]
    out: dict[str, int] = {}
    for name, width in CHANNELS.items():
        if name in arrays:
            out[name] = width
    for key, value in arrays.items():
        if key in out or key in ("t", "mode", "t_det", "p_WP_meas"):
            continue
        a = np.asarray(value)
        if a.ndim in (1, 2) and a.shape[0] == n and a.dtype.kind == "f":
            out[key] = 1 if a.ndim == 1 else a.shape[1]
    return out
