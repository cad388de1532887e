"""summary.json: per preset and condition, the success rate with its Wilson 95 % interval, the
distribution of the touchdown error and the compute of each pipeline block per simulated second, from
results.csv and the campaign's lock file.

``n`` counts every finished mission of a group, ``errors`` those that did not fly to an outcome (an
exception, a timeout, a dead worker). An error says nothing about landing, so the success rate and its
interval are over the ``n_flown = n - errors`` missions that flew: ``success_rate = successes /
n_flown`` (null when nothing flew).

results.csv is read by :func:`alight.campaign.results.read_table`, as the report reads it: a damaged row
is left out of every figure and listed in ``damaged_rows`` (``n_damaged_rows``), with the file's other
problems in ``results_notes``; ``n_missions`` counts the rows the figures are computed from.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

import alight
from alight.campaign.results import (
    BLOCK_TIME_COLUMN,
    RESULTS_CSV,
    Mission,
    ResultsTable,
    expected_cells,
    figures_of,
    read_table,
)
from alight.campaign.store import SUMMARY_JSON, read_lock, write_json
from alight.errors import InputError
from alight.types import PIPELINE_BLOCKS


def wilson95(successes: int, n: int) -> tuple[float, float] | None:
    """The Wilson score 95 % interval of a binomial proportion (no continuity correction); None for n = 0.

    Wilson (1927): p = (p_hat + z^2/2n +- z sqrt(p_hat (1 - p_hat)/n + z^2/4n^2)) / (1 + z^2/n), computed
    by SciPy's ``BinomTestResult.proportion_ci(method="wilson")``.
    """
    if n < 0 or not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n, got {successes} of {n}")
    if n == 0:
        return None
    from scipy.stats import binomtest

    ci = binomtest(successes, n).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


class MissionFigures(Protocol):
    """What the group statistics read of one mission: a results.csv row, parsed (the report's
    :class:`alight.campaign.report.Mission` is one)."""

    @property
    def outcome(self) -> str:
        """``landed``, ``crashed``, ..., or ``error`` (no flight)."""
        ...

    @property
    def success(self) -> bool:
        """Whether the mission counts as a success."""
        ...

    @property
    def values(self) -> Mapping[str, float | None]:
        """Numeric result columns (SI units, as in results.csv); None where a cell is empty."""
        ...


def _values(missions: Iterable[MissionFigures], column: str) -> list[float]:
    """The finite values of ``column`` (an empty or damaged cell says nothing about the group)."""
    out = []
    for m in missions:
        v = m.values.get(column)
        if v is not None and math.isfinite(v):
            out.append(v)
    return out


def _stats(values: list[float], which: Sequence[str]) -> dict[str, float | None]:
    if not values:
        return dict.fromkeys(which)
    a = np.asarray(values, dtype=float)
    known = {
        "p50": lambda: np.percentile(a, 50),
        "p90": lambda: np.percentile(a, 90),
        "p95": lambda: np.percentile(a, 95),
        "max": lambda: np.max(a),
        "mean": lambda: np.mean(a),
    }
    return {k: float(known[k]()) for k in which}


def compute_per_simulated_s(
    missions: Iterable[tuple[Mapping[str, float | None], float | None, float | None]],
) -> dict[str, float | None]:
    """Milliseconds of wall time per simulated second of each pipeline block, and of the ``simulator``
    (the rest of the missions' wall time: physics, sensors, rendering), over ``missions`` given as
    ``(block -> seconds, simulated s, wall s)``. A ratio of sums, so long missions weigh as much as
    their length; missions without the block times or the clocks, or with a non-finite one, are left
    out. None without any."""
    blocks = dict.fromkeys(PIPELINE_BLOCKS, 0.0)
    sim_total = wall_total = 0.0
    for times, sim_s, wall_s in missions:
        values = [times.get(b) for b in PIPELINE_BLOCKS]
        clocks = [sim_s, wall_s, *values]
        if (
            sim_s is None
            or wall_s is None
            or any(v is None or not math.isfinite(v) for v in clocks)
            or sim_s <= 0
        ):
            continue  # missing, or a damaged cell (NaN, inf): this mission says nothing about compute
        for b, v in zip(PIPELINE_BLOCKS, values, strict=True):
            blocks[b] += float(v)  # type: ignore[arg-type]
        sim_total += sim_s
        wall_total += wall_s
    keys = (*PIPELINE_BLOCKS, "simulator")
    if sim_total <= 0:
        return dict.fromkeys(keys)
    out: dict[str, float | None] = {b: 1e3 * v / sim_total for b, v in blocks.items()}
    out["simulator"] = 1e3 * max(wall_total - sum(blocks.values()), 0.0) / sim_total
    return out


def group_statistics(missions: Sequence[MissionFigures]) -> dict[str, Any]:
    """Counts, success rate, Wilson interval and statistics of one group of missions: a ``summary.json``
    group's figures (the report computes its tables and maps with this too, so the two cannot drift).
    Successes and the interval are over the missions that flew; touchdown error and time to land over
    the landed ones; energies and compute over those that flew. Quantiles are numpy's default (linear
    interpolation between order statistics)."""
    n = len(missions)
    flew = [m for m in missions if m.outcome != "error"]
    landed = [m for m in missions if m.outcome == "landed"]
    flown = len(flew)
    successes = sum(1 for m in flew if m.success)
    ci = wilson95(successes, flown)
    return {
        "n": n,
        "n_flown": flown,
        "successes": successes,
        "errors": n - flown,
        "success_rate": successes / flown if flown else None,
        "wilson95": list(ci) if ci is not None else None,
        "touchdown_error_m": _stats(_values(landed, "touchdown_error_m"), ("p50", "p90", "p95", "max")),
        "time_to_land_s": _stats(_values(landed, "time_to_land_s"), ("p50", "mean")),
        "energy_flight_J": _stats(_values(flew, "energy_flight_J"), ("mean",)),
        "energy_compute_J": _stats(_values(flew, "energy_compute_J"), ("mean",)),
        "compute_ms_per_simulated_s": compute_per_simulated_s(
            (
                {b: m.values.get(column) for b, column in BLOCK_TIME_COLUMN.items()},
                m.values.get("simulated_time_s"),
                m.values.get("wall_time_s"),
            )
            for m in flew
        ),
    }


def group_summary(rows: Sequence[Mapping[str, str]]) -> dict[str, Any]:
    """:func:`group_statistics` of one group's results.csv rows held as text, read by the column rules
    (``ValueError`` for a cell that breaks its rule)."""
    return group_statistics([figures_of(r) for r in rows])


def summarize(table: ResultsTable, lock: Mapping[str, Any]) -> dict[str, Any]:
    """summary.json's content for results.csv (as read by ``read_table``) of the campaign described by
    ``lock``."""
    presets = list(lock["presets"])
    by_group: dict[tuple[str, str], list[Mission]] = {}
    for m in table.missions:
        by_group.setdefault((m.preset, m.condition_id), []).append(m)
    groups = []
    for cond in lock["conditions"]:
        for preset in presets:
            members = by_group.get((preset, cond["condition_id"]))
            if not members:
                continue
            groups.append(
                {"preset": preset, "condition_id": cond["condition_id"], "params": cond["params"]}
                | group_statistics(members)
            )
    return {
        "campaign": lock["campaign"],
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "alight_version": alight.__version__,
        "n_missions": len(table.missions),
        "n_planned": len(lock["missions"]),
        "n_errors": sum(1 for m in table.missions if m.outcome == "error"),
        "n_damaged_rows": len(table.damaged),
        "damaged_rows": [d.as_json() for d in table.damaged],
        "results_notes": list(table.notes),
        "presets": presets,
        "swept_parameters": list(lock["swept_parameters"]),
        "groups": groups,
    }


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def read_campaign_table(out_dir: Path, lock: Mapping[str, Any] | None) -> ResultsTable:
    """``out_dir``'s results.csv read by the column rules, its rows checked against ``lock``'s plan when
    there is one (the summary and the report read it so)."""
    path = out_dir / RESULTS_CSV
    if lock is None:
        return read_table(path)
    columns = lock.get("columns")
    columns = [str(c) for c in columns] if isinstance(columns, list) else None
    return read_table(path, expected=expected_cells(lock), columns=columns)


def write_summary(out_dir: str | Path) -> Path:
    """Write ``out_dir/summary.json`` from its results.csv and campaign.lock.json."""
    out = Path(out_dir)
    lock = read_lock(out)
    if lock is None:
        raise InputError(f"{out}: no campaign.lock.json (not a campaign output directory)")
    results = out / RESULTS_CSV
    table = read_campaign_table(out, lock) if results.is_file() else ResultsTable(results, [], [], [])
    path = out / SUMMARY_JSON
    try:
        summary = summarize(table, lock)
    except (KeyError, TypeError, AttributeError) as err:  # a lock file edited by hand, or cut short
        raise InputError(f"{out}: campaign.lock.json lacks what a summary needs ({_one_line(err)})") from None
    write_json(path, summary)
    return path
