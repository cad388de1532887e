"""Run a campaign: expand it, skip what results.csv already holds, fly the rest on an engine, record
each mission as it finishes, then write summary.json and the campaign report.

Output layout (shared with the report): see docs/campaigns.md. Rerunning the same campaign into the
same directory resumes it; a campaign whose missions changed since the directory was started is
refused (use another ``--out``), except that missions may be added (more seeds, more conditions at the
end of the expansion).
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import yaml

import alight
from alight.campaign.engines import (
    CLOCK_FIELDS,
    DEFAULT_MISSION_FN,
    SIMULATED_MISSION_FNS,
    VIEWS_MISSION_FN,
    MissionFn,
    MissionOutcome,
    MissionTask,
    function_spec,
    make_engine,
)
from alight.campaign.spec import Campaign, PlannedMission, load_campaign
from alight.campaign.store import (
    BLOCK_TIME_COLUMN,
    BLOCK_TIME_COLUMNS,
    CAMPAIGN_YAML,
    MISSIONS_DIR,
    RESULT_COLUMNS,
    RESULT_JSON,
    RESULTS_CSV,
    ResultsStore,
    columns_for,
    json_safe,
    read_lock,
    write_lock,
    write_mission_dir,
)
from alight.campaign.summary import write_summary
from alight.compile.warmup import presets_to_warm_up
from alight.errors import AlightError, ConfigError, InputError
from alight.evaluation.result import OUTCOMES

# The result fields a row copies from result.json: the store's columns but those the run sets itself.
_RESULT_KEYS = tuple(
    c
    for c in RESULT_COLUMNS
    if c not in ("outcome", "success", "wall_time_s", "mission_dir", "error", *BLOCK_TIME_COLUMNS)
)


@dataclass
class CampaignRunResult:
    campaign: str
    out_dir: Path
    n_planned: int
    """Missions of the campaign (after ``limit``)."""
    n_skipped: int
    """Of those, already in results.csv before this run."""
    n_run: int
    """Flown (and recorded) by this run."""
    n_errors: int
    """Error rows recorded by this run."""
    wall_time_s: float
    """Wall time of the whole run (s)."""
    summary_path: Path | None
    report_path: Path | None = None
    report_error: str | None = None
    """One line when the campaign report could not be written (the results are complete regardless)."""
    n_recorded: int = 0
    """Rows of this campaign's missions (after ``limit``) in results.csv once the run ended, earlier runs'
    included."""
    n_recorded_errors: int = 0
    """Of those, error rows. ``alight campaign`` exits with status 1 when they are all errors."""
    n_views: int = 0
    """Failures whose views (figures, report.html, replay.gif) this run drew by flying them again."""
    views_problems: list[str] = field(default_factory=list)
    """One line per failure whose views could not be drawn, or whose second flight differed from the
    recorded one (the mission directory's views.txt says more)."""


class CampaignInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped the campaign; every mission recorded so far is kept (``result``)."""

    def __init__(self, message: str, result: CampaignRunResult) -> None:
        super().__init__(message)
        self.message = message
        self.result = result


def lock_data(campaign: Campaign) -> dict[str, Any]:
    """campaign.lock.json: the expanded campaign, for resuming and for ``alight report``."""
    spec = campaign.spec
    return {
        "campaign": campaign.name,
        "alight_version": alight.__version__,
        "campaign_seed": spec.seed,
        "seeds_per_condition": spec.seeds_per_condition,
        "timeout_s": spec.timeout_s,
        "presets": campaign.presets,
        "swept_parameters": campaign.swept_parameters,
        "columns": columns_for(campaign.swept_parameters),
        "conditions": [
            {"condition_id": c.condition_id, "index": c.index, "params": c.params}
            for c in campaign.conditions
        ],
        "missions": [
            {
                "mission_id": m.mission_id,
                "condition_id": m.condition_id,
                "preset": m.preset,
                "replicate": m.replicate,
                "seed": m.seed,
                "params": m.params,
                "scenario": m.scenario,
            }
            for m in campaign.missions
        ],
    }


def _check_resume(out: Path, campaign: Campaign, done_rows: list[dict[str, str]]) -> None:
    """Refuse to resume into a directory whose recorded missions are not this campaign's."""
    if not done_rows:
        return
    hint = "the campaign changed since this output directory was started: use another --out"
    planned = {m.mission_id: m for m in campaign.missions}
    old = read_lock(out)
    old_missions = {m["mission_id"]: m for m in old["missions"]} if old else {}
    for row in done_rows:
        mid = row["mission_id"]
        m = planned.get(mid)
        if m is None:
            raise ConfigError(
                f"{out}: results.csv holds mission {mid}, which this campaign does not have; {hint}"
            )
        if row["seed"] != str(m.seed):
            raise ConfigError(f"{out}: mission {mid} was flown with seed {row['seed']}, now {m.seed}; {hint}")
        before = old_missions.get(mid)
        if before is not None and before.get("scenario") != m.scenario:
            raise ConfigError(f"{out}: mission {mid} has a different scenario now; {hint}")


def _row(m: PlannedMission, outcome: MissionOutcome, mission_dir: str) -> dict[str, Any]:
    row: dict[str, Any] = {
        "mission_id": m.mission_id,
        "condition_id": m.condition_id,
        "preset": m.preset,
        "replicate": m.replicate,
        "seed": m.seed,
        **m.params,
        "mission_dir": mission_dir,
    }
    if outcome.error is None and outcome.result is not None:
        r = outcome.result
        row.update({k: r.get(k) for k in _RESULT_KEYS})
        blocks = r.get("block_time_s")
        if isinstance(blocks, dict):
            row.update({column: blocks.get(b) for b, column in BLOCK_TIME_COLUMN.items()})
        row["outcome"] = r["outcome"]
        row["success"] = bool(r.get("success", r["outcome"] == "landed"))
        row["wall_time_s"] = r.get("wall_time_s", outcome.wall_time_s)
        row["error"] = None
    else:
        row.update({"outcome": "error", "success": False, "wall_time_s": outcome.wall_time_s})
        row["error"] = outcome.error or "unknown error"
    return row


def _record(out: Path, campaign: Campaign, m: PlannedMission, outcome: MissionOutcome) -> dict[str, Any]:
    """Write the mission's directory; the results.csv row that says it is complete."""
    context = {
        "campaign": campaign.name,
        "mission_id": m.mission_id,
        "condition_id": m.condition_id,
        "replicate": m.replicate,
        "params": m.params,
    }
    error_text = None
    if outcome.error is None and outcome.result is not None:
        result = {**outcome.result, "campaign": context}
    else:
        result = {
            "scenario": m.scenario,
            "seed": m.seed,
            "preset": m.preset,
            "outcome": "error",
            "success": False,
            "error": outcome.error,
            "wall_time_s": outcome.wall_time_s,
            "alight_version": alight.__version__,
            "campaign": context,
        }
        error_text = f"{m.mission_id}: {outcome.error}\n\n{outcome.details or ''}"
    rel = write_mission_dir(out, m.mission_id, result, outcome.files, error_text)
    return _row(m, outcome, rel)


VIEWS_TXT = "views.txt"
"""In a mission directory: why its views are missing, or how their flight differed from the recorded one."""
VIEWS_MARK = "report.html"
"""A failure's views are complete once its report.html is written (it is written last)."""
FLOWN_FAILURES = tuple(o for o in OUTCOMES if o not in ("landed", "error"))
"""Outcomes of a mission that flew and did not land: the failures that have views (an error has no log)."""


def views_wanted(
    out: Path, missions: list[PlannedMission], rows: list[dict[str, str]], n: int
) -> list[PlannedMission]:
    """The failures of ``missions`` that should have their views: in each (preset, condition) cell the
    first ``n`` of those recorded as a flown failure, by replicate, leaving out those that have them
    already. The choice depends on the results alone, not on the order in which missions finished."""
    outcome = {r["mission_id"]: r["outcome"] for r in rows}
    cells: dict[tuple[str, str], list[PlannedMission]] = {}
    for m in missions:
        if outcome.get(m.mission_id) in FLOWN_FAILURES:
            cells.setdefault((m.preset, m.condition_id), []).append(m)
    chosen = {
        m.mission_id for failures in cells.values() for m in sorted(failures, key=lambda m: m.replicate)[:n]
    }
    return [
        m
        for m in missions
        if m.mission_id in chosen and not (out / MISSIONS_DIR / m.mission_id / VIEWS_MARK).is_file()
    ]


def _comparable(result: dict[str, Any]) -> dict[str, Any]:
    """A result as result.json holds it, without its clocks and the campaign's context."""
    data = json.loads(json.dumps(json_safe(result)))
    return {k: v for k, v in data.items() if k not in CLOCK_FIELDS and k != "campaign"}


def _differences(recorded: dict[str, Any], again: dict[str, Any]) -> list[str]:
    keys = sorted(set(recorded) | set(again))
    return [f"{k}: {recorded.get(k)!r} -> {again.get(k)!r}" for k in keys if recorded.get(k) != again.get(k)]


def _record_views(out: Path, m: PlannedMission, outcome: MissionOutcome) -> str | None:
    """Add the views that a second flight of ``m`` drew to its mission directory; None, or one line
    saying what went wrong (also written into the directory's views.txt). The views only add files: the
    recorded result.json, scenario.yaml and log stay as the sweep wrote them (they are the record)."""
    target = out / MISSIONS_DIR / m.mission_id
    problem: str | None = None
    detail = ""
    if outcome.error is not None or outcome.result is None:
        problem = f"{m.mission_id}: its views could not be drawn ({outcome.error})"
        detail = outcome.details or ""
    else:
        try:
            recorded = json.loads((target / RESULT_JSON).read_text(encoding="utf-8"))
        except (OSError, ValueError) as err:
            recorded = {"unreadable": str(err)}
        diff = _differences(_comparable(recorded), _comparable(outcome.result))
        if diff:
            problem = (
                f"{m.mission_id}: the flight drawn for its views differed from the recorded one "
                f"({diff[0]}{'; ...' if len(diff) > 1 else ''})"
            )
            detail = "Differences (recorded -> flown again for the views):\n" + "\n".join(diff) + "\n"
        files = {k: v for k, v in outcome.files.items() if not (target / k).exists()}
        if VIEWS_MARK not in files and problem is None:
            problem = f"{m.mission_id}: the flight drawn for its views wrote no {VIEWS_MARK}"
        # report.html last: its presence says the views are complete
        for name in sorted(files, key=lambda k: k == VIEWS_MARK):
            dest = (target / name).resolve()
            if target.resolve() not in dest.parents:
                problem = problem or f"{m.mission_id}: refusing to write {name!r} outside its directory"
                continue
            dest.parent.mkdir(parents=True, exist_ok=True)
            dest.write_bytes(files[name])
    views_txt = target / VIEWS_TXT
    if problem is None:
        views_txt.unlink(missing_ok=True)
    else:
        views_txt.write_text(problem + "\n\n" + detail, encoding="utf-8")
    return problem


def _fly_views(
    out: Path,
    campaign: Campaign,
    wanted: list[PlannedMission],
    runner: Any,
    progress: bool,
    result: CampaignRunResult,
) -> bool:
    """Fly ``wanted`` again on ``runner`` and add their views; True when Ctrl-C stopped it."""
    by_id = {m.mission_id: m for m in wanted}
    tasks = [MissionTask(m.mission_id, m.scenario, campaign.timeout_s) for m in wanted]
    bar = _Progress(f"{campaign.name} views", len(wanted), 0, progress)
    done: set[str] = set()
    interrupted = False
    with _Interrupts() as interrupts:
        outcomes = runner.run(tasks)
        try:
            bar.show()
            for outcome in outcomes:
                if outcome.mission_id in done:
                    continue
                done.add(outcome.mission_id)
                with interrupts.critical():
                    problem = _record_views(out, by_id[outcome.mission_id], outcome)
                result.n_views += int(problem is None)
                if problem is not None:
                    result.views_problems.append(problem)
                bar.update(problem is not None)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            interrupts.ignore()
            outcomes.close()
            bar.close()
    return interrupted


class _Progress:
    """One carriage-return line on stderr, when it is a terminal."""

    def __init__(self, name: str, total: int, done: int, enabled: bool, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = enabled and self.stream.isatty()
        self.name, self.total, self.done, self.errors = name, total, done, 0
        self.t0 = time.monotonic()
        self.flown = 0
        self.width = 0

    def update(self, error: bool) -> None:
        self.done += 1
        self.flown += 1
        self.errors += int(error)
        self.show()

    def show(self) -> None:
        if not self.enabled:
            return
        elapsed = time.monotonic() - self.t0
        text = f"{self.name}: {self.done}/{self.total} missions"
        if self.errors:
            text += f", {self.errors} errors"
        if self.flown:
            eta = elapsed / self.flown * (self.total - self.done)
            text += f", {60.0 * self.flown / max(elapsed, 1e-9):.1f}/min, ETA {_duration(eta)}"
        self.width = max(self.width, len(text))
        self.stream.write("\r" + text.ljust(self.width))
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()


def _duration(seconds: float) -> str:
    s = int(round(seconds))
    if s < 60:
        return f"{s}s"
    if s < 3600:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s // 3600}h{s % 3600 // 60:02d}m"


class _Interrupts:
    """SIGINT raises KeyboardInterrupt, except inside ``critical()`` (recording one mission), where it is
    held until the block ends: a Ctrl-C never leaves half a mission directory or half a row."""

    def __init__(self) -> None:
        self.active = threading.current_thread() is threading.main_thread()
        self.in_critical = False
        self.pending = False
        self.previous: Any = None

    def _handler(self, signum: int, frame: Any) -> None:
        if self.in_critical:
            self.pending = True
            return
        raise KeyboardInterrupt

    def __enter__(self) -> _Interrupts:
        if self.active:
            self.previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def ignore(self) -> None:
        """From now on (cleaning up) a further Ctrl-C is ignored."""
        if self.active:
            signal.signal(signal.SIGINT, signal.SIG_IGN)

    def __exit__(self, *exc: object) -> None:
        if self.active:
            signal.signal(signal.SIGINT, self.previous)

    @contextmanager
    def critical(self) -> Iterator[None]:
        self.in_critical = True
        try:
            yield
        finally:
            self.in_critical = False
        if self.pending:
            self.pending = False
            raise KeyboardInterrupt


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


MAX_PROBLEM_LINES = 20
"""Problems of results.csv printed on stderr when the report is written; the rest are counted (the
report and summary.json list them all)."""


def write_report(out_dir: Path, *, stream: TextIO | None = None) -> tuple[Path | None, str | None]:
    """The campaign report: (path, None); (None, reason) when writing it failed; (None, None) when
    ``alight.campaign.report`` is not installed. What is wrong with results.csv (its damaged rows, left
    out of every figure) is also said on ``stream`` (default stderr), one line each."""
    try:
        from alight.campaign.report import read_results, write_campaign_report
    except ImportError:  # the report is optional: results and summary.json stand on their own
        return None, None
    try:
        res = read_results(out_dir)
        _say_problems(out_dir, [*res.notes, *(d.text() for d in res.damaged)], stream or sys.stderr)
        return Path(write_campaign_report(out_dir, res)), None
    except AlightError as err:
        return None, " ".join(str(err).split())
    except Exception as err:  # noqa: BLE001  (a report failure must never cost the results)
        return None, _one_line(err)


def _say_problems(out_dir: Path, problems: list[str], stream: TextIO) -> None:
    where = out_dir / RESULTS_CSV
    for problem in problems[:MAX_PROBLEM_LINES]:
        print(f"alight: warning: {where}: {problem}", file=stream)
    if len(problems) > MAX_PROBLEM_LINES:
        more = len(problems) - MAX_PROBLEM_LINES
        print(
            f"alight: warning: {where}: {more} more problems (report.html and summary.json list them)",
            file=stream,
        )


def run_campaign(
    campaign: str | Path | Campaign,
    out_dir: str | Path | None = None,
    *,
    engine: str = "local",
    workers: int | None = None,
    scheduler: str | None = None,
    limit: int | None = None,
    progress: bool = False,
    mission_fn: MissionFn | str | None = None,
    report: bool = True,
    warmup: bool | None = None,
    memory_limit_mib: float | None = None,
    views_fn: MissionFn | str | None = None,
    flown_with: dict[str, Any] | None = None,
) -> CampaignRunResult:
    """Fly every mission of ``campaign`` not yet in ``out_dir/results.csv`` (default ``runs/<name>``).

    ``engine``: ``local`` (``workers`` processes, default the CPU count) or ``dask`` (``scheduler`` address,
    or an embedded LocalCluster of ``workers`` processes). ``limit``: only the first ``limit`` missions of
    the campaign's order. ``mission_fn``: what a mission is (default ``engines.fly_mission``), a
    module-level function or ``"module:function"``. ``warmup``: every sandbox flies a short mission of
    each of the campaign's presets before its first mission, so numba's compile stays out of the mission
    clocks (default: only for the default mission function and its views variant). ``memory_limit_mib``:
    a worker process whose memory high-water mark is over it after a mission is replaced by a fresh one.
    ``views_fn``: the mission function that flies a failure again to draw its views, for the first
    ``views_per_cell`` failures of each cell once the sweep is over (default:
    ``engines.fly_mission_views`` for the default missions, none for others); with ``views_per_cell: all``
    it flies every mission instead. ``flown_with``: how the missions are flown when not by alight's own
    simulator (``alight campaign --autopilot``: the autopilot's setting), recorded in the lock so that a
    resume flown another way is refused. Raises ``AlightError`` for bad input and ``CampaignInterrupted``
    on Ctrl-C (after recording what finished and writing summary.json).
    """
    t0 = time.monotonic()
    if not isinstance(campaign, Campaign):
        campaign = load_campaign(campaign)
    if limit is not None and limit < 1:
        raise ConfigError(f"--limit must be >= 1, got {limit}")
    fn_spec, views_spec = _mission_functions(campaign, mission_fn, views_fn)
    # Real missions: every sandbox compiles the campaign's presets' kernels before its first mission, so
    # no mission's clocks or deadline pay for numba's compile. Other mission functions (the tests' fakes)
    # need no warm-up unless asked.
    if warmup is None:
        warmup = fn_spec in SIMULATED_MISSION_FNS
    engine_options: dict[str, Any] = {
        "workers": workers,
        "scheduler": scheduler,
        "memory_limit_mib": memory_limit_mib,
    }
    # a block set's label is not a preset: the sandboxes warm up the presets that fly its blocks
    to_warm = presets_to_warm_up(m.scenario for m in campaign.missions) if warmup else ()
    runner = make_engine(engine, fn_spec=fn_spec, warmup=to_warm, **engine_options)

    out = Path(out_dir) if out_dir is not None else Path("runs") / campaign.name
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"{out}: cannot create the output directory ({err.strerror})") from None
    missions = campaign.missions[:limit] if limit is not None else campaign.missions
    store = ResultsStore.open(out / RESULTS_CSV, columns_for(campaign.swept_parameters))
    try:
        _start_directory(out, campaign, store, flown_with)
        result = _sweep(out, campaign, missions, store, runner, progress, t0)
        views_per_cell = campaign.spec.views_per_cell
        if views_spec is not None and isinstance(views_per_cell, int):
            wanted = views_wanted(out, missions, store.rows, views_per_cell)
            if wanted:
                views_warmup = warmup or views_spec in SIMULATED_MISSION_FNS
                presets = presets_to_warm_up(m.scenario for m in wanted) if views_warmup else ()
                views_runner = make_engine(engine, fn_spec=views_spec, warmup=presets, **engine_options)
                _draw_views(out, campaign, wanted, views_runner, progress, result, t0)
        if report:  # Ctrl-C works again here: the results are complete whatever happens to the report
            result.report_path, result.report_error = write_report(out)
    finally:
        store.close()
    result.wall_time_s = time.monotonic() - t0
    return result


def _mission_functions(
    campaign: Campaign, mission_fn: MissionFn | str | None, views_fn: MissionFn | str | None
) -> tuple[str, str | None]:
    """The sweep's mission function and the one that draws the failures' views (None: no views flight),
    by ``views_per_cell``: ``all`` flies the views function in the sweep, 0 draws none."""
    fn_spec = function_spec(mission_fn)
    if views_fn is not None:
        views_spec: str | None = function_spec(views_fn)
    else:
        views_spec = VIEWS_MISSION_FN if fn_spec == DEFAULT_MISSION_FN else None
    views_per_cell = campaign.spec.views_per_cell
    if views_spec is None and "views_per_cell" in campaign.spec.model_fields_set:
        raise ConfigError(
            f"views_per_cell: the mission function {fn_spec} writes its own files and has no views "
            "function to draw them (give views_fn, or leave views_per_cell out)"
        )
    if views_per_cell == "all" and views_spec is not None:
        # every failure's views from its one flight: the sweep flies the views function itself
        return views_spec, None
    if views_per_cell == 0:
        return fn_spec, None
    return fn_spec, views_spec


def _start_directory(
    out: Path, campaign: Campaign, store: ResultsStore, flown_with: dict[str, Any] | None = None
) -> None:
    """Check that ``out``'s recorded missions are this campaign's, flown the same way; write its
    campaign.yaml and lock (with ``flown_with``)."""
    _check_resume(out, campaign, store.rows)
    if store.rows:
        before = (read_lock(out) or {}).get("flown_with")
        if before != flown_with:
            raise ConfigError(
                f"{out}: its missions were flown with {before or 'alight sim'}, now with "
                f"{flown_with or 'alight sim'}: use another --out"
            )
    text = campaign.text
    if text is None:
        text = yaml.safe_dump(campaign.spec.model_dump(mode="json", exclude_none=True), sort_keys=False)
    (out / CAMPAIGN_YAML).write_text(text, encoding="utf-8")
    write_lock(out, {**lock_data(campaign), "flown_with": flown_with})


def _sweep(
    out: Path,
    campaign: Campaign,
    missions: list[PlannedMission],
    store: ResultsStore,
    runner: Any,
    progress: bool,
    t0: float,
) -> CampaignRunResult:
    """Fly the ``missions`` not yet in ``store`` on ``runner``, recording each as it finishes, then write
    summary.json; ``CampaignInterrupted`` on Ctrl-C, after that."""
    pending = [m for m in missions if m.mission_id not in store.done]
    bar = _Progress(campaign.name, len(missions), len(missions) - len(pending), progress)
    result = CampaignRunResult(
        campaign=campaign.name,
        out_dir=out,
        n_planned=len(missions),
        n_skipped=len(missions) - len(pending),
        n_run=0,
        n_errors=0,
        wall_time_s=0.0,
        summary_path=None,
    )
    interrupted = False
    with _Interrupts() as interrupts:
        outcomes = runner.run([MissionTask(m.mission_id, m.scenario, campaign.timeout_s) for m in pending])
        try:
            bar.show()
            _record_outcomes(out, campaign, pending, outcomes, store, interrupts, bar, result)
            _record_lost(out, campaign, pending, runner.name, store, interrupts, bar, result)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            interrupts.ignore()
            outcomes.close()  # stops the engine: pending work cancelled, worker processes killed
            bar.close()
        ours = {m.mission_id for m in missions}
        recorded = [r for r in store.rows if r["mission_id"] in ours]
        result.n_recorded = len(recorded)
        result.n_recorded_errors = sum(r["outcome"] == "error" for r in recorded)
        result.summary_path = write_summary(out)
        if interrupted:
            result.wall_time_s = time.monotonic() - t0
            raise CampaignInterrupted(
                f"interrupted: {result.n_skipped + result.n_run} of {len(missions)} missions recorded in "
                f"{out}; run the same command again to resume",
                result,
            )
    return result


def _record_outcomes(
    out: Path,
    campaign: Campaign,
    pending: list[PlannedMission],
    outcomes: Iterator[MissionOutcome],
    store: ResultsStore,
    interrupts: _Interrupts,
    bar: _Progress,
    result: CampaignRunResult,
) -> None:
    by_id = {m.mission_id: m for m in pending}
    for outcome in outcomes:
        if outcome.mission_id in store.done:  # one row per mission, whatever an engine repeats
            continue
        with interrupts.critical():
            row = _record(out, campaign, by_id[outcome.mission_id], outcome)
            store.append(row)
        result.n_run += 1
        result.n_errors += int(row["outcome"] == "error")
        bar.update(row["outcome"] == "error")


def _record_lost(
    out: Path,
    campaign: Campaign,
    pending: list[PlannedMission],
    engine_name: str,
    store: ResultsStore,
    interrupts: _Interrupts,
    bar: _Progress,
    result: CampaignRunResult,
) -> None:
    """Never silently drop a mission: one the engine gave no outcome for is an error row."""
    for m in pending:
        if m.mission_id not in store.done:
            lost = MissionOutcome(
                m.mission_id,
                None,
                error="lost: the engine ended without a result for this mission",
                details=f"The {engine_name} engine returned nothing for {m.mission_id}.\n",
            )
            with interrupts.critical():
                store.append(_record(out, campaign, m, lost))
            result.n_run += 1
            result.n_errors += 1
            bar.update(True)


def _draw_views(
    out: Path,
    campaign: Campaign,
    wanted: list[PlannedMission],
    views_runner: Any,
    progress: bool,
    result: CampaignRunResult,
    t0: float,
) -> None:
    """Fly ``wanted`` again for their views; ``CampaignInterrupted`` on Ctrl-C (every result is kept)."""
    try:
        stopped = _fly_views(out, campaign, wanted, views_runner, progress, result)
    except (AlightError, OSError) as err:
        # The engine could not fly the views (workers that die at start-up, a lost
        # scheduler): every result is recorded, and the report is still written.
        stopped = False
        result.views_problems.append(
            f"the views of {len(wanted)} failures were not drawn ({_one_line(err)}); "
            "run the same command again to draw them"
        )
    if stopped:
        result.wall_time_s = time.monotonic() - t0
        raise CampaignInterrupted(
            f"interrupted while drawing the views of failures: all {result.n_recorded} missions "
            f"are recorded in {out}; run the same command again to draw the rest",
            result,
        )
