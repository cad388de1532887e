"""The report of a replayed recorded flight (``alight replay``): ``report.html`` and its figures.

A recorded flight is not a simulated mission: there is no touchdown to judge, no energy model, no
simulated clock, and the log's own odometry is an estimate, not the truth. The page says what the
recording says first (the reader's warnings, such as PX4's validity flags, and the log's own messages),
then the recorded time and how alight's ego estimate compares with the log's own (position, velocity,
attitude), then the figures: top view, the estimates side by side, their differences, the IMU, and camera
frames with the detections drawn where the log has frames. Like the mission report it is one
self-contained file (figures inlined); the PNGs are written beside it.
"""

from __future__ import annotations

import html
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from alight.evaluation.plots import DPI, figure_to_png
from alight.evaluation.recorded_flight import WARNING_LEVELS, RecordedFlight, estimate_differences
from alight.evaluation.recorded_plots import (
    camera_sheet,
    plot_differences,
    plot_imu,
    plot_recorded_states,
    plot_recorded_top_view,
)
from alight.evaluation.report import _CSS as _MISSION_CSS
from alight.evaluation.report import (
    REPORT_HTML,
    _result_table_html,
    figure_html,
    format_quantity,
    page_head,
)

RECORDED_BADGE = "#0969da"
MAX_MESSAGES_SHOWN = 200
"""Log messages listed at most (every warning-level one first, then the others in time order)."""

_CSS = (
    _MISSION_CSS
    + """
.alerts { margin-top:18px; }
.alerts ul { margin:6px 0; padding-left:20px; }
.alerts li.warn { color:#9a6700; }
tr.warn td { background:#fff8c5; }
"""
)

FIGURE_HEADINGS: tuple[tuple[str, str], ...] = (
    ("top_view", "Top view"),
    ("estimates", "The log's estimate and alight's: position, velocity, attitude"),
    ("estimate_differences", "Differences of alight's estimate"),
    ("imu", "IMU (and the range finder, where the log has one)"),
    ("camera_frames", "Camera frames and detections"),
)
"""File stem and heading of each figure of the recorded flight's report, in page order."""


def _header_html(result: Mapping[str, Any], rec: RecordedFlight) -> list[str]:
    esc = html.escape
    name = Path(str(result.get("source", ""))).name or "recorded flight"
    title = f"Replay report \u2014 {name}"
    sub = [
        f"{esc(k)} <b>{esc(str(result[k]))}</b>"
        for k in ("format", "preset", "seed")
        if result.get(k) is not None
    ]
    if rec.vehicle:
        sub.insert(1, f"vehicle <b>{esc(rec.vehicle)}</b>")
    return [
        *page_head(title, _CSS),
        f'<span class="badge" style="background:{RECORDED_BADGE}">recorded flight</span>',
        f'<p class="sub">{" &middot; ".join(sub)}</p>' if sub else "",
        "</header>",
    ]


def _alerts_html(rec: RecordedFlight) -> list[str]:
    """The reader's warnings, then the log's own messages (warning levels first and marked)."""
    esc = html.escape
    out = ['<section class="alerts">', "<h2>Warnings and log messages</h2>"]
    if rec.warnings:
        out += ["<ul>", *(f'<li class="warn">{esc(w)}</li>' for w in rec.warnings), "</ul>"]
    else:
        out.append("<p>The reader found nothing to warn about.</p>")
    warn = [m for m in rec.messages if m.level.upper() in WARNING_LEVELS]
    rest = [m for m in rec.messages if m.level.upper() not in WARNING_LEVELS]
    shown = warn + rest[: max(MAX_MESSAGES_SHOWN - len(warn), 0)]
    if not rec.messages:
        out.append("<p>The log carries no text messages.</p>")
    else:
        n_left = len(rec.messages) - len(shown)
        more = f" ({n_left} more not shown)" if n_left > 0 else ""
        out += [
            f"<p>{len(rec.messages)} messages in the log, {len(warn)} at warning level or above{more}.</p>",
            "<table>",
            "<thead><tr><th>t (s)</th><th>level</th><th>message</th></tr></thead>",
            "<tbody>",
        ]
        for m in shown:
            cls = ' class="warn"' if m.level.upper() in WARNING_LEVELS else ""
            out.append(
                f'<tr{cls}><td class="num">{m.t:.3f}</td><td>{esc(m.level)}</td><td>{esc(m.text)}</td></tr>'
            )
        out += ["</tbody>", "</table>"]
    out.append("</section>")
    return out


def _cards(result: Mapping[str, Any], rec: RecordedFlight) -> list[tuple[str, str, bool]]:
    raw_msgs = result.get("messages")
    msgs: Mapping[str, Any] = raw_msgs if isinstance(raw_msgs, Mapping) else {}
    raw_vs_log = result.get("ego_vs_log_estimate")
    vs_log: Mapping[str, Any] = raw_vs_log if isinstance(raw_vs_log, Mapping) else {}
    cards = [
        ("Recorded time", format_quantity(result.get("duration_s"), "s"), True),
        ("alight vs log: position RMS", format_quantity(vs_log.get("position_rms_m"), "m"), True),
        ("alight vs log: velocity RMS", format_quantity(vs_log.get("velocity_rms_mps"), "m/s"), True),
        ("alight vs log: attitude RMS", format_quantity(vs_log.get("attitude_rms_deg"), "deg"), True),
    ]
    vs_truth = result.get("ego_vs_truth")
    if isinstance(vs_truth, Mapping):
        cards.append(
            ("alight vs truth: position RMS", format_quantity(vs_truth.get("position_rms_m"), "m"), True)
        )
    cards += [
        ("Odometry messages", format_quantity(msgs.get("odometry", 0)), False),
        ("IMU samples", format_quantity(msgs.get("imu", 0)), False),
        ("Camera frames", format_quantity(result.get("frames")), False),
        ("Frames with detections", format_quantity(result.get("frames_with_observations")), False),
        ("Detections", format_quantity(result.get("detections")), False),
        ("Log messages", format_quantity(len(rec.messages)), False),
        ("Replay wall time", format_quantity(result.get("wall_time_s"), "s"), False),
    ]
    if result.get("platform_estimate_rmse_m") is not None:
        cards.insert(
            5, ("Platform est. RMSE", format_quantity(result.get("platform_estimate_rmse_m"), "m"), True)
        )
    return cards


def _cards_html(result: Mapping[str, Any], rec: RecordedFlight) -> list[str]:
    esc = html.escape
    out = ['<section class="cards">']
    for label, value, main in _cards(result, rec):
        card = f'<div class="k">{esc(label)}</div><div class="v">{esc(value)}</div>'
        out.append(f'<div class="{"card main" if main else "card"}">{card}</div>')
    out.append("</section>")
    return out


def _figures_html(figures: Mapping[str, bytes]) -> list[str]:
    out: list[str] = []
    for stem, heading in FIGURE_HEADINGS:
        png = figures.get(stem)
        if png is not None:
            out += figure_html(stem, heading, png)
    return out


def render_recorded_html(result: Mapping[str, Any], rec: RecordedFlight, figures: Mapping[str, bytes]) -> str:
    """The recorded flight's report page as a string; ``figures`` maps a :data:`FIGURE_HEADINGS` stem
    to PNG bytes."""
    version = result.get("alight_version")
    out = [
        *_header_html(result, rec),
        *_alerts_html(rec),
        *_cards_html(result, rec),
        *_figures_html(figures),
        *_result_table_html(result),
        f"<footer>alight {html.escape(str(version))}</footer>"
        if version is not None
        else "<footer>alight</footer>",
        "</main>",
        "</body>",
        "</html>",
        "",
    ]
    return "\n".join(line for line in out if line != "")


def recorded_figures(rec: RecordedFlight, log: Mapping[str, np.ndarray], dpi: int = DPI) -> dict[str, bytes]:
    """PNG bytes of each figure, by stem (no camera sheet when the log has no frames)."""
    figures = {
        "top_view": figure_to_png(plot_recorded_top_view(rec, log), dpi),
        "estimates": figure_to_png(plot_recorded_states(rec, log), dpi),
        "estimate_differences": figure_to_png(plot_differences(estimate_differences(rec, log)), dpi),
        "imu": figure_to_png(plot_imu(rec), dpi),
    }
    sheet = camera_sheet(rec.frames)
    if sheet is not None:
        figures["camera_frames"] = sheet
    return figures


def write_recorded_report(
    out_dir: str | Path,
    result: Mapping[str, Any],
    log_arrays: Mapping[str, np.ndarray],
    rec: RecordedFlight,
    *,
    dpi: int = DPI,
) -> Path:
    """Write ``report.html`` and its figure PNGs into ``out_dir`` (created if needed) and return the
    page's path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = recorded_figures(rec, log_arrays, dpi)
    for stem, png in figures.items():
        (out / f"{stem}.png").write_bytes(png)
    path = out / REPORT_HTML
    path.write_text(render_recorded_html(result, rec, figures), encoding="utf-8")
    return path
