"""The figures of a recorded flight's report: the log's own estimate against alight's (position,
velocity, attitude), their differences, the IMU (and range finder), a top view, and camera frames with
the detections drawn on them.

Legends name what each line is: the log's estimate by its topics (``PX4 (vehicle_local_position + ...)``),
alight's ego estimate, and ground truth only where the log carries one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from alight.evaluation.plots import DET_COLOR, PLATFORM_COLOR, new_figure
from alight.evaluation.recorded_flight import (
    CameraFrame,
    EstimateDifference,
    FloatArray,
    RecordedFlight,
    euler_rpy,
)

LOG_COLOR = "tab:green"
"""The log's own estimate."""
ALIGHT_COLOR = "tab:blue"
"""alight's ego estimate."""
TRUTH_COLOR = "0.15"
AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")
"""x, y, z of a vector in the IMU plots."""
MAX_POINTS = 20_000
"""Longer series are drawn as their min-max envelope over this many bins (a spike stays visible)."""


def _series(ax: Axes, t: FloatArray, y: FloatArray, **style: object) -> None:
    """``y`` against ``t``; beyond :data:`MAX_POINTS` samples, the per-bin mean with its min-max band."""
    if t.size <= MAX_POINTS:
        ax.plot(t, y, **style)  # type: ignore[arg-type]
        return
    edges = np.linspace(0, t.size, MAX_POINTS // 2 + 1).astype(int)
    starts = edges[:-1]
    with np.errstate(invalid="ignore"):
        lo = np.fmin.reduceat(y, starts)
        hi = np.fmax.reduceat(y, starts)
        mean = np.add.reduceat(np.nan_to_num(y), starts) / np.maximum(np.diff(edges), 1)
    tc = t[starts]
    ax.fill_between(tc, lo, hi, color=str(style.get("color", "0.5")), alpha=0.25, lw=0)
    ax.plot(tc, mean, **style)  # type: ignore[arg-type]


def _no_data(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", color="0.45", fontsize=9)


def _column(log: Mapping[str, np.ndarray], name: str, width: int) -> FloatArray:
    t = np.asarray(log.get("t", np.zeros(0)), dtype=np.float64).reshape(-1)
    a = np.asarray(log.get(name, np.full((t.size, width), np.nan)), dtype=np.float64)
    return a.reshape(t.size, width)


def plot_recorded_states(rec: RecordedFlight, log: Mapping[str, np.ndarray]) -> Figure:
    """Position (m), velocity (m/s) and roll, pitch, yaw (deg) against time, one column each: the log's
    own estimate at its rate, alight's ego estimate at the replay's 50 Hz, the ground truth if any."""
    fig = new_figure(12.0, 8.0)
    axes = fig.subplots(3, 3, sharex=True)
    fig.subplots_adjust(left=0.06, right=0.99, top=0.94, bottom=0.12, hspace=0.12, wspace=0.3)
    t = np.asarray(log.get("t", np.zeros(0)), dtype=np.float64).reshape(-1)
    est = (_column(log, "p_WB_est", 3), _column(log, "v_WB_est", 3), euler_rpy(_column(log, "q_WB_est", 4)))
    tracks = [(rec.odometry, LOG_COLOR, "-", 1.4, rec.estimate_label)]
    if rec.truth is not None:
        tracks.append((rec.truth, TRUTH_COLOR, "-", 0.9, rec.truth_label))
    heads = (
        ("position", "m", "xyz"),
        ("velocity", "m/s", ("vx", "vy", "vz")),
        ("attitude", "deg", ("roll", "pitch", "yaw")),
    )
    for c, (title, unit, names) in enumerate(heads):
        axes[0, c].set_title(title, fontsize=10)
        for k in range(3):
            ax = axes[k, c]
            for tr, color, ls, lw, _ in tracks:
                y = (tr.p_W, tr.v_W, np.degrees(euler_rpy(tr.q_W)))[c][:, k]
                _series(ax, tr.t, y, color=color, ls=ls, lw=lw)
            y_est = np.degrees(est[c][:, k]) if c == 2 else est[c][:, k]
            ax.plot(t, y_est, color=ALIGHT_COLOR, ls="--", lw=1.1)
            ax.set_ylabel(f"{names[k]} ({unit})")
            ax.grid(True, lw=0.4, alpha=0.6)
        axes[2, c].set_xlabel("t (s)")
    labels = [label for *_, label in tracks] + ["alight's ego estimate"]
    handles = [axes[0, 0].plot([], [], color=tr[1], lw=1.4)[0] for tr in tracks]
    handles.append(axes[0, 0].plot([], [], color=ALIGHT_COLOR, ls="--", lw=1.4)[0])
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8.5, frameon=False)
    return fig


def plot_differences(diffs: Sequence[tuple[str, EstimateDifference]]) -> Figure:
    """|position|, |velocity| and attitude-angle differences of alight's ego estimate from each track
    (the log's estimate; the ground truth where the log has one) against time."""
    fig = new_figure(9.0, 6.6)
    axes = fig.subplots(3, 1, sharex=True)
    fig.subplots_adjust(left=0.1, right=0.975, top=0.95, bottom=0.08, hspace=0.1)
    colors = (LOG_COLOR, TRUTH_COLOR)
    for k, (label, d) in enumerate(diffs):
        color = colors[k % len(colors)]
        axes[0].plot(d.t, d.position_m, color=color, lw=1.1, label=f"alight \u2212 {label}")
        axes[1].plot(d.t, d.velocity_mps, color=color, lw=1.1)
        axes[2].plot(d.t, np.degrees(d.attitude_rad), color=color, lw=1.1)
    for ax, ylabel in zip(axes, ("position (m)", "velocity (m/s)", "attitude (deg)"), strict=True):
        ax.set_ylabel(ylabel)
        ax.set_ylim(bottom=0)
        ax.grid(True, lw=0.4, alpha=0.6)
    if not diffs:
        _no_data(axes[0], "nothing to compare with")
    else:
        axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title("alight's ego estimate: difference from the log's own", fontsize=10)
    axes[2].set_xlabel("t (s)")
    return fig


def plot_imu(rec: RecordedFlight) -> Figure:
    """The logged IMU in B (FLU): specific force (m/s^2) and body rates (deg/s), and the range finder's
    distance (m) when the log has one."""
    with_range = rec.range_t.size > 0
    fig = new_figure(9.0, 7.4 if with_range else 5.6)
    axes = fig.subplots(3 if with_range else 2, 1, sharex=True)
    fig.subplots_adjust(left=0.1, right=0.975, top=0.95, bottom=0.08, hspace=0.1)
    for ax, y, unit in (
        (axes[0], rec.f_B, "specific force f_B (m/s\u00b2)"),
        (axes[1], np.degrees(rec.w_B), "body rate w_B (deg/s)"),
    ):
        for k in range(3):
            _series(ax, rec.imu_t, y[:, k], color=AXIS_COLORS[k], lw=0.8, label="xyz"[k])
        ax.set_ylabel(unit)
        ax.grid(True, lw=0.4, alpha=0.6)
        if rec.imu_t.size:
            ax.legend(fontsize=8, loc="upper right", ncol=3)
        else:
            _no_data(ax, "the log has no IMU")
    if with_range:
        _series(axes[2], rec.range_t, rec.range_m, color="tab:brown", lw=1.0)
        axes[2].set_ylabel("range (m)")
        axes[2].grid(True, lw=0.4, alpha=0.6)
    axes[0].set_title("IMU, body frame (x forward, y left, z up)", fontsize=10)
    axes[-1].set_xlabel("t (s)")
    return fig


def plot_recorded_top_view(rec: RecordedFlight, log: Mapping[str, np.ndarray]) -> Figure:
    """The vehicle's path in W's x-y plane (m): the log's estimate, alight's, the ground truth if any,
    and the platform's estimate and geolocated detections where the replay found the pad."""
    fig = new_figure(6.6, 5.8)
    ax = fig.add_subplot()
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.09, top=0.94)
    ax.plot(rec.odometry.p_W[:, 0], rec.odometry.p_W[:, 1], color=LOG_COLOR, lw=1.6, label=rec.estimate_label)
    if rec.truth is not None:
        ax.plot(rec.truth.p_W[:, 0], rec.truth.p_W[:, 1], color=TRUTH_COLOR, lw=0.9, label=rec.truth_label)
    p_est = _column(log, "p_WB_est", 3)
    ax.plot(p_est[:, 0], p_est[:, 1], color=ALIGHT_COLOR, lw=1.1, ls="--", label="alight's ego estimate")
    p_WP_est = _column(log, "p_WP_est", 3)
    if np.isfinite(p_WP_est).any():
        ax.plot(
            p_WP_est[:, 0], p_WP_est[:, 1], color=PLATFORM_COLOR, lw=1.1, ls="--", label="platform (est.)"
        )
    meas = np.asarray(log.get("p_WP_meas", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    if meas.shape[0]:
        ax.plot(
            meas[:, 0],
            meas[:, 1],
            ls="none",
            marker=".",
            color=DET_COLOR,
            ms=4,
            label=f"detections ({meas.shape[0]})",
        )
    if rec.odometry.t.size == 0:
        _no_data(ax, "no position in the log")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x, east (m)")
    ax.set_ylabel("y, north (m)")
    ax.set_title("Top view")
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.legend(fontsize=7.5, loc="best", framealpha=0.85)
    return fig


SHEET_COLUMNS = 3
DETECTION_BGR = (0, 140, 255)


def _draw_frame(frame: CameraFrame) -> np.ndarray:
    """The frame in BGR with each observation's pixels drawn (a closed outline for three or more, dots
    otherwise), its kind and quality written beside it, and the time in the corner."""
    img = frame.image if frame.image.ndim == 3 else cv2.cvtColor(frame.image, cv2.COLOR_GRAY2BGR)
    img = np.ascontiguousarray(img).copy()
    for obs in frame.observations:
        px = np.asarray(obs.pixels, dtype=np.float64).reshape(-1, 2)
        px = px[np.isfinite(px).all(axis=1)]
        if px.shape[0] == 0:
            continue
        pts = np.round(px).astype(np.int32)
        if pts.shape[0] >= 3:
            cv2.polylines(img, [pts.reshape(-1, 1, 2)], True, DETECTION_BGR, 2, cv2.LINE_AA)
        for u, v in pts:
            cv2.circle(img, (int(u), int(v)), 3, DETECTION_BGR, -1, cv2.LINE_AA)
        u0, v0 = pts.min(axis=0)
        cv2.putText(
            img,
            f"{obs.kind} {obs.quality:.2f}",
            (int(u0), max(int(v0) - 6, 12)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.45,
            DETECTION_BGR,
            1,
            cv2.LINE_AA,
        )
    cv2.putText(
        img,
        f"t = {frame.t:.2f} s, {len(frame.observations)} found",
        (6, img.shape[0] - 8),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (255, 255, 255),
        1,
        cv2.LINE_AA,
    )
    return img


def camera_sheet(frames: Sequence[CameraFrame]) -> bytes | None:
    """A PNG of the frames side by side, :data:`SHEET_COLUMNS` a row, with their detections; None when
    there are no frames."""
    if not frames:
        return None
    tiles = [_draw_frame(f) for f in frames]
    h = max(t.shape[0] for t in tiles)
    w = max(t.shape[1] for t in tiles)
    rows = -(-len(tiles) // SHEET_COLUMNS)
    sheet = np.full((rows * (h + 4), SHEET_COLUMNS * (w + 4), 3), 255, dtype=np.uint8)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, SHEET_COLUMNS)
        y, x = r * (h + 4), c * (w + 4)
        sheet[y : y + tile.shape[0], x : x + tile.shape[1]] = tile
    ok, png = cv2.imencode(".png", sheet)
    return bytes(png.tobytes()) if ok else None
