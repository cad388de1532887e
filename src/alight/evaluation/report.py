"""A self-contained HTML report of one mission: outcome, key numbers, figures, result table, scenario.

``report.html`` embeds its figures as base64 ``data:`` URIs and its CSS inline; it references no
external script, font, stylesheet or image, so it can be mailed or archived as one file. The PNGs are
also written beside it (``top_view.png``, ``time_series.png``, ``errors.png``).
"""

from __future__ import annotations

import base64
import html
import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from alight.evaluation.plots import (
    DPI,
    EVENTS,
    figure_to_png,
    mode_color,
    mode_segments,
    plot_errors,
    plot_time_series,
    plot_top_view,
)

REPORT_HTML = "report.html"

FIGURES: tuple[tuple[str, str, Callable[..., Figure]], ...] = (
    ("top_view", "Top view", plot_top_view),
    ("time_series", "Position and velocity", plot_time_series),
    ("errors", "Errors and distances", plot_errors),
)
"""File stem, heading and plotting function of each figure in the report."""

OUTCOME_COLORS: dict[str, str] = {
    "landed": "#1a7f37",
    "crashed": "#cf222e",
    "timeout": "#9a6700",
    "aborted": "#bc4c00",
    "error": "#8250df",
}

_CSS = """
:root { --fg:#1f2328; --muted:#59636e; --line:#d1d9e0; --bg:#f6f8fa; }
* { box-sizing: border-box; }
body { margin:0; font-family: system-ui, -apple-system, "Segoe UI", Roboto, Helvetica, Arial, sans-serif;
       color:var(--fg); background:#fff; line-height:1.45; }
main { max-width: 1180px; margin: 0 auto; padding: 24px 28px 40px; }
header { display:flex; flex-wrap:wrap; align-items:center; gap:14px; border-bottom:1px solid var(--line);
         padding-bottom:14px; }
h1 { font-size: 1.5rem; margin:0; font-weight:600; }
h2 { font-size: 1.15rem; margin: 30px 0 10px; font-weight:600; }
.sub { color:var(--muted); width:100%; margin:0; font-size:0.92rem; }
.badge { display:inline-block; color:#fff; font-weight:700; letter-spacing:0.06em; padding:5px 14px;
         border-radius: 999px; font-size:0.95rem; text-transform:uppercase; }
.cards { display:grid; grid-template-columns: repeat(auto-fill, minmax(170px, 1fr)); gap:12px;
         margin-top:18px; }
.card { border:1px solid var(--line); border-radius:8px; padding:10px 14px; background:var(--bg); }
.card .k { color:var(--muted); font-size:0.8rem; }
.card .v { font-size:1.35rem; font-weight:600; font-variant-numeric: tabular-nums; }
.card.main { background:#fff; border-width:2px; }
.timeline { display:flex; height:26px; border-radius:6px; overflow:hidden; border:1px solid var(--line);
            margin-top:20px; }
.timeline div { font-size:0.75rem; display:flex; align-items:center; justify-content:center;
                overflow:hidden; white-space:nowrap; color:#222; }
.legend { color:var(--muted); font-size:0.82rem; margin-top:6px; }
.legend span.sw { display:inline-block; width:11px; height:11px; border-radius:2px; margin:0 4px -1px 12px; }
table.compute span.sw { display:inline-block; width:11px; height:11px; border-radius:2px;
                        margin:0 8px -1px 0; }
figure { margin: 0 0 10px; }
figure img { max-width:100%; height:auto; border:1px solid var(--line); border-radius:6px; }
figcaption { color:var(--muted); font-size:0.85rem; }
table { border-collapse: collapse; font-size:0.9rem; min-width: 50%; }
th, td { text-align:left; padding:5px 12px; border-bottom:1px solid var(--line); vertical-align:top; }
th { background:var(--bg); font-weight:600; }
td.num { font-variant-numeric: tabular-nums;
         font-family: ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; }
pre { background:var(--bg); border:1px solid var(--line); border-radius:6px; padding:12px 14px; overflow:auto;
      font-size:0.85rem; }
footer { margin-top: 34px; color:var(--muted); font-size:0.8rem; border-top:1px solid var(--line);
         padding-top:10px; }
"""


# --------------------------------------------------------------------------------------------------
# events
# --------------------------------------------------------------------------------------------------


def events_from_log(
    log: Mapping[str, np.ndarray], result: Mapping[str, Any] | None = None
) -> dict[str, float | None]:
    """Event times (s) for the plots, from the log (and ``result`` where it says more).

    - ``t_first_detection``: ``result['time_first_detection_s']`` when given, else the first
      detection in the log.
    - ``t_landing_start``: the first sample in mode ``land``.
    - ``t_touchdown``: the first sample in mode ``landed``; failing that ``result['time_to_land_s']``,
      which is taken to be measured from the log's t = 0.
    """
    res = result or {}
    t = np.asarray(log.get("t", np.zeros(0)), dtype=np.float64)
    mode = np.asarray(log.get("mode", np.full(t.shape[0], "", dtype=np.str_))).astype(str)

    def first(m: str) -> float | None:
        idx = np.flatnonzero(mode == m) if mode.shape == t.shape else np.zeros(0, dtype=int)
        return float(t[idx[0]]) if idx.size else None

    t_det = np.asarray(log.get("t_det", np.zeros(0)), dtype=np.float64).reshape(-1)
    td = _finite_or_none(res.get("time_first_detection_s"))
    if td is None and t_det.size:
        td = float(t_det[0])
    tf = first("landed")
    if tf is None:
        tf = _finite_or_none(res.get("time_to_land_s"))
    return {"t_first_detection": td, "t_landing_start": first("land"), "t_touchdown": tf}


def _finite_or_none(x: object) -> float | None:
    if x is None or isinstance(x, bool):
        return None
    try:
        v = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


# --------------------------------------------------------------------------------------------------
# formatting
# --------------------------------------------------------------------------------------------------


def _num(x: float) -> str:
    a = abs(x)
    if a >= 10:
        return f"{x:.1f}"
    if a >= 1:
        return f"{x:.2f}"
    return f"{x:.3f}"


def format_quantity(value: object, unit: str = "") -> str:
    """A value for a card: ``None`` -> em dash, NaN -> 'n/a', energy in kJ above 10 kJ, else 2-4 digits."""
    if value is None:
        return "\u2014"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return f"{int(value)}{' ' + unit if unit else ''}"
    v = _finite_or_none(value)
    if v is None:
        try:
            float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return str(value)
        return "n/a"
    if unit == "J" and abs(v) >= 1e4:
        v, unit = v / 1e3, "kJ"
    return f"{_num(v)}{' ' + unit if unit else ''}"


def _json_value(value: object) -> str:
    """A result field as compact JSON-like text (floats shortest-exact, NaN as NaN)."""
    try:
        return json.dumps(value, default=_json_default, allow_nan=True)
    except (TypeError, ValueError):
        return repr(value)


def _json_default(o: object) -> object:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return repr(o)


def yamlish(obj: object, indent: int = 0) -> list[str]:
    """Lines of a YAML-like rendering of nested dicts/lists/scalars (for reading, not for parsing)."""
    pad = "  " * indent
    lines: list[str] = []
    if isinstance(obj, Mapping):
        if not obj:
            return [pad + "{}"]
        for k, v in obj.items():
            if _is_scalar(v) or _is_flat_list(v) or (isinstance(v, (Mapping, list, tuple)) and not v):
                lines.append(f"{pad}{k}: {_scalar_text(v)}")
            else:
                lines.append(f"{pad}{k}:")
                lines.extend(yamlish(v, indent + 1))
        return lines
    if isinstance(obj, (list, tuple)):
        if _is_flat_list(obj) or not obj:
            return [pad + _scalar_text(obj)]
        for item in obj:
            sub = yamlish(item, indent + 1)
            first = sub[0].lstrip() if sub else ""
            lines.append(f"{pad}- {first}")
            lines.extend(sub[1:])
        return lines
    return [pad + _scalar_text(obj)]


def _is_scalar(v: object) -> bool:
    return v is None or isinstance(v, (str, bool, int, float, np.generic))


def _is_flat_list(v: object) -> bool:
    return isinstance(v, (list, tuple, np.ndarray)) and len(v) <= 12 and all(_is_scalar(x) for x in list(v))


def _scalar_text(v: object) -> str:
    if isinstance(v, Mapping) and not v:
        return "{}"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_scalar_text(x) for x in list(v)) + "]"
    if v is None:
        return "null"
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, str):
        plain = v and v.strip() == v and not any(c in v for c in ":#{}[],&*!|>'\"%@`\n")
        return v if plain else json.dumps(v)
    return repr(v) if isinstance(v, float) else str(v)


# --------------------------------------------------------------------------------------------------
# the report
# --------------------------------------------------------------------------------------------------


def _scenario_name(result: Mapping[str, Any]) -> str | None:
    sc = result.get("scenario")
    if isinstance(sc, str):
        return Path(sc).stem or sc
    if isinstance(sc, Mapping):
        name = sc.get("name")
        return str(name) if name is not None else None
    return None


def _cards(result: Mapping[str, Any], log: Mapping[str, np.ndarray]) -> list[tuple[str, str, bool]]:
    t = np.asarray(log.get("t", np.zeros(0)), dtype=np.float64)
    duration = float(t[-1] - t[0]) if t.size > 1 else None
    wall = _finite_or_none(result.get("wall_time_s"))
    speedup = f"{duration / wall:.0f}\u00d7" if duration is not None and wall else "\u2014"
    cards = [
        ("Touchdown error", format_quantity(result.get("touchdown_error_m"), "m"), True),
        ("Time to land", format_quantity(result.get("time_to_land_s"), "s"), True),
        ("First detection", format_quantity(result.get("time_first_detection_s"), "s"), True),
        ("Touchdown rel. speed", format_quantity(result.get("touchdown_rel_speed_mps"), "m/s"), False),
        ("At contact", _contact_tile(result), False),
        ("Detections", format_quantity(result.get("detections")), False),
        ("Platform est. RMSE", format_quantity(result.get("platform_estimate_rmse_m"), "m"), False),
        ("Flight energy", format_quantity(result.get("energy_flight_J"), "J"), False),
        ("Compute energy", format_quantity(result.get("energy_compute_J"), "J"), False),
        ("Simulated time", format_quantity(duration, "s"), False),
        ("Wall time", format_quantity(result.get("wall_time_s"), "s"), False),
        ("Sim / wall", speedup, False),
    ]
    return cards


def _contact_tile(result: Mapping[str, Any]) -> str:
    """The first contact against its limits: the speed across the deck and the vertical one relative to
    it, and the platform's speed and heading rate then ("—" without a contact)."""
    h = _finite_or_none(result.get("touchdown_rel_horizontal_speed_mps"))
    v = _finite_or_none(result.get("touchdown_rel_vertical_speed_mps"))
    if h is None or v is None:
        return "—"
    text = f"across {h:.2f} m/s, vertical {v:.2f} m/s"
    speed = _finite_or_none(result.get("touchdown_platform_speed_mps"))
    rate = _finite_or_none(result.get("touchdown_platform_turn_rate_rad_s"))
    if speed is not None and rate is not None:
        text += f"; platform {speed:.1f} m/s turning {rate:+.2f} rad/s ({abs(speed * rate):.1f} m/s²)"
    return text


def _timeline_html(log: Mapping[str, np.ndarray]) -> str:
    t = np.asarray(log.get("t", np.zeros(0)), dtype=np.float64)
    mode = np.asarray(log.get("mode", np.full(t.shape[0], "", dtype=np.str_)))
    segs = [s for s in mode_segments(t, mode) if s[2] > s[1]]
    if not segs:
        return ""
    total = sum(t1 - t0 for _, t0, t1 in segs)
    blocks = []
    per_mode: dict[str, float] = {}
    for m, t0, t1 in segs:
        label = m or "(none)"
        per_mode[label] = per_mode.get(label, 0.0) + (t1 - t0)
        frac = (t1 - t0) / total
        text = html.escape(label) if frac > 0.06 else ""
        blocks.append(
            f'<div style="flex:{t1 - t0:.6g} 0 0;background:{mode_color(m)}" '
            f'title="{html.escape(label)}: {t0:.2f} s to {t1:.2f} s">{text}</div>'
        )
    legend = "".join(
        f'<span class="sw" style="background:{mode_color(m if m != "(none)" else "")}"></span>'
        f"{html.escape(m)} {d:.1f} s"
        for m, d in per_mode.items()
    )
    return f'<div class="timeline">{"".join(blocks)}</div>\n<div class="legend">mode:{legend}</div>'


BLOCK_COLORS = ("#4c78a8", "#f58518", "#54a24b", "#e45756", "#72b7b2", "#b279a2", "#eeca3b")
"""Colours of the pipeline blocks (``alight.types.PIPELINE_BLOCKS``, in order) in compute plots."""
SIMULATOR_COLOR = "#bab0ac"
"""Colour of the simulator's share (physics, sensors, rendering) in compute plots."""


def _compute_html(result: Mapping[str, Any]) -> str:
    """Where the mission's wall time went: each pipeline block (``block_time_s``) and the simulator (the
    rest of ``wall_time_s``: physics, sensors, rendering, the log), as a stacked bar and a table with ms per
    simulated second, the figure that compares algorithms' cost across missions of any length."""
    blocks = result.get("block_time_s")
    wall = _finite_or_none(result.get("wall_time_s"))
    sim = _finite_or_none(result.get("simulated_time_s"))
    if not isinstance(blocks, Mapping) or not wall or not sim or wall <= 0 or sim <= 0:
        return ""
    parts: list[tuple[str, float, str]] = []
    for k, (name, value) in enumerate(blocks.items()):
        v = _finite_or_none(value)
        if v is not None and v >= 0:
            parts.append((str(name), v, BLOCK_COLORS[k % len(BLOCK_COLORS)]))
    if not parts:
        return ""
    parts.append(("simulator", max(wall - sum(v for _, v, _ in parts), 0.0), SIMULATOR_COLOR))
    total = sum(v for _, v, _ in parts) or 1.0
    esc = html.escape
    bar, rows = [], []
    for name, v, color in parts:
        share = v / total
        if v > 0:
            text = esc(name) if share > 0.08 else ""
            bar.append(
                f'<div style="flex:{v:.6g} 0 0;background:{color}" title="{esc(name)}: '
                f'{1e3 * v:.1f} ms ({100 * share:.0f} %)">{text}</div>'
            )
        rows.append(
            f'<tr><td><span class="sw" style="background:{color}"></span>{esc(name)}</td>'
            f'<td class="num">{1e3 * v:.1f}</td><td class="num">{1e3 * v / sim:.2f}</td>'
            f'<td class="num">{100 * share:.1f} %</td></tr>'
        )
    return "\n".join(
        [
            "<h2>Compute</h2>",
            f'<div class="timeline">{"".join(bar)}</div>',
            '<table class="compute">',
            "<thead><tr><th>block</th><th>ms</th><th>ms per simulated s</th><th>share</th></tr></thead>",
            "<tbody>",
            *rows,
            "</tbody>",
            "</table>",
        ]
    )


def _events_line(events: Mapping[str, float | None]) -> str:
    parts = []
    for key, sym, label in EVENTS:
        v = _finite_or_none(events.get(key))
        if v is not None:
            parts.append(f"{html.escape(label)} <i>{sym[0]}</i><sub>{sym[2:]}</sub> = {v:.2f} s")
    return f'<div class="legend">{" &middot; ".join(parts)}</div>' if parts else ""


def page_head(title: str, css: str) -> list[str]:
    """The HTML lines from the doctype to the page's ``<h1>`` (inside an open ``<header>``): the one page
    head of the mission, replay and campaign reports."""
    esc = html.escape
    return [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{esc(title)}</title>",
        f"<style>{css}</style>",
        "</head>",
        "<body>",
        "<main>",
        "<header>",
        f"<h1>{esc(title)}</h1>",
    ]


def _header_html(result: Mapping[str, Any]) -> list[str]:
    """The page's head and its header: the title, the outcome badge, the preset, seed and success line."""
    esc = html.escape
    outcome = str(result.get("outcome") or "unknown")
    color = OUTCOME_COLORS.get(outcome.lower(), "#59636e")
    name = _scenario_name(result)
    title = f"Mission report \u2014 {name}" if name else "Mission report"
    sub = []
    for key, label in (("preset", "preset"), ("seed", "seed")):
        if result.get(key) is not None:
            sub.append(f"{label} <b>{esc(str(result[key]))}</b>")
    if "success" in result:
        sub.append("success <b>" + ("yes" if result.get("success") else "no") + "</b>")
    return [
        *page_head(title, _CSS),
        f'<span class="badge" style="background:{color}">{esc(outcome)}</span>',
        f'<p class="sub">{" &middot; ".join(sub)}</p>' if sub else "",
        "</header>",
    ]


def _cards_html(result: Mapping[str, Any], log: Mapping[str, np.ndarray]) -> list[str]:
    """The section of headline figures, one card each."""
    esc = html.escape
    out = ['<section class="cards">']
    for label, value, main in _cards(result, log):
        cls = "card main" if main else "card"
        card = f'<div class="k">{esc(label)}</div><div class="v">{esc(value)}</div>'
        out.append(f'<div class="{cls}">{card}</div>')
    out.append("</section>")
    return out


def figure_html(stem: str, heading: str, png: bytes) -> list[str]:
    """One figure of a report: its heading, the PNG inlined as data, and the file name as its caption (the
    mission, replay and recorded-flight reports)."""
    esc = html.escape
    data = base64.b64encode(png).decode("ascii")
    return [
        f"<h2>{esc(heading)}</h2>",
        "<figure>",
        f'<img src="data:image/png;base64,{data}" alt="{esc(heading)}">',
        f"<figcaption>{esc(stem)}.png</figcaption>",
        "</figure>",
    ]


def _figures_html(figures: Mapping[str, bytes], replay_gif: str | None) -> list[str]:
    """The figures inlined as PNG data, in :data:`FIGURES` order, then the linked replay GIF if any."""
    esc = html.escape
    out: list[str] = []
    for stem, heading, _ in FIGURES:
        png = figures.get(stem)
        if png is not None:
            out += figure_html(stem, heading, png)
    if replay_gif:
        # Linked, not inlined: the GIF is megabytes and sits next to the report in the mission directory.
        out += [
            "<h2>Replay</h2>",
            "<figure>",
            f'<img src="{esc(replay_gif)}" alt="animated replay of the mission">',
            f"<figcaption>{esc(replay_gif)}: onboard camera with detections, top view, altitude</figcaption>",
            "</figure>",
        ]
    return out


def _result_table_html(result: Mapping[str, Any]) -> list[str]:
    """Every field of ``result.json`` as a table row, then the scenario as YAML-like text."""
    esc = html.escape
    out = ["<h2>Result</h2>", "<table>", "<thead><tr><th>field</th><th>value</th></tr></thead>", "<tbody>"]
    for key, value in result.items():
        if key == "scenario" and isinstance(value, Mapping):
            text = "(see Scenario below)"
        elif isinstance(value, str):
            text = value
        else:
            text = _json_value(value)
        out.append(f'<tr><td>{esc(str(key))}</td><td class="num">{esc(text)}</td></tr>')
    out += ["</tbody>", "</table>"]

    sc = result.get("scenario")
    if sc is not None:
        body = sc if isinstance(sc, str) else "\n".join(yamlish(sc))
        out += ["<h2>Scenario</h2>", f"<pre>{esc(body)}</pre>"]
    return out


def render_mission_html(
    result: Mapping[str, Any],
    log: Mapping[str, np.ndarray],
    events: Mapping[str, float | None],
    figures: Mapping[str, bytes],
    replay_gif: str | None = None,
) -> str:
    """The report page as a string; ``figures`` maps a :data:`FIGURES` stem to PNG bytes; ``replay_gif``
    is the relative path of the mission's animated replay, when there is one."""
    version = result.get("alight_version")
    out = [
        *_header_html(result),
        *_cards_html(result, log),
        _timeline_html(log),
        _events_line(events),
        _compute_html(result),
        *_figures_html(figures, replay_gif),
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


def write_mission_report(
    out_dir: str | Path,
    result: Mapping[str, Any],
    log_arrays: Mapping[str, np.ndarray],
    events: Mapping[str, float | None] | None = None,
    *,
    dpi: int = DPI,
) -> Path:
    """Write ``report.html`` and the figure PNGs into ``out_dir`` (created if needed).

    Args:
        out_dir: the mission's output directory.
        result: the mission's ``result.json`` content (fields may be ``None``).
        log_arrays: :meth:`alight.evaluation.log.MissionLog.finalize` output.
        events: optional ``t_first_detection``, ``t_landing_start``, ``t_touchdown`` (s); when
            ``None`` they are derived with :func:`events_from_log`.
        dpi: resolution of the PNGs.

    Returns:
        The path of ``report.html``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ev = dict(events) if events is not None else events_from_log(log_arrays, result)
    figures: dict[str, bytes] = {}
    for stem, _, plot in FIGURES:
        fig = plot(log_arrays, ev)
        png = figure_to_png(fig, dpi)
        (out / f"{stem}.png").write_bytes(png)
        figures[stem] = png
    path = out / REPORT_HTML
    replay = "replay.gif" if (out / "replay.gif").is_file() else None
    path.write_text(render_mission_html(result, log_arrays, ev, figures, replay), encoding="utf-8")
    return path
