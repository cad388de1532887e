"""The campaign report: one self-contained HTML page that compares the presets of a campaign.

``write_campaign_report(out_dir)`` reads ``OUT/results.csv`` (and ``OUT/summary.json`` when it is there
and matches the CSV) and writes ``OUT/report.html`` with

- a header: campaign name, mission counts (done of planned, errors), outcomes, total compute time;
- a per-preset comparison table: success rate with its Wilson 95 % interval, touchdown error p50/p90,
  time to land, flight and compute energy, errors; cells coloured from worse to better;
- success-rate maps over the swept parameters: a heatmap per preset over the two most informative
  parameters (aggregated over the others), a bar chart with interval error bars when one parameter
  was swept, one bar per preset when none was;
- the outcome mix per preset, and the touchdown-error distribution per preset (box + points, ECDF);
- the failures (every mission that did not land) with their parameters and relative links to the
  mission's own ``report.html`` and ``replay.gif`` where those exist, and the most common errors;
- a condition-by-preset table.

Counting (as ``summary.json``): ``n`` is every finished mission, ``errors`` those that ended in an
exception rather than a flight; success rates and their intervals are over the ``n - errors`` missions
that flew. Touchdown error and time to land are over landed missions; energies over missions that flew.
Quantiles are numpy's default (linear interpolation between order statistics).

The page is self-contained: figures are inline base64 PNGs, the CSS is inline, there is no script and
no reference to anything on the network (links to mission files are relative). Empty and partial
results give a page that says what is missing rather than an exception. results.csv is read by
:func:`alight.campaign.results.read_table`, as summary.json is: a damaged row is listed under "Damaged
rows" and left out of every figure; a file that is not a campaign's results.csv is an ``InputError``.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from alight.campaign.results import Damage, Mission
from alight.campaign.store import OUTCOMES, read_lock
from alight.campaign.summary import group_statistics, read_campaign_table
from alight.errors import InputError
from alight.evaluation.log import LOG_NPZ
from alight.evaluation.plots import DPI, figure_to_png, new_figure
from alight.evaluation.replay import REPLAY_GIF
from alight.evaluation.report import _CSS as _MISSION_CSS
from alight.evaluation.report import BLOCK_COLORS, OUTCOME_COLORS, SIMULATOR_COLOR, format_quantity, page_head
from alight.types import PIPELINE_BLOCKS

REPORT_HTML = "report.html"
RESULTS_CSV = "results.csv"
SUMMARY_JSON = "summary.json"
MISSION_REPORT = "report.html"

MAX_FAILURE_ROWS = 400
"""Failures listed in the page; the rest are counted (results.csv has them all)."""
MAX_LEVELS = 14
"""A numeric parameter with more distinct values than this is binned (quantile bins) in the maps."""
N_BINS = 7
_CMAP = "RdYlGn"
_PRESET_COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")
_MISSING = "\u2014"  # a parameter not set at a condition (the base scenario's value)


# --------------------------------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------------------------------


@dataclass
class Results:
    """What the report is built from."""

    missions: list[Mission]
    """The undamaged rows of results.csv: every figure is computed from these."""
    swept: list[str]
    presets: list[str]
    summary: dict[str, Any] | None
    notes: list[str] = field(default_factory=list)
    """Problems met while reading (columns, a stale summary), shown in the page."""
    damaged: list[Damage] = field(default_factory=list)
    """The rows of results.csv left out of every figure, each with its problem, listed in the page."""


def _float(text: str | None) -> float | None:
    """A parameter's cell as a number, None when it is not one (a parameter may be text)."""
    try:
        v = float(text or "")
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def read_results(out_dir: str | Path) -> Results:
    """Read ``results.csv`` (by :func:`alight.campaign.results.read_table`'s column rules, its rows
    checked against campaign.lock.json when it is there) and ``summary.json`` (if present).

    Raises:
        InputError: ``out_dir`` is not a directory, or its results.csv is not a campaign's.
    """
    out = Path(out_dir)
    if not out.is_dir():
        raise InputError(f"{out}: no such campaign output directory")
    notes: list[str] = []
    summary = _read_summary(out / SUMMARY_JSON, notes)
    if not (out / RESULTS_CSV).is_file():
        notes.append("results.csv is missing: no mission has finished yet.")
        return Results(missions=[], swept=[], presets=[], summary=summary, notes=notes)
    table = read_campaign_table(out, _read_lock(out, notes))
    notes += [f"{n[0].upper()}{n[1:]}." for n in table.notes]
    if table.damaged:
        notes.append(
            f"{len(table.damaged)} row(s) of results.csv are damaged and left out of every figure "
            "(listed under Damaged rows)."
        )
    missions = table.missions
    # the summary knows the swept parameters and the presets' order even when the CSV cannot show them
    swept = _in_order(table.swept, _get(summary, "swept_parameters"))
    presets = _in_order(list(dict.fromkeys(m.preset for m in missions)), _get(summary, "presets"))
    if summary is not None and (
        summary.get("n_missions") != len(missions) or summary.get("n_damaged_rows", 0) != len(table.damaged)
    ):
        notes.append(
            f"summary.json counts {summary.get('n_missions')} missions, results.csv has {len(missions)} "
            f"readable ones: the numbers below are computed from results.csv."
        )
        summary = {k: v for k, v in summary.items() if k != "groups"}
    return Results(missions, swept, presets, summary, notes, table.damaged)


def _in_order(names: list[str], order: Any) -> list[str]:
    """``names``, those listed in ``order`` (summary.json's) first, in its order."""
    if not isinstance(order, list):
        return names
    first = [str(p) for p in order if str(p) in names]
    return first + [p for p in names if p not in first]


def _read_lock(out: Path, notes: list[str]) -> dict[str, Any] | None:
    try:
        return read_lock(out)
    except InputError as err:
        notes.append(f"{err}: the rows are not checked against the campaign's plan.")
        return None


def _read_summary(path: Path, notes: list[str]) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        notes.append(f"summary.json could not be read ({err}); numbers are computed from results.csv.")
        return None
    if not isinstance(data, dict):
        notes.append("summary.json is not an object; numbers are computed from results.csv.")
        return None
    return data


# --------------------------------------------------------------------------------------------------
# statistics (summary.json's function, for when it is absent and for aggregates it lacks)
# --------------------------------------------------------------------------------------------------


def group_stats(missions: Sequence[Mission]) -> dict[str, Any]:
    """:func:`alight.campaign.summary.group_statistics` (a ``summary.json`` group's figures, computed the
    same way) and the count of each outcome."""
    return group_statistics(missions) | {
        "outcomes": {o: sum(1 for m in missions if m.outcome == o) for o in _outcomes_of(missions)}
    }


def _outcomes_of(missions: Iterable[Mission]) -> list[str]:
    seen = dict.fromkeys(m.outcome for m in missions)
    return [o for o in OUTCOMES if o in seen] + [o for o in seen if o not in OUTCOMES]


def _get(d: Mapping[str, Any] | None, *keys: str) -> Any:
    for k in keys:
        if not isinstance(d, Mapping):
            return None
        d = d.get(k)
    return d


def condition_groups(res: Results) -> list[dict[str, Any]]:
    """One entry per (condition, preset): summary.json's group when it has it, else computed."""
    by_key: dict[tuple[str, str], list[Mission]] = {}
    for m in res.missions:
        by_key.setdefault((m.condition_id, m.preset), []).append(m)
    from_summary: dict[tuple[str, str], dict[str, Any]] = {}
    for g in (res.summary or {}).get("groups") or []:
        if isinstance(g, Mapping) and "preset" in g and "condition_id" in g:
            from_summary[(str(g["condition_id"]), str(g["preset"]))] = dict(g)
    out = []
    for (cid, preset), members in by_key.items():
        computed = group_stats(members)
        g = from_summary.get((cid, preset))
        if g is None or not _valid_group(g):
            g = computed
        else:
            g = dict(g)
            g.setdefault("n_flown", g["n"] - g["errors"])
            g["outcomes"] = computed["outcomes"]
        g["condition_id"], g["preset"] = cid, preset
        g["params"] = dict(members[0].params)
        out.append(g)
    return sorted(out, key=lambda g: (_natural(g["condition_id"]), res.presets.index(g["preset"])))


def _valid_group(g: Mapping[str, Any]) -> bool:
    """Whether a summary.json group has the fields the page shows, with the right types."""

    def num(x: object) -> bool:
        return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)

    ci = g.get("wilson95")
    td = g.get("touchdown_error_m")
    return (
        all(
            isinstance(g.get(k), int) and not isinstance(g.get(k), bool) for k in ("n", "successes", "errors")
        )
        and (g.get("success_rate") is None or num(g.get("success_rate")))
        and (ci is None or (isinstance(ci, list) and len(ci) == 2 and all(num(x) for x in ci)))
        and isinstance(td, Mapping)
        and all(td.get(q) is None or num(td.get(q)) for q in ("p50", "p90"))
    )


def _natural(s: str) -> tuple[Any, ...]:
    digits = "".join(ch for ch in s if ch.isdigit())
    return (int(digits) if digits else math.inf, s)


# --------------------------------------------------------------------------------------------------
# swept parameters: levels, bins, and which two to map
# --------------------------------------------------------------------------------------------------


@dataclass
class Axis:
    """The levels of one swept parameter as shown in a map (values, or bins of a numeric parameter)."""

    name: str
    labels: list[str]
    index: dict[str, int]
    """Cell text -> level index."""


def param_axis(name: str, values: Iterable[str]) -> Axis:
    """Levels of a parameter: numeric values sorted (binned into quantile bins when there are more than
    :data:`MAX_LEVELS`), text in order of appearance; an empty cell (not set) is its own level."""
    distinct = list(dict.fromkeys(values))
    blank = [v for v in distinct if v == ""]
    rest = [v for v in distinct if v != ""]
    nums = [_float(v) for v in rest]
    known = [x for x in nums if x is not None]
    labels: list[str] = [_MISSING] if blank else []
    index: dict[str, int] = {"": 0} if blank else {}
    off = len(labels)
    if rest and len(known) == len(nums):
        order = sorted(zip(known, rest, strict=True))
        if len(order) <= MAX_LEVELS:
            for k, (_, v) in enumerate(order):
                labels.append(v)
                index[v] = off + k
        else:
            xs = np.array([x for x, _ in order])
            edges = np.unique(np.quantile(xs, np.linspace(0, 1, N_BINS + 1)))
            for k in range(len(edges) - 1):
                close = "]" if k == len(edges) - 2 else ")"
                labels.append(f"[{_short(edges[k])}, {_short(edges[k + 1])}{close}")
            for x, v in order:
                k = min(int(np.searchsorted(edges, x, side="right")) - 1, len(edges) - 2)
                index[v] = off + max(k, 0)
    else:
        for k, v in enumerate(rest):
            labels.append(v)
            index[v] = off + k
    return Axis(name, labels, index)


def _short(x: float) -> str:
    return f"{x:.3g}"


def informative_params(missions: Sequence[Mission], swept: Sequence[str], k: int = 2) -> list[str]:
    """The (at most ``k``) swept parameters whose values best explain success and failure, best first.

    Parameters with a single level are dropped. Each parameter is scored by the share of the variance
    of the success indicator (missions that flew) that lies between its levels, within each preset,
    less what chance alone puts there: adjusted eta^2 = sum_p (SS_between,p - (c_p - 1) MS_within,p)
    / sum_p SS_total,p over presets p with c_p levels flown. Ties (e.g. nothing ever fails) keep the
    campaign's order of parameters.
    """
    axes = {p: param_axis(p, (m.params.get(p, "") for m in missions)) for p in swept}
    useful = [p for p in swept if len(axes[p].labels) > 1]
    by_preset: dict[str, list[Mission]] = {}
    for m in missions:
        if m.flew:
            by_preset.setdefault(m.preset, []).append(m)

    def score(param: str) -> float:
        num = den = 0.0
        for ms in by_preset.values():
            y = np.array([1.0 if m.success else 0.0 for m in ms])
            level = np.array([axes[param].index[m.params.get(param, "")] for m in ms])
            ss_tot = float(((y - y.mean()) ** 2).sum())
            if y.size < 2 or ss_tot == 0.0:
                continue
            levels = np.unique(level)
            ss_b = sum(float((level == c).sum()) * (y[level == c].mean() - y.mean()) ** 2 for c in levels)
            ms_w = (ss_tot - ss_b) / max(y.size - levels.size, 1)
            num += ss_b - (levels.size - 1) * ms_w
            den += ss_tot
        return num / den if den > 0 else 0.0

    scores = {p: score(p) for p in useful}
    return sorted(useful, key=lambda p: (-scores[p], useful.index(p)))[:k]


# --------------------------------------------------------------------------------------------------
# colours and figures
# --------------------------------------------------------------------------------------------------


def rate_color(p: float | None, lighten: float = 0.55) -> str:
    """Background colour of a success rate (red at 0, yellow at 0.5, green at 1), lightened so that
    text stays readable; grey for None."""
    if p is None or not math.isfinite(p):
        return "#eeeeee"
    r, g, b, _ = colormaps[_CMAP](min(max(p, 0.0), 1.0))
    return to_hex((r + (1 - r) * lighten, g + (1 - g) * lighten, b + (1 - b) * lighten))


def _rank_color(v: float | None, values: Sequence[float | None]) -> str:
    """Colour of a value (lower is better) among the presets' values: green at the best, turning red as
    it gets worse, fully red at 50 % worse than the best ('' with fewer than two values)."""
    vs = [x for x in values if x is not None and math.isfinite(x)]
    if v is None or len(vs) < 2 or min(vs) <= 0:
        return ""
    worse = (v - min(vs)) / (0.5 * min(vs))
    return rate_color(1.0 - min(1.0, worse), lighten=0.65)


def _preset_color(k: int) -> str:
    return _PRESET_COLORS[k % len(_PRESET_COLORS)]


def plot_success_heatmap(
    grid_k: np.ndarray, grid_n: np.ndarray, row_axis: Axis, col_axis: Axis, title: str
) -> Figure:
    """Success rate per cell (successes ``grid_k`` of ``grid_n`` flown), red to green; grey = no data."""
    n_rows, n_cols = grid_k.shape
    rate = np.where(grid_n > 0, grid_k / np.maximum(grid_n, 1), np.nan)
    cell_w = 0.72 if n_cols <= 8 else 0.6 if n_cols <= 12 else 0.42
    cell_h = 0.5 if n_rows <= 8 else 0.42 if n_rows <= 12 else 0.3
    label_w = min(2.4, 0.4 + 0.075 * max(len(s) for s in row_axis.labels))
    rotate = n_cols > 8
    w = min(13.0, label_w + 1.3 + cell_w * n_cols)
    # room under the map for the tick labels (slanted ones need their length) and the axis label
    bottom = 0.62 + (min(1.2, 0.055 * max(len(s) for s in col_axis.labels)) if rotate else 0.0)
    h = min(14.0, bottom + 0.38 + cell_h * n_rows)
    fig = new_figure(w, h)
    ax = fig.add_axes((label_w / w, bottom / h, (w - label_w - 1.15) / w, (h - bottom - 0.38) / h))
    cax = fig.add_axes(((w - 0.95) / w, bottom / h, 0.14 / w, (h - bottom - 0.38) / h))
    cmap = colormaps[_CMAP].with_extremes(bad="#e6e6e6")
    im = ax.imshow(
        np.ma.masked_invalid(rate), cmap=cmap, vmin=0.0, vmax=1.0, aspect="auto", interpolation="nearest"
    )
    annotate = n_rows * n_cols <= 150
    fs = 8 if n_rows * n_cols <= 48 else 6.5
    for i in range(n_rows):
        for j in range(n_cols):
            if not annotate:
                break
            if grid_n[i, j] == 0:
                ax.text(j, i, "n/a", ha="center", va="center", fontsize=fs, color="0.45")
                continue
            p = rate[i, j]
            text = (
                f"{100 * p:.0f}%"
                if n_cols > 10
                else f"{100 * p:.0f}%\n{int(grid_k[i, j])}/{int(grid_n[i, j])}"
            )
            ax.text(j, i, text, ha="center", va="center", fontsize=fs, color="black", linespacing=1.0)
    ax.set_xticks(
        range(n_cols),
        col_axis.labels,
        fontsize=8,
        rotation=45 if rotate else 0,
        ha="right" if rotate else "center",
    )
    ax.set_yticks(range(n_rows), row_axis.labels, fontsize=8)
    ax.set_xlabel(col_axis.name, fontsize=9)
    ax.set_ylabel(row_axis.name, fontsize=9)
    ax.set_xticks(np.arange(-0.5, n_cols, 1.0), minor=True)
    ax.set_yticks(np.arange(-0.5, n_rows, 1.0), minor=True)
    ax.grid(which="minor", color="white", lw=1.2)
    ax.tick_params(which="minor", length=0)
    ax.set_title(title, fontsize=10, loc="left")
    cb = fig.colorbar(im, cax=cax)
    cb.set_label("success rate", fontsize=8)
    cb.ax.tick_params(labelsize=7)
    return fig


def plot_success_bars(
    labels: Sequence[str],
    series: Sequence[tuple[str, Sequence[dict[str, Any] | None]]],
    xlabel: str,
    *,
    color_by_label: bool = False,
) -> Figure:
    """Grouped bars of success rate with Wilson 95 % error bars: one group per label, one bar per
    preset (``series`` = [(preset, [group stats or None per label])]). ``color_by_label``: one series
    whose labels are the presets, each bar in its preset's colour."""
    n_lab, n_ser = len(labels), max(len(series), 1)
    w = min(13.0, max(4.5, 1.6 + 0.32 * n_lab * n_ser + 0.25 * n_lab))
    fig = new_figure(w, 3.6)
    ax = fig.add_axes((0.8 / w, 0.28 if n_lab > 8 else 0.2, (w - 1.0) / w, 0.6))
    width = 0.8 / n_ser
    x = np.arange(n_lab)
    for s, (name, stats) in enumerate(series):
        rates = np.array(
            [st["success_rate"] if st and st["success_rate"] is not None else np.nan for st in stats]
        )
        lo = np.array([st["wilson95"][0] if st and st["wilson95"] else np.nan for st in stats])
        hi = np.array([st["wilson95"][1] if st and st["wilson95"] else np.nan for st in stats])
        xs = x - 0.4 + width * (s + 0.5)
        colors = [_preset_color(j) for j in range(n_lab)] if color_by_label else _preset_color(s)
        ax.bar(xs, np.nan_to_num(rates), width * 0.92, color=colors, alpha=0.85, label=name)
        ok = np.isfinite(rates)
        ax.errorbar(
            xs[ok],
            rates[ok],
            yerr=np.vstack([rates[ok] - lo[ok], hi[ok] - rates[ok]]),
            fmt="none",
            ecolor="black",
            elinewidth=1.0,
            capsize=3,
        )
        for xi, st in zip(xs, stats, strict=True):
            if st and st["n_flown"] == 0:
                ax.text(xi, 0.02, "n/a", ha="center", va="bottom", fontsize=7, color="0.4")
    ax.set_xticks(
        x, labels, fontsize=8, rotation=45 if n_lab > 8 else 0, ha="right" if n_lab > 8 else "center"
    )
    ax.set_xlabel(xlabel, fontsize=9)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("success rate", fontsize=9)
    ax.grid(True, axis="y", lw=0.4, alpha=0.6)
    if not color_by_label:
        ax.legend(fontsize=8, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=n_ser, frameon=False)
    return fig


def plot_touchdown_errors(by_preset: Sequence[tuple[str, np.ndarray]]) -> Figure:
    """Touchdown error of landed missions per preset: box plot with every mission as a point (left),
    and the empirical CDF (right)."""
    fig = new_figure(11.0, 3.9)
    ax, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.1, 1.0]})
    fig.subplots_adjust(left=0.07, right=0.985, bottom=0.16, top=0.9, wspace=0.22)
    rng = np.random.default_rng(0)  # jitter of the points only; fixed so the page is reproducible
    names = [name for name, _ in by_preset]
    for k, (name, e) in enumerate(by_preset):
        c = _preset_color(k)
        if e.size:
            ax.boxplot(
                [e],
                positions=[k],
                widths=0.5,
                showfliers=False,
                patch_artist=True,
                boxprops={"facecolor": c, "alpha": 0.25, "edgecolor": c},
                medianprops={"color": c, "lw": 2},
                whiskerprops={"color": c},
                capprops={"color": c},
            )
            ax.plot(k + rng.uniform(-0.18, 0.18, e.size), e, ls="none", marker="o", ms=3, color=c, alpha=0.55)
            xs = np.sort(e)
            ax2.step(
                np.concatenate([[0.0], xs]),
                np.arange(xs.size + 1) / xs.size,
                where="post",
                color=c,
                lw=1.6,
                label=f"{name} (n={xs.size})",
            )
        else:
            ax.text(
                k,
                0.5,
                "no landings",
                ha="center",
                va="center",
                fontsize=8,
                color="0.45",
                transform=ax.get_xaxis_transform(),
            )
    ax.set_xticks(range(len(names)), names, fontsize=8)
    ax.set_xlim(-0.6, len(names) - 0.4)
    ax.set_ylabel("touchdown error (m)", fontsize=9)
    ax.set_ylim(bottom=0)
    ax.grid(True, axis="y", lw=0.4, alpha=0.6)
    ax.set_title("per preset (landed missions)", fontsize=10, loc="left")
    ax2.set_xlabel("touchdown error (m)", fontsize=9)
    ax2.set_ylabel("fraction of landings \u2264 x", fontsize=9)
    ax2.set_ylim(0, 1.02)
    ax2.set_xlim(left=0)
    ax2.grid(True, lw=0.4, alpha=0.6)
    ax2.set_title("empirical CDF", fontsize=10, loc="left")
    if ax2.get_legend_handles_labels()[0]:
        ax2.legend(fontsize=8, loc="lower right")
    for a in (ax, ax2):
        a.tick_params(labelsize=8)
    return fig


def plot_outcomes(presets: Sequence[str], counts: Sequence[Mapping[str, int]]) -> Figure:
    """Outcome mix per preset as stacked horizontal bars (fractions of the preset's missions)."""
    h = 0.9 + 0.42 * len(presets)
    fig = new_figure(11.0, h)
    label_w = min(2.6, 0.5 + 0.08 * max(len(p) for p in presets))
    ax = fig.add_axes((label_w / 11.0, 0.55 / h, 1 - (label_w + 1.9) / 11.0, (h - 0.75) / h))
    outcomes = [o for o in OUTCOMES if any(c.get(o) for c in counts)]
    outcomes += sorted({o for c in counts for o in c if o not in OUTCOMES and c[o]})
    for i, c in enumerate(counts):
        total = sum(c.values()) or 1
        left = 0.0
        for o in outcomes:
            f = c.get(o, 0) / total
            if f <= 0:
                continue
            ax.barh(i, f, left=left, color=_outcome_color(o), height=0.7)
            if f >= 0.06:
                ax.text(
                    left + f / 2,
                    i,
                    f"{c[o]}",
                    ha="center",
                    va="center",
                    color="white",
                    fontsize=8,
                    fontweight="bold",
                )
            left += f
    ax.set_yticks(range(len(presets)), presets, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0, 1)
    ax.set_xlabel("fraction of missions", fontsize=8)
    ax.tick_params(labelsize=8)
    handles = [Patch(color=_outcome_color(o), label=o) for o in outcomes]
    ax.legend(handles=handles, fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    return fig


def plot_compute(presets: Sequence[str], per_s: Sequence[Mapping[str, float | None]]) -> Figure:
    """Wall time per simulated second of each pipeline block and of the simulator, per preset, as
    stacked horizontal bars (ms per simulated second; the bar's end is the whole mission's cost)."""
    h = 0.9 + 0.42 * len(presets)
    fig = new_figure(11.0, h)
    label_w = min(2.6, 0.5 + 0.08 * max(len(p) for p in presets))
    ax = fig.add_axes((label_w / 11.0, 0.55 / h, 1 - (label_w + 2.2) / 11.0, (h - 0.75) / h))
    parts = [*zip(PIPELINE_BLOCKS, BLOCK_COLORS, strict=False), ("simulator", SIMULATOR_COLOR)]
    right = 0.0
    for i, c in enumerate(per_s):
        left = 0.0
        for name, color in parts:
            v = c.get(name)
            if v is None or v <= 0:
                continue
            ax.barh(i, v, left=left, color=color, height=0.7)
            left += v
        if left > 0:
            ax.text(left, i, f" {left:.1f}", ha="left", va="center", fontsize=8)
        right = max(right, left)
    ax.set_yticks(range(len(presets)), presets, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0, 1.12 * right if right > 0 else 1.0)
    ax.set_xlabel("wall-clock ms per simulated second", fontsize=8)
    ax.tick_params(labelsize=8)
    handles = [Patch(color=color, label=name) for name, color in parts]
    ax.legend(handles=handles, fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    return fig


def _outcome_color(outcome: str) -> str:
    return OUTCOME_COLORS.get(outcome, "#8c8c8c")


def _figure(fig: Figure, alt: str) -> str:
    """A figure as an inline PNG."""
    data = base64.b64encode(figure_to_png(fig, DPI)).decode("ascii")
    return f'<figure><img src="data:image/png;base64,{data}" alt="{_esc(alt)}"></figure>'


# --------------------------------------------------------------------------------------------------
# HTML
# --------------------------------------------------------------------------------------------------

_CSS = (
    _MISSION_CSS
    + """
main { max-width: 1320px; }
.note { background:#fff8c5; border:1px solid #d4a72c66; border-radius:6px; padding:8px 12px; margin:10px 0;
        font-size:0.88rem; }
.empty { font-size:1.15rem; color:var(--muted); padding:40px 0; text-align:center; }
.scroll { overflow-x:auto; }
table.cmp td { white-space:nowrap; }
.cards { grid-template-columns: repeat(auto-fill, minmax(140px, 1fr)); }
.card .v { font-size:1.2rem; white-space:nowrap; }
table.fail td { white-space:nowrap; }
table.cmp td.num { text-align:right; }
td .ci { color:var(--muted); font-size:0.8rem; }
.figs { display:flex; flex-wrap:wrap; gap:14px; align-items:flex-start; }
.figs figure { flex: 0 1 auto; }
.pill { display:inline-block; color:#fff; font-weight:600; padding:1px 8px; border-radius:999px;
        font-size:0.78rem; }
table.fail td { font-size:0.84rem; }
table.fail td.err { max-width: 320px; white-space: normal; color:#6e1d1d; font-size:0.78rem;
                    font-family: ui-monospace, monospace; }
table.det td, table.det th { font-size:0.84rem; padding:4px 9px; }
details > summary { cursor:pointer; color:var(--muted); margin:6px 0; }
.muted { color:var(--muted); }
"""
)


def _esc(x: object) -> str:
    return html.escape(str(x), quote=True)


def _pct(p: float | None) -> str:
    return "n/a" if p is None else f"{100 * p:.1f}%"


def _ci_text(ci: Sequence[float] | None) -> str:
    if not ci:
        return ""
    return f'<span class="ci">[{100 * ci[0]:.0f}\u2013{100 * ci[1]:.0f}%]</span>'


def _duration(seconds: float) -> str:
    s = int(round(seconds))
    if s < 120:
        return f"{seconds:.1f} s"
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h} h {m:02d} min" if h else f"{m} min {sec:02d} s"


def _safe_rel(mission_dir: str) -> str | None:
    """The mission directory as a safe relative path (None for absolute paths or paths leaving OUT)."""
    d = mission_dir.strip().replace("\\", "/").strip("/")
    if not d or mission_dir.startswith("/") or ":" in d or any(part == ".." for part in d.split("/")):
        return None
    return d


def _link(out: Path, mission_dir: str, name: str, text: str) -> str:
    d = _safe_rel(mission_dir)
    if d is None or not (out / d / name).is_file():
        return ""
    return f'<a href="{_esc(quote(f"{d}/{name}"))}">{_esc(text)}</a>'


def _param_text(v: str) -> str:
    return v if v != "" else _MISSING


def _cards(res: Results, overall: dict[str, Any]) -> list[tuple[str, str]]:
    ms = res.missions
    planned = _get(res.summary, "n_planned")
    done = f"{len(ms)}" + (f" of {planned}" if isinstance(planned, int) and planned != len(ms) else "")
    wall = sum(m.values["wall_time_s"] or 0.0 for m in ms)
    sim = sum(m.values["simulated_time_s"] or 0.0 for m in ms)
    conditions = len({m.condition_id for m in ms})
    return [
        ("Missions", done),
        ("Presets", str(len(res.presets))),
        ("Conditions", str(conditions)),
        ("Success (all presets)", _pct(overall["success_rate"])),
        ("Errors", str(overall["errors"])),
        ("Simulated time", _duration(sim)),
        ("Compute time (sum)", _duration(wall)),
        ("Sim / compute", f"{sim / wall:.0f}\u00d7" if wall > 0 and sim > 0 else "\u2014"),
    ]


def _comparison_table(res: Results, per_preset: dict[str, dict[str, Any]]) -> list[str]:
    cols: list[tuple[str, tuple[str, str]]] = [
        ("TD error p50", ("touchdown_error_m", "p50")),
        ("TD error p90", ("touchdown_error_m", "p90")),
        ("time to land p50", ("time_to_land_s", "p50")),
        ("flight energy (mean)", ("energy_flight_J", "mean")),
        ("compute energy (mean)", ("energy_compute_J", "mean")),
    ]
    units = {"touchdown_error_m": "m", "time_to_land_s": "s", "energy_flight_J": "J", "energy_compute_J": "J"}
    head = "<th>success rate [95% CI]</th>" + "".join(f"<th>{_esc(c)}</th>" for c, _ in cols)
    out = [
        '<div class="scroll"><table class="cmp">',
        f"<thead><tr><th>preset</th><th>missions</th>{head}<th>errors</th></tr></thead>",
        "<tbody>",
    ]
    for p in res.presets:
        st = per_preset[p]
        cells = [
            f"<td><b>{_esc(p)}</b></td>",
            f'<td class="num">{st["n"]}</td>',
        ]
        rate = st["success_rate"]
        cells.append(
            f'<td class="num" style="background:{rate_color(rate)}"><b>{_pct(rate)}</b> '
            f'{_ci_text(st["wilson95"])} <span class="ci">{st["successes"]}/{st["n_flown"]}</span></td>'
        )
        for _, key in cols:
            v = _get(st, *key)
            others = [_get(per_preset[q], *key) for q in res.presets]
            bg = _rank_color(v, others)
            style = f' style="background:{bg}"' if bg else ""
            cells.append(f'<td class="num"{style}>{_esc(format_quantity(v, units[key[0]]))}</td>')
        err_style = ' style="background:#f5c6cb"' if st["errors"] else ""
        cells.append(f'<td class="num"{err_style}>{st["errors"]}</td>')
        out.append("<tr>" + "".join(cells) + "</tr>")
    out += ["</tbody></table></div>"]
    return out


def _compute_section(res: Results, per_preset: dict[str, dict[str, Any]]) -> list[str]:
    """What each preset's blocks cost: ms of wall time per simulated second (figure and table), from the
    missions' block times; nothing when no mission has them (an older campaign)."""
    per_s = [per_preset[p]["compute_ms_per_simulated_s"] for p in res.presets]
    if all(c.get("simulator") is None for c in per_s):
        return []
    names = [*PIPELINE_BLOCKS, "simulator"]
    out = [
        "<h2>Compute</h2>",
        _figure(plot_compute(res.presets, per_s), "compute per simulated second per preset"),
        '<div class="scroll"><table class="cmp">',
        "<thead><tr><th>preset</th>"
        + "".join(f"<th>{_esc(n)}</th>" for n in names)
        + "<th>total</th></tr></thead>",
        "<tbody>",
    ]
    totals = [None if c.get("simulator") is None else sum(c[n] or 0.0 for n in names) for c in per_s]
    for p, c, total in zip(res.presets, per_s, totals, strict=True):
        cells = [f"<td><b>{_esc(p)}</b></td>"]
        for n in [*names, "total"]:
            v = total if n == "total" else c.get(n)
            others = totals if n == "total" else [q.get(n) for q in per_s]
            bg = _rank_color(v, others)
            style = f' style="background:{bg}"' if bg else ""
            text = "\u2014" if v is None else f"{v:.2f}"
            cells.append(f'<td class="num"{style}>{text}</td>')
        out.append("<tr>" + "".join(cells) + "</tr>")
    out += [
        "</tbody></table></div>",
        '<p class="muted">Wall-clock milliseconds per simulated second, over the missions that flew, on the '
        "machines that flew them: each pipeline block, and the simulator (physics, sensors, rendering, "
        "the rest of the mission's wall time). Green marks the cheapest preset.</p>",
    ]
    return out


def _maps_section(res: Results) -> list[str]:
    flew_any = any(m.flew for m in res.missions)
    out = ["<h2>Success rate over the swept parameters</h2>"]
    if not flew_any:
        return [*out, '<p class="muted">No mission flew (all ended in errors): nothing to map.</p>']
    chosen = informative_params(res.missions, res.swept, 2)
    others = [p for p in res.swept if p not in chosen]
    by_preset = {p: [m for m in res.missions if m.preset == p] for p in res.presets}
    if len(chosen) == 2:
        a0 = param_axis(chosen[0], (m.params.get(chosen[0], "") for m in res.missions))
        a1 = param_axis(chosen[1], (m.params.get(chosen[1], "") for m in res.missions))
        # the parameter with more levels across (unless that makes the map too wide)
        col, row = (a0, a1) if len(a0.labels) >= len(a1.labels) and len(a0.labels) <= 16 else (a1, a0)
        if len(col.labels) > 16 and len(row.labels) <= 16:
            col, row = row, col
        figs = []
        for p in res.presets:
            k = np.zeros((len(row.labels), len(col.labels)))
            n = np.zeros_like(k)
            for m in by_preset[p]:
                if not m.flew:
                    continue
                i, j = row.index[m.params.get(row.name, "")], col.index[m.params.get(col.name, "")]
                n[i, j] += 1
                k[i, j] += m.success
            figs.append((p, plot_success_heatmap(k, n, row, col, p)))
        note = f"{_esc(row.name)} \u00d7 {_esc(col.name)}"
        if others:
            note += f"; aggregated over {', '.join(_esc(o) for o in others)}"
        out.append(
            f'<p class="muted">Success rate of missions that flew, per cell ({note}). The two parameters '
            "that best separate successes from failures are mapped; grey cells have no flown mission.</p>"
        )
        out.append('<div class="figs">')
        for p, fig in figs:
            out.append(_figure(fig, f"success rate map, {p}"))
        out.append("</div>")
        return out
    if len(chosen) == 1:
        axis = param_axis(chosen[0], (m.params.get(chosen[0], "") for m in res.missions))
        series = []
        for p in res.presets:
            per_level: list[list[Mission]] = [[] for _ in axis.labels]
            for m in by_preset[p]:
                per_level[axis.index[m.params.get(axis.name, "")]].append(m)
            series.append((p, [group_stats(ms) if ms else None for ms in per_level]))
        fig = plot_success_bars(axis.labels, series, axis.name)
        note = f"; aggregated over {', '.join(_esc(o) for o in others)}" if others else ""
        out.append(
            f'<p class="muted">Success rate with Wilson 95% intervals per value of {_esc(axis.name)}'
            f"{note}.</p>"
        )
    else:
        series = [("", [group_stats(by_preset[p]) for p in res.presets])]
        fig = plot_success_bars(res.presets, series, "preset", color_by_label=True)
        out.append(
            '<p class="muted">No parameter was swept: success rate with Wilson 95% interval per preset.</p>'
        )
    out.append(_figure(fig, "success rate"))
    return out


def _failures_section(res: Results, out_dir: Path) -> list[str]:
    failed = [m for m in res.missions if m.outcome != "landed"]
    out = [f"<h2>Failures ({len(failed)})</h2>"]
    if not failed:
        return [*out, '<p class="muted">Every mission landed.</p>']
    errors = [m for m in failed if m.outcome == "error"]
    if errors:
        counts: dict[str, int] = {}
        for m in errors:
            counts[m.error or "(no message)"] = counts.get(m.error or "(no message)", 0) + 1
        top = sorted(counts.items(), key=lambda kv: -kv[1])[:8]
        out.append("<p>Most common errors:</p><ul>")
        out += [
            f'<li><span class="muted">{c}\u00d7</span> <code>{_esc(msg[:300])}</code></li>' for msg, c in top
        ]
        out.append("</ul>")
    order = {p: i for i, p in enumerate(res.presets)}
    failed.sort(
        key=lambda m: (
            order.get(m.preset, 99),
            OUTCOMES.index(m.outcome) if m.outcome in OUTCOMES else 9,
            _natural(m.condition_id),
            m.mission_id,
        )
    )
    shown = failed[:MAX_FAILURE_ROWS]
    params = "".join(f"<th>{_esc(p)}</th>" for p in res.swept)
    out += [
        '<div class="scroll"><table class="fail">',
        f"<thead><tr><th>mission</th><th>preset</th><th>outcome</th>{params}<th>seed</th>"
        "<th>TD error</th><th>sim. time</th><th>files</th><th>error</th></tr></thead>",
        "<tbody>",
    ]
    for m in shown:
        color = _outcome_color(m.outcome)
        links = " ".join(
            x
            for x in (
                _link(out_dir, m.mission_dir, MISSION_REPORT, "report"),
                _link(out_dir, m.mission_dir, REPLAY_GIF, "replay"),
                _link(out_dir, m.mission_dir, "error.txt", "traceback"),
                _link(out_dir, m.mission_dir, LOG_NPZ, "log"),
                _link(out_dir, m.mission_dir, "views.txt", "views.txt"),
                _link(out_dir, m.mission_dir, "result.json", "result.json"),
            )
            if x
        )
        pcells = "".join(f"<td>{_esc(_param_text(m.params.get(p, '')))}</td>" for p in res.swept)
        err = m.error
        short = err[:160] + ("\u2026" if len(err) > 160 else "")
        out.append(
            f"<tr><td>{_esc(m.mission_id)}</td><td>{_esc(m.preset)}</td>"
            f'<td><span class="pill" style="background:{color}">{_esc(m.outcome)}</span></td>{pcells}'
            f"<td>{_esc(m.seed)}</td>"
            f'<td class="num">{_esc(format_quantity(m.values["touchdown_error_m"], "m"))}</td>'
            f'<td class="num">{_esc(format_quantity(m.values["simulated_time_s"], "s"))}</td>'
            f"<td>{links or '<span class=muted>none kept</span>'}</td>"
            f'<td class="err" title="{_esc(err)}">{_esc(short)}</td></tr>'
        )
    out.append("</tbody></table></div>")
    out.append(
        '<p class="muted">Every failure keeps its log and scenario.yaml; the first failures of each '
        "preset and condition (the campaign's <code>views_per_cell</code>) also have their report and "
        "replay. <code>alight fly missions/&lt;id&gt;/scenario.yaml --out DIR --replay</code> flies any "
        "mission again, the same flight, with both.</p>"
    )
    if len(failed) > len(shown):
        out.append(f'<p class="muted">{len(failed) - len(shown)} more failures are in results.csv.</p>')
    return out


def _detail_section(res: Results, groups: list[dict[str, Any]]) -> list[str]:
    conds: dict[str, dict[str, str]] = {}
    cell: dict[tuple[str, str], dict[str, Any]] = {}
    for group in groups:
        conds.setdefault(group["condition_id"], group["params"])
        cell[(group["condition_id"], group["preset"])] = group
    params = "".join(f"<th>{_esc(p)}</th>" for p in res.swept)
    heads = "".join(f'<th colspan="2">{_esc(p)}</th>' for p in res.presets)
    sub = "".join("<th>success [95% CI]</th><th>TD p50 / p90</th>" for _ in res.presets)
    blank = "".join("<th></th>" for _ in res.swept)
    out = [
        f"<h2>Conditions ({len(conds)})</h2>",
        "<details open><summary>success and touchdown error per condition and preset</summary>",
        '<div class="scroll"><table class="det">',
        f"<thead><tr><th>condition</th>{params}{heads}</tr><tr><th></th>{blank}{sub}</tr></thead>",
        "<tbody>",
    ]
    for cid, pv in conds.items():
        tds = [f"<td>{_esc(cid)}</td>"] + [
            f"<td>{_esc(_param_text(str(pv.get(p, ''))))}</td>" for p in res.swept
        ]
        for p in res.presets:
            g = cell.get((cid, p))
            if g is None:
                tds.append('<td class="muted">\u2014</td><td></td>')
                continue
            rate = g.get("success_rate")
            flown = g.get("n_flown", g.get("n", 0))
            errs = int(g.get("errors") or 0)
            err_txt = f' <span class="ci">({errs} err)</span>' if errs else ""
            tds.append(
                f'<td class="num" style="background:{rate_color(rate)}">'
                f"{_pct(rate)} {_ci_text(g.get('wilson95'))} "
                f'<span class="ci">{g.get("successes", 0)}/{flown}</span>{err_txt}</td>'
            )
            p50 = _get(g, "touchdown_error_m", "p50")
            p90 = _get(g, "touchdown_error_m", "p90")
            td = "\u2014" if p50 is None else f"{format_quantity(p50, 'm')} / {format_quantity(p90, 'm')}"
            tds.append(f'<td class="num">{_esc(td)}</td>')
        out.append("<tr>" + "".join(tds) + "</tr>")
    out += ["</tbody></table></div>", "</details>"]
    return out


def render_campaign_html(res: Results, out_dir: Path) -> str:
    """The report page for parsed results (``out_dir`` is used to find the mission files to link)."""
    out = _page_head(res, out_dir)
    out += [f'<div class="note">{_esc(n)}</div>' for n in res.notes]
    out += _damaged_section(res)
    if not res.missions:
        what = "readable mission" if res.damaged else "missions"
        out.append(f'<p class="empty">No {what} in results.csv yet: there is nothing to report.</p>')
        return "\n".join([*out, _footer(res), "</main>", "</body>", "</html>", ""])

    overall = group_stats(res.missions)
    per_preset = {p: group_stats([m for m in res.missions if m.preset == p]) for p in res.presets}
    out.append('<section class="cards">')
    for label, value in _cards(res, overall):
        out.append(
            f'<div class="card"><div class="k">{_esc(label)}</div><div class="v">{_esc(value)}</div></div>'
        )
    out.append("</section>")
    if overall["n_flown"] == 0:
        out.append('<div class="note">Every mission ended in an error: see the errors under Failures.</div>')

    out.append("<h2>Presets</h2>")
    out += _comparison_table(res, per_preset)
    out.append(
        '<p class="muted">Success rate over missions that flew (errors excluded), '
        "Wilson 95% interval in brackets. "
        "Touchdown error (TD) and time to land over landed missions; energies over missions that flew. "
        "Green marks the best preset, red one 50% or more worse. Outcomes per preset:</p>"
    )
    fig = plot_outcomes(res.presets, [per_preset[p]["outcomes"] for p in res.presets])
    out.append(_figure(fig, "outcomes per preset"))
    out += _compute_section(res, per_preset)
    out += _maps_section(res)
    out += _touchdown_section(res)
    out += _detail_section(res, condition_groups(res))
    out += _failures_section(res, out_dir)
    return "\n".join([*out, _footer(res), "</main>", "</body>", "</html>", ""])


def _page_head(res: Results, out_dir: Path) -> list[str]:
    """From the doctype to the end of the page's header: title, date, version, swept parameters, links."""
    name = str(_get(res.summary, "campaign") or out_dir.resolve().name)
    title = f"Campaign report \u2014 {name}"
    head = page_head(title, _CSS)
    sub = []
    for key, label in (("created", "created"), ("alight_version", "alight")):
        v = _get(res.summary, key)
        if v:
            sub.append(f"{label} <b>{_esc(v)}</b>")
    if res.swept:
        sub.append("swept: " + ", ".join(f"<b>{_esc(p)}</b>" for p in res.swept))
    links = [f'<a href="{f}">{f}</a>' for f in (RESULTS_CSV, SUMMARY_JSON) if (out_dir / f).is_file()]
    if links:
        sub.append(" ".join(links))
    return head + ([f'<p class="sub">{" &middot; ".join(sub)}</p>'] if sub else []) + ["</header>"]


def _damaged_section(res: Results) -> list[str]:
    """Every damaged row of results.csv (up to :data:`MAX_FAILURE_ROWS`), with what is wrong with it."""
    if not res.damaged:
        return []
    out = [
        f"<h2>Damaged rows ({len(res.damaged)})</h2>",
        '<p class="muted">Rows of results.csv that break a column\'s rule: left out of every figure on '
        "this page and in summary.json (its <code>damaged_rows</code>).</p>",
        '<div class="scroll"><table class="fail">',
        "<thead><tr><th>line</th><th>mission</th><th>problem</th></tr></thead>",
        "<tbody>",
    ]
    for d in res.damaged[:MAX_FAILURE_ROWS]:
        out.append(
            f"<tr><td>{d.line}</td><td>{_esc(d.mission_id or _MISSING)}</td>"
            f'<td class="err">{_esc(d.problem)}</td></tr>'
        )
    out.append("</tbody></table></div>")
    if len(res.damaged) > MAX_FAILURE_ROWS:
        more = len(res.damaged) - MAX_FAILURE_ROWS
        out.append(f'<p class="muted">{more} more damaged rows are listed in summary.json.</p>')
    return out


def _touchdown_section(res: Results) -> list[str]:
    out = ["<h2>Touchdown error</h2>"]
    td = [
        (
            p,
            np.array(
                [
                    m.values["touchdown_error_m"]
                    for m in res.missions
                    if m.preset == p and m.outcome == "landed" and m.values["touchdown_error_m"] is not None
                ]
            ),
        )
        for p in res.presets
    ]
    if any(e.size for _, e in td):
        out.append(_figure(plot_touchdown_errors(td), "touchdown error distributions"))
    else:
        out.append('<p class="muted">No mission landed: no touchdown errors to show.</p>')
    return out


def _footer(res: Results) -> str:
    when = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    version = _get(res.summary, "alight_version")
    return (
        f"<footer>alight{(' ' + _esc(version)) if version else ''} campaign report, written {when}</footer>"
    )


def write_campaign_report(out_dir: str | Path, results: Results | None = None) -> Path:
    """Write ``OUT/report.html`` for the campaign output directory ``out_dir`` and return its path;
    ``results``: what :func:`read_results` read of it, when the caller has it already.

    Raises:
        InputError: ``out_dir`` is not a directory, or its results.csv is not a campaign's.
    """
    out = Path(out_dir)
    res = read_results(out) if results is None else results
    path = out / REPORT_HTML
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(render_campaign_html(res, out), encoding="utf-8")
    tmp.replace(path)  # a browser open on the old report never sees half a page
    return path
