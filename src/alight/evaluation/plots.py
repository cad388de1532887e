"""Plots of one mission's log, after paper 000 (Falanga et al. 2017) Fig. 7 and Fig. 9.

Every function takes the arrays of :meth:`alight.evaluation.log.MissionLog.finalize` (missing channels
are treated as all-NaN, so a log from a mission that never saw the platform plots fine) and an
``events`` dict with optional float keys ``t_first_detection`` (paper 000's t_d), ``t_landing_start``
(t_l) and ``t_touchdown`` (t_f); a missing or ``None`` event is not drawn.

Figures are built on :class:`matplotlib.figure.Figure` with an Agg canvas, never through ``pyplot``,
so no global figure state is created or leaked (safe in worker processes and in long campaigns).
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

DPI = 110

QUAD_COLOR = "tab:blue"
PLATFORM_COLOR = "tab:red"
REF_COLOR = "0.45"
DET_COLOR = "tab:orange"

MODE_COLORS: dict[str, str] = {
    "idle": "#d9d9d9",
    "takeoff": "#9ecae1",
    "explore": "#c7e9c0",
    "track": "#fdd49e",
    "land": "#bcbddc",
    "go_around": "#fcbba1",
    "landed": "#74c476",
    "abort": "#fb6a4a",
}
"""Colour of each mission mode (:class:`alight.types.Mode` values) in the time-series band and report."""

_EXTRA_MODE_COLORS = ("#fee391", "#c6dbef", "#dadaeb", "#f2f0f7", "#e5f5e0", "#fdae6b")

EVENTS: tuple[tuple[str, str, str], ...] = (
    ("t_first_detection", "t_d", "first detection"),
    ("t_landing_start", "t_l", "landing start"),
    ("t_touchdown", "t_f", "touchdown"),
)
"""Event keys, their paper-000 symbols and labels, in mission order."""

_DET_STYLE: dict[str, Any] = {"ls": "none", "marker": ".", "ms": 3, "color": DET_COLOR}

_EVENT_STYLE: dict[str, dict[str, Any]] = {
    "t_first_detection": {"color": "tab:orange", "marker": "*", "ms": 13},
    "t_landing_start": {"color": "tab:purple", "marker": "v", "ms": 9},
    "t_touchdown": {"color": "tab:green", "marker": "s", "ms": 8},
}


# --------------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------------


def new_figure(width_in: float, height_in: float) -> Figure:
    """A pyplot-free figure with an Agg canvas attached.

    Margins are set by hand rather than by constrained layout, which would double the drawing time
    (it measures every tick label before the real draw).
    """
    fig = Figure(figsize=(width_in, height_in))
    FigureCanvasAgg(fig)
    return fig


def figure_to_png(fig: Figure, dpi: int = DPI) -> bytes:
    """PNG bytes of a figure (no 'Software' metadata, so equal figures give equal files)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    return buf.getvalue()


def save_png(fig: Figure, path: str | Path, dpi: int = DPI) -> Path:
    """Write a figure as PNG to ``path`` (parent directories created) and return the path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_bytes(figure_to_png(fig, dpi))
    return p


def _t(log: Mapping[str, np.ndarray]) -> np.ndarray:
    return np.asarray(log.get("t", np.zeros(0)), dtype=np.float64).reshape(-1)


def _channel(log: Mapping[str, np.ndarray], name: str, width: int) -> np.ndarray:
    """A channel as float64 (N, width) (or (N,) when width is 1), all-NaN when the log lacks it."""
    n = _t(log).shape[0]
    shape = (n,) if width == 1 else (n, width)
    if name not in log:
        return np.full(shape, np.nan)
    a = np.asarray(log[name], dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"log channel {name!r} has shape {a.shape}, expected {shape}")
    return a


def _detections(log: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    t_det = np.asarray(log.get("t_det", np.zeros(0)), dtype=np.float64).reshape(-1)
    p = np.asarray(log.get("p_WP_meas", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    return t_det, p


def _event_times(
    events: Mapping[str, float | None] | None, t: np.ndarray
) -> list[tuple[str, str, str, float]]:
    """The events that are given and fall inside the logged time span, as (key, symbol, label, time)."""
    out: list[tuple[str, str, str, float]] = []
    if t.shape[0] == 0:
        return out
    for key, sym, label in EVENTS:
        v = (events or {}).get(key)
        if v is not None and math.isfinite(float(v)) and t[0] <= float(v) <= t[-1]:
            out.append((key, sym, label, float(v)))
    return out


def _value_at(t: np.ndarray, a: np.ndarray, te: float) -> np.ndarray | None:
    """Linear interpolation of rows of ``a`` (N, k) at time ``te``; None outside the log or at NaN."""
    if t.shape[0] == 0 or not (t[0] <= te <= t[-1]):
        return None
    v = np.array([np.interp(te, t, a[:, k]) for k in range(a.shape[1])])
    return v if np.isfinite(v).all() else None


def _has_data(a: np.ndarray) -> bool:
    return bool(np.isfinite(a).any())


def mode_segments(t: np.ndarray, mode: np.ndarray) -> list[tuple[str, float, float]]:
    """Runs of equal mode as ``(mode, t_start, t_end)``; a run ends where the next one starts."""
    n = t.shape[0]
    if n == 0 or mode.shape[0] != n:
        return []
    m = np.asarray(mode).astype(str)
    change = np.flatnonzero(m[1:] != m[:-1]) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [n - 1]])
    return [(str(m[s]), float(t[s]), float(t[e])) for s, e in zip(starts, ends, strict=True)]


def mode_color(mode: str) -> str:
    """Colour of a mode; unknown modes get a stable pastel picked from their name."""
    if mode in MODE_COLORS:
        return MODE_COLORS[mode]
    return _EXTRA_MODE_COLORS[sum(mode.encode()) % len(_EXTRA_MODE_COLORS)]


def _draw_event_lines(ax: Axes, events: list[tuple[str, str, str, float]], label: bool) -> None:
    for key, sym, _, te in events:
        ax.axvline(te, color=_EVENT_STYLE[key]["color"], lw=1.1, ls="--", zorder=1)
        if label:
            ax.annotate(
                _tex(sym),
                xy=(te, 1.0),
                xycoords=("data", "axes fraction"),
                xytext=(2, 2),
                textcoords="offset points",
                color=_EVENT_STYLE[key]["color"],
                fontsize=10,
                va="bottom",
            )


def _tex(sym: str) -> str:
    """'t_d' -> '$t_{d}$' (mathtext, rendered by matplotlib itself, no LaTeX install needed)."""
    return f"${sym[0]}_{{{sym[2:]}}}$"


def _no_data_note(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", color="0.5", fontsize=9)


# --------------------------------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------------------------------


def plot_top_view(
    log: Mapping[str, np.ndarray],
    events: Mapping[str, float | None] | None = None,
    *,
    ax: Axes | None = None,
    path: str | Path | None = None,
    dpi: int = DPI,
) -> Figure:
    """Quadrotor and platform paths in the world xy plane (m), truth solid and estimates dashed.

    Marks the start points, the geolocated detections, and the vehicle's and the platform's
    positions at first detection, landing start and touchdown. Draws into ``ax`` when given,
    otherwise into a new figure; writes a PNG when ``path`` is given. Returns the figure.
    """
    if ax is None:
        fig = new_figure(6.6, 5.8)
        ax = fig.add_subplot()
        fig.subplots_adjust(left=0.11, right=0.97, bottom=0.09, top=0.94)
    else:
        fig = ax.get_figure()  # type: ignore[assignment]
    t = _t(log)
    p_WB = _channel(log, "p_WB", 3)
    p_WB_est = _channel(log, "p_WB_est", 3)
    p_WP = _channel(log, "p_WP", 3)
    p_WP_est = _channel(log, "p_WP_est", 3)
    p_ref = _channel(log, "p_ref", 3)
    t_det, p_meas = _detections(log)

    ax.plot(p_WP[:, 0], p_WP[:, 1], color=PLATFORM_COLOR, lw=1.8, label="platform (truth)")
    if _has_data(p_WP_est):
        ax.plot(*p_WP_est[:, :2].T, color=PLATFORM_COLOR, lw=1.2, ls="--", label="platform (est.)")
    if p_meas.shape[0]:
        ax.plot(*p_meas[:, :2].T, **_DET_STYLE, alpha=0.6, label=f"detections ({p_meas.shape[0]})")
    if _has_data(p_ref):
        ax.plot(p_ref[:, 0], p_ref[:, 1], color=REF_COLOR, lw=0.9, ls=":", label="reference")
    ax.plot(p_WB[:, 0], p_WB[:, 1], color=QUAD_COLOR, lw=1.8, label="quadrotor (truth)")
    if _has_data(p_WB_est):
        ax.plot(p_WB_est[:, 0], p_WB_est[:, 1], color=QUAD_COLOR, lw=1.2, ls="--", label="quadrotor (est.)")

    for p, color in ((p_WB, QUAD_COLOR), (p_WP, PLATFORM_COLOR)):
        ok = np.flatnonzero(np.isfinite(p[:, :2]).all(axis=1))
        if ok.size:
            ax.plot(*p[ok[0], :2], ls="none", marker="o", ms=8, mfc="white", mec=color, mew=2, zorder=5)
    ax.plot([], [], ls="none", marker="o", ms=8, mfc="white", mec="0.3", mew=2, label="start")

    for key, sym, label, te in _event_times(events, t):
        st = _EVENT_STYLE[key]
        drawn = False
        for p in (p_WB, p_WP):
            v = _value_at(t, p, te)
            if v is not None:
                ax.plot(v[0], v[1], **st, ls="none", mec="black", mew=0.6, zorder=6)
                drawn = True
        if drawn:
            ax.plot(
                [], [], **st, ls="none", mec="black", mew=0.6, label=f"{label} ({_tex(sym)} = {te:.1f} s)"
            )

    if not (_has_data(p_WB) or _has_data(p_WP)):
        _no_data_note(ax, "no position data")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Top view")
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.legend(fontsize=7.5, loc="best", framealpha=0.85)
    if path is not None:
        save_png(fig, path, dpi)
    return fig


def _draw_mode_band(ax: Axes, t: np.ndarray, mode: np.ndarray, ylabel: bool = True) -> None:
    segs = mode_segments(t, mode)
    span = (t[-1] - t[0]) if t.shape[0] > 1 else 0.0
    seen: dict[str, str] = {}
    for m, t0, t1 in segs:
        c = mode_color(m)
        ax.axvspan(t0, t1, color=c, lw=0)
        seen.setdefault(m, c)
        if span > 0 and (t1 - t0) > 0.12 * span and m:
            ax.text(0.5 * (t0 + t1), 0.5, m, ha="center", va="center", fontsize=7.5)
    ax.set_yticks([])
    ax.set_ylim(0, 1)
    if ylabel:
        ax.set_ylabel("mode", rotation=0, ha="right", va="center", fontsize=9)
    if not segs:
        _no_data_note(ax, "no mode recorded")


def plot_time_series(
    log: Mapping[str, np.ndarray],
    events: Mapping[str, float | None] | None = None,
    path: str | Path | None = None,
    *,
    dpi: int = DPI,
) -> Figure:
    """Position (left) and velocity (right) of quadrotor and platform against time, as paper 000 Fig. 7.

    x, y, z rows; truth solid, estimates dashed, the reference dotted, geolocated detections as dots;
    vertical lines at t_d, t_l, t_f; the mission mode as a coloured band on top.
    """
    fig = new_figure(11.0, 8.4)
    gs = fig.add_gridspec(
        4,
        2,
        height_ratios=[0.22, 1, 1, 1],
        left=0.07,
        right=0.985,
        top=0.94,
        bottom=0.14,
        hspace=0.12,
        wspace=0.2,
    )
    t = _t(log)
    # One mode band per column, so that the band's time axis lines up with the plots under it.
    bands = [fig.add_subplot(gs[0, c]) for c in range(2)]
    axes_p = [fig.add_subplot(gs[1 + k, 0], sharex=bands[0]) for k in range(3)]
    axes_v = [fig.add_subplot(gs[1 + k, 1], sharex=bands[1]) for k in range(3)]
    mode = np.asarray(log.get("mode", np.full(t.shape[0], "", dtype=np.str_)))
    evs = _event_times(events, t)
    for c, band in enumerate(bands):
        _draw_mode_band(band, t, mode, ylabel=(c == 0))
        band.tick_params(labelbottom=False)
        _draw_event_lines(band, evs, label=True)
        band.set_title(("position", "velocity")[c], fontsize=10, pad=14)

    t_det, p_meas = _detections(log)
    for col, (axes, kind, unit) in enumerate(((axes_p, "p", "m"), (axes_v, "v", "m/s"))):
        quad = _channel(log, f"{kind}_WB", 3)
        quad_est = _channel(log, f"{kind}_WB_est", 3)
        plat = _channel(log, f"{kind}_WP", 3)
        plat_est = _channel(log, f"{kind}_WP_est", 3)
        ref = _channel(log, f"{kind}_ref", 3)
        for k, ax in enumerate(axes):
            ax.plot(t, plat[:, k], color=PLATFORM_COLOR, lw=1.5)
            ax.plot(t, plat_est[:, k], color=PLATFORM_COLOR, lw=1.1, ls="--")
            ax.plot(t, ref[:, k], color=REF_COLOR, lw=0.9, ls=":")
            ax.plot(t, quad[:, k], color=QUAD_COLOR, lw=1.5)
            ax.plot(t, quad_est[:, k], color=QUAD_COLOR, lw=1.1, ls="--")
            if col == 0 and t_det.shape[0]:
                ax.plot(t_det, p_meas[:, k], **_DET_STYLE, alpha=0.6)
            _draw_event_lines(ax, evs, label=False)
            ax.set_ylabel(f"{kind}{'xyz'[k]} ({unit})" if kind == "v" else f"{'xyz'[k]} ({unit})")
            ax.grid(True, lw=0.4, alpha=0.6)
            if k < 2:
                ax.tick_params(labelbottom=False)
        axes[-1].set_xlabel("t (s)")

    handles: list[Artist] = [
        _line(QUAD_COLOR, "-", "quadrotor (truth)"),
        _line(QUAD_COLOR, "--", "quadrotor (est.)"),
        _line(PLATFORM_COLOR, "-", "platform (truth)"),
        _line(PLATFORM_COLOR, "--", "platform (est.)"),
        _line(REF_COLOR, ":", "reference"),
    ]
    if t_det.shape[0]:
        handles.append(_line(DET_COLOR, "none", f"detections ({t_det.shape[0]})", marker="."))
    handles += [_line(_EVENT_STYLE[key]["color"], "--", f"{label} ({te:.1f} s)") for key, _, label, te in evs]
    modes_seen = list(dict.fromkeys(m for m, _, _ in mode_segments(t, mode) if m))
    handles += [Patch(color=mode_color(m), label=m) for m in modes_seen]
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 6), fontsize=8, frameon=False)
    if t.shape[0] > 1:
        for band in bands:
            band.set_xlim(t[0], t[-1])
    if path is not None:
        save_png(fig, path, dpi)
    return fig


def _line(color: str, ls: str, label: str, marker: str | None = None) -> Line2D:
    return Line2D([], [], color=color, ls=ls, marker=marker, label=label, lw=1.4)


def plot_errors(
    log: Mapping[str, np.ndarray],
    events: Mapping[str, float | None] | None = None,
    path: str | Path | None = None,
    *,
    dpi: int = DPI,
) -> Figure:
    """Platform-estimate error, quad-pad horizontal distance and height above the pad against time.

    Top: horizontal and vertical error of the platform estimate (m), with the horizontal error of each
    geolocated measurement as dots. Middle: horizontal distance vehicle-pad centre (m), true and as
    the vehicle believes it (ego estimate minus platform estimate). Bottom: height of the vehicle
    above the pad (truth) and the range-finder reading (m).
    """
    fig = new_figure(9.0, 7.2)
    axes = fig.subplots(3, 1, sharex=True)
    fig.subplots_adjust(left=0.11, right=0.975, top=0.95, bottom=0.075, hspace=0.1)
    t = _t(log)
    evs = _event_times(events, t)
    p_WB = _channel(log, "p_WB", 3)
    p_WB_est = _channel(log, "p_WB_est", 3)
    p_WP = _channel(log, "p_WP", 3)
    p_WP_est = _channel(log, "p_WP_est", 3)
    range_m = _channel(log, "range_m", 1)
    t_det, p_meas = _detections(log)

    ax = axes[0]
    err = p_WP_est - p_WP
    if _has_data(err):
        ax.plot(t, np.hypot(err[:, 0], err[:, 1]), color=PLATFORM_COLOR, lw=1.3, label="estimate, horizontal")
        ax.plot(t, np.abs(err[:, 2]), color=PLATFORM_COLOR, lw=1.0, ls=":", label="estimate, vertical")
    if t_det.shape[0] and t.shape[0]:
        inside = (t_det >= t[0]) & (t_det <= t[-1])
        truth = np.column_stack([np.interp(t_det[inside], t, p_WP[:, k]) for k in range(2)])
        e_meas = np.hypot(*(p_meas[inside, :2] - truth).T)
        ax.plot(t_det[inside], e_meas, **_DET_STYLE, alpha=0.7, label="measurement, horizontal")
    if not _has_data(err):
        _no_data_note(ax, "no platform estimate")
    ax.set_ylabel("platform error (m)")
    ax.set_ylim(bottom=0)

    ax = axes[1]
    d = p_WB - p_WP
    ax.plot(t, np.hypot(d[:, 0], d[:, 1]), color=QUAD_COLOR, lw=1.4, label="true")
    d_est = p_WB_est - p_WP_est
    if _has_data(d_est):
        ax.plot(t, np.hypot(d_est[:, 0], d_est[:, 1]), color=QUAD_COLOR, lw=1.1, ls="--", label="believed")
    ax.set_ylabel("horizontal dist.\nquad-pad (m)")
    ax.set_ylim(bottom=0)

    ax = axes[2]
    ax.plot(t, p_WB[:, 2] - p_WP[:, 2], color=QUAD_COLOR, lw=1.4, label="height above pad (truth)")
    if _has_data(range_m):
        ax.plot(t, range_m, color="tab:brown", lw=1.0, ls="--", label="range finder")
    ax.set_ylabel("height (m)")
    ax.set_xlabel("t (s)")

    for k, ax in enumerate(axes):
        _draw_event_lines(ax, evs, label=(k == 0))
        ax.grid(True, lw=0.4, alpha=0.6)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7.5, loc="upper right", framealpha=0.85)
    if t.shape[0] > 1:
        axes[0].set_xlim(t[0], t[-1])
    if path is not None:
        save_png(fig, path, dpi)
    return fig
