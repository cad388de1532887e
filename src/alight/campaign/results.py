"""results.csv: its columns, the writer's cell rule, one reading rule per column, and the one reader.

summary.json, report.html and a resumed campaign all read results.csv here, so they cannot disagree:

- :func:`read_table` (the summary and the report) reads every row by :data:`COLUMNS`' rules. A row that
  breaks a rule is a *damaged row*: it is left out of every figure and named (:class:`Damage`: its line,
  its mission, what is wrong), never dropped in silence and never read as something else. A file that
  is not a campaign's results.csv (no header, a required column missing or renamed, a column twice) is
  refused with one ``InputError`` line.
- :func:`read_rows` (the store, when a campaign resumes) reads the same lines with the same header rule,
  and refuses any structural damage with one line: a campaign appends only to a file it can trust.

The writer (:func:`cell`) writes one physical line per row (text is made one line, JSON is compact), so
the reader parses each line on its own: a damaged line cannot swallow the lines after it. A last line
without its newline is a row cut short by a kill: left out (and named), and removed by a resume, which
flies that mission again.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import typing
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from alight.errors import InputError
from alight.evaluation.result import OUTCOMES, MissionResult
from alight.types import PIPELINE_BLOCKS

RESULTS_CSV = "results.csv"

ID_COLUMNS = ("mission_id", "condition_id", "preset", "replicate", "seed")
BLOCK_TIME_COLUMN = {block: f"{block}_time_s" for block in PIPELINE_BLOCKS}
"""The column of each pipeline block's wall time in the mission (s), from ``result.json``'s
``block_time_s``."""
BLOCK_TIME_COLUMNS = tuple(BLOCK_TIME_COLUMN.values())
RESULT_COLUMNS = (*MissionResult.columns(), "mission_dir", "error")
"""The result columns, from :class:`alight.evaluation.result.MissionResult` (the one list)."""
NUMERIC_COLUMNS = MissionResult.numeric_columns()

MAX_MAGNITUDE = 1e9
"""Largest magnitude a numeric cell may hold, in its SI unit: no figure alight records comes near it
(1e9 s is 31 years, 1e9 J a month of a 400 W multirotor, 1e9 detections 300 years at 100 Hz). A larger
value is damage; the bound also keeps the sums of 100,000 missions finite and their plots drawable."""

Kind = Literal["id", "int", "outcome", "flag", "number", "count", "text"]


@dataclass(frozen=True)
class Column:
    """One column's reading rule. An empty cell is None (no value) unless the column is ``required``."""

    name: str
    kind: Kind
    """``id``: a name matching ``pattern``; ``int``: a whole number >= 0; ``outcome``: one of
    :data:`OUTCOMES`; ``flag``: ``0`` or ``1``; ``number``: finite, in [``low``, :data:`MAX_MAGNITUDE`];
    ``count``: a whole ``number``; ``text``: anything decodable."""
    required: bool = False
    pattern: str = ""
    low: float = 0.0


_NAME = r"[A-Za-z0-9][A-Za-z0-9._+-]{0,199}"


def _result_kind(name: str) -> Kind:
    hints = typing.get_type_hints(MissionResult)
    if name not in hints:
        return "number"  # a block's time
    args = set(typing.get_args(hints[name])) or {hints[name]}
    return "flag" if bool in args else "count" if int in args else "number"


_SIGNED_COLUMNS = ("touchdown_rel_vertical_speed_mps", "touchdown_platform_turn_rate_rad_s")
"""The numeric result columns that may be negative (a turn to the right is a negative rate)."""

COLUMNS: tuple[Column, ...] = (
    Column("mission_id", "id", required=True, pattern=_NAME),
    Column("condition_id", "id", required=True, pattern=r"c[0-9]{3,9}"),
    Column("preset", "id", required=True, pattern=r"[A-Za-z0-9][A-Za-z0-9._+-]{0,59}"),  # a BlockSet name
    Column("replicate", "int"),
    Column("seed", "int"),
    Column("outcome", "outcome", required=True),
    Column("success", "flag", required=True),
    *(
        Column(c, _result_kind(c), low=-MAX_MAGNITUDE if c in _SIGNED_COLUMNS else 0.0)
        for c in RESULT_COLUMNS
        if c not in ("outcome", "success", "mission_dir", "error")
    ),
    Column("mission_dir", "text"),
    Column("error", "text"),
)
"""Every column a campaign writes but the swept parameters, which are ``text`` (their values are checked
against the campaign's lock file when it is given)."""
COLUMN = {c.name: c for c in COLUMNS}
_PATTERN = {c.pattern: re.compile(c.pattern) for c in COLUMNS if c.pattern}
REQUIRED = tuple(c.name for c in COLUMNS if c.required)
_PARAMETER = Column("", "text")


def columns_for(swept_parameters: Sequence[str]) -> list[str]:
    """results.csv's header for a campaign sweeping ``swept_parameters`` (dotted paths)."""
    return [*ID_COLUMNS, *swept_parameters, *RESULT_COLUMNS]


def cell(value: Any) -> str:
    """A value as a results.csv cell: empty for missing or non-finite, 0/1 for booleans, the shortest
    round-trip repr for floats, JSON for lists and mappings, one line for text."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    if isinstance(value, list | tuple | dict):
        return json.dumps(value, separators=(",", ":"))
    return " ".join(str(value).split())


# --------------------------------------------------------------------------------------------------
# one cell
# --------------------------------------------------------------------------------------------------


def _shown(text: str, limit: int = 40) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "...") + (
        f" ({len(text):,} characters)" if len(text) > limit else ""
    )


_NOT_TEXT = re.compile("[\x00\ud800-\udfff]")
"""A NUL, or a byte that is not UTF-8 (read as a lone surrogate)."""


def read_cell(column: Column, text: str) -> tuple[Any, str | None]:
    """``(value, None)``, or ``(None, problem)`` for a cell that breaks ``column``'s rule. Surrounding
    whitespace is ignored (the writer writes none, a spreadsheet may add it)."""
    if _NOT_TEXT.search(text):
        return None, f"{column.name or 'cell'}: not text (undecodable bytes or a NUL)"
    return _read_text(column, text.strip())


def _read_text(column: Column, s: str) -> tuple[Any, str | None]:
    """:func:`read_cell` of a stripped cell known to be text."""
    if s == "":
        return None, f"{column.name}: empty" if column.required else None
    kind = column.kind
    if kind == "text":
        return s, None
    if kind == "number" or kind == "count":
        return _read_number(column, s)
    if kind == "id":
        ok = _PATTERN[column.pattern].fullmatch(s) is not None
        return (s, None) if ok else (None, f"{column.name}: {_shown(s)} is not a {column.name}")
    if kind == "outcome":
        return (
            (s, None)
            if s in OUTCOMES
            else (None, f"outcome: {_shown(s)} is not one of {', '.join(OUTCOMES)}")
        )
    if kind == "flag":
        return (s == "1", None) if s in ("0", "1") else (None, f"{column.name}: {_shown(s)} is not 0 or 1")
    ok = s.isascii() and s.isdigit() and len(s) <= 20
    return (int(s), None) if ok else (None, f"{column.name}: {_shown(s)} is not a whole number >= 0")


def _read_number(column: Column, s: str) -> tuple[float | None, str | None]:
    try:
        value = float(s)
    except ValueError:
        return None, f"{column.name}: {_shown(s)} is not a number"
    if not (math.isfinite(value) and column.low <= value <= MAX_MAGNITUDE):
        low = "0" if column.low == 0 else f"{column.low:g}"
        return None, f"{column.name}: {_shown(s)} is outside [{low}, {MAX_MAGNITUDE:g}]"
    if column.kind == "count" and not value.is_integer():
        return None, f"{column.name}: {_shown(s)} is not a whole number"
    return value, None


# --------------------------------------------------------------------------------------------------
# the lines of the file
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Lines:
    header: list[str]
    lines: list[tuple[int, str]]
    """(line number, text) of every line after the header, the blank ones left out."""
    cut: tuple[int, str] | None
    """The last line when it has no newline (a row cut short by a kill)."""
    blank: int


@contextmanager
def _field_limit(n: int) -> Iterator[None]:
    """csv's field-size limit raised to ``n`` (a long error message is a legal cell), then restored."""
    before = csv.field_size_limit()
    csv.field_size_limit(max(before, n))
    try:
        yield
    finally:
        csv.field_size_limit(before)


def _cells(text: str) -> list[str]:
    """One line's cells; ``csv.Error`` for a line the writer cannot have written (a stray quote)."""
    return next(csv.reader([text], strict=True), [])


def _read_lines(path: Path, *, strict: bool, repair: bool = False) -> _Lines:
    """The header (checked by name) and the lines of ``path``; ``InputError`` for a file that is not a
    campaign's results.csv. ``strict``: undecodable bytes refuse the file (else they damage their row)."""
    try:
        data = path.read_bytes()
    except OSError as err:
        raise InputError(f"{path}: cannot read ({err.strerror})") from None
    if repair and data and not data.endswith(b"\n"):
        keep = data.rfind(b"\n") + 1
        with path.open("r+b") as f:
            f.truncate(keep)
            f.flush()
            os.fsync(f.fileno())
        data = data[:keep]
    try:
        text = data.decode("utf-8", "strict" if strict else "surrogateescape")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text file") from None
    text = text.removeprefix("\ufeff")  # a spreadsheet's byte-order mark
    raw = text.split("\n")
    cut = raw.pop() if raw else ""  # after the last newline: "" or a line cut short
    numbered = [(k, line.removesuffix("\r")) for k, line in enumerate(raw, start=1)]
    if not numbered:
        raise InputError(f"{path}: no header line (an empty or cut-off results.csv)")
    with _field_limit(len(text) + 1):
        try:
            header = [c.strip() for c in _cells(numbered[0][1])]
        except csv.Error as err:
            raise InputError(f"{path}: line 1: not a results.csv header ({err})") from None
    _check_header(path, header)
    lines = [(k, t) for k, t in numbered[1:] if t.strip()]
    cut_line = (len(raw) + 1, cut) if cut.strip() else None
    return _Lines(header, lines, cut_line, len(numbered) - 1 - len(lines))


def _check_header(path: Path, header: list[str]) -> None:
    twice = sorted({c for c in header if header.count(c) > 1})
    if twice:
        raise InputError(f"{path}: the column {twice[0]!r} appears twice in the header")
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        shown = ", ".join(_shown(c, 30) for c in header[:8]) + (", ..." if len(header) > 8 else "")
        raise InputError(
            f"{path}: not a campaign results.csv: no {', '.join(missing)} column "
            f"(a campaign's has {', '.join(REQUIRED)}; this one has {shown or 'no columns'})"
        )


def read_header(path: str | Path) -> list[str]:
    """results.csv's header, checked as :func:`read_rows` checks it."""
    return _read_lines(Path(path), strict=True).header


def read_rows(path: str | Path, *, repair: bool = False) -> list[dict[str, str]]:
    """The rows of a results.csv as text (column -> cell), for the store. A last line without its newline
    (a write cut short by a kill) is ignored, and with ``repair`` removed from the file. Any other damage
    (a line of the wrong length, a mission twice, undecodable bytes) raises ``InputError``."""
    p = Path(path)
    lines = _read_lines(p, strict=True, repair=repair)
    header = lines.header
    rows: list[dict[str, str]] = []
    seen: set[str] = set()
    with _field_limit(p.stat().st_size + 1):
        for number, text in lines.lines:
            try:
                values = _cells(text)
            except csv.Error as err:
                raise InputError(f"{p}: line {number}: not a results.csv row ({err})") from None
            if len(values) != len(header):
                raise InputError(f"{p}: line {number} has {len(values)} cells, the header {len(header)}")
            row = dict(zip(header, values, strict=True))
            if row["mission_id"] in seen:
                raise InputError(f"{p}: line {number}: mission {row['mission_id']} appears twice")
            seen.add(row["mission_id"])
            rows.append(row)
    if lines.blank:
        raise InputError(f"{p}: {lines.blank} blank line(s) among the rows")
    return rows


# --------------------------------------------------------------------------------------------------
# the rows, read by the column rules
# --------------------------------------------------------------------------------------------------


@dataclass
class Mission:
    """One undamaged row of results.csv, read by the column rules."""

    mission_id: str
    condition_id: str
    preset: str
    params: dict[str, str]
    """Swept parameter (dotted path) -> cell text ('' when the condition does not set it)."""
    outcome: str
    success: bool
    values: dict[str, float | None]
    """Numeric result columns (SI units, as in results.csv); None for an empty cell."""
    replicate: str = ""
    seed: str = ""
    mission_dir: str = ""
    error: str = ""
    line: int = 0
    """Its line in results.csv (1 is the header)."""

    @property
    def flew(self) -> bool:
        return self.outcome != "error"


@dataclass(frozen=True)
class Damage:
    """A row left out of every figure, and why."""

    line: int
    mission_id: str
    """As far as it can be read ('' when it cannot)."""
    problem: str

    def text(self) -> str:
        who = f" ({self.mission_id})" if self.mission_id else ""
        return f"line {self.line}{who}: {self.problem}"

    def as_json(self) -> dict[str, Any]:
        return {"line": self.line, "mission_id": self.mission_id, "problem": self.problem}


@dataclass
class ResultsTable:
    """results.csv read by :func:`read_table`."""

    path: Path
    header: list[str]
    swept: list[str]
    missions: list[Mission]
    """The undamaged rows, in file order: every figure is computed from these."""
    damaged: list[Damage] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    """What is wrong with the file as a whole (columns missing or unexpected, blank lines)."""

    def problems(self) -> list[str]:
        """One line per note and per damaged row."""
        return [*self.notes, *(d.text() for d in self.damaged)]


Expected = Mapping[str, Mapping[str, str]]
"""mission id -> the cells its row must hold (condition, preset, seed, swept parameters), as the writer
writes them; from the campaign's lock file (:func:`expected_cells`)."""


def expected_cells(lock: Mapping[str, Any]) -> dict[str, dict[str, str]] | None:
    """What each planned mission's row must hold, from campaign.lock.json; None when its missions are not
    readable (the rows are then checked by their own rules only)."""
    try:
        return {
            str(m["mission_id"]): {
                "condition_id": str(m["condition_id"]),
                "preset": str(m["preset"]),
                "seed": cell(m["seed"]),
                **{str(p): cell(v) for p, v in dict(m["params"]).items()},
            }
            for m in lock["missions"]
        }
    except (KeyError, TypeError, ValueError, AttributeError):
        return None


def read_table(
    path: str | Path, *, expected: Expected | None = None, columns: Sequence[str] | None = None
) -> ResultsTable:
    """results.csv read by the column rules: the undamaged rows, the damaged ones named. ``columns``:
    the header the campaign wrote (its lock file's); a column missing or unexpected is then a note, and
    the swept parameters are the campaign's. ``expected``: each mission's cells from the lock file; a row
    of a mission the campaign does not have, or whose ids, seed or parameters differ, is damaged.
    ``InputError`` for a file that is not a campaign's results.csv."""
    p = Path(path)
    lines = _read_lines(p, strict=False)
    header = lines.header
    known = set(ID_COLUMNS) | set(RESULT_COLUMNS)
    swept = (
        [c for c in header if c not in known] if columns is None else [c for c in columns if c not in known]
    )
    table = ResultsTable(p, header, swept, [])
    table.notes += _column_notes(header, columns)
    if lines.blank:
        table.notes.append(f"{lines.blank} blank line(s) ignored")
    seen: dict[str, int] = {}
    with _field_limit(p.stat().st_size + 1):
        for number, text in lines.lines:
            _read_line(table, number, text, seen, expected)
    if lines.cut is not None:
        number, text = lines.cut
        why = "cut short (no newline at the end of the file): a row being written when the campaign stopped"
        table.damaged.append(Damage(number, _first_cell(text), why))
    return table


def _column_notes(header: list[str], columns: Sequence[str] | None) -> list[str]:
    if columns is None:
        return []
    notes = []
    missing = [c for c in columns if c not in header]
    extra = [c for c in header if c not in columns]
    if missing:
        notes.append(f"results.csv has no {', '.join(missing)} column(s): their figures are missing")
    if extra:
        shown = ", ".join(_shown(c, 30) for c in extra[:5]) + (", ..." if len(extra) > 5 else "")
        notes.append(f"results.csv has column(s) the campaign does not write, ignored: {shown}")
    return notes


def _first_cell(text: str) -> str:
    head = text.split(",", 1)[0].strip()
    return head if re.fullmatch(_NAME, head) else ""


def _read_line(
    table: ResultsTable, number: int, text: str, seen: dict[str, int], expected: Expected | None
) -> None:
    """Read one line into ``table``: a :class:`Mission`, or a :class:`Damage` naming its problems."""
    try:
        values = _cells(text)
    except csv.Error as err:
        table.damaged.append(Damage(number, _first_cell(text), f"not a results.csv row ({err})"))
        return
    header = table.header
    if len(values) != len(header):
        table.damaged.append(
            Damage(number, _first_cell(text), f"has {len(values)} cells, the header {len(header)}")
        )
        return
    row = dict(zip(header, values, strict=True))
    read: dict[str, Any] = {}
    problems: list[str] = []
    is_text = _NOT_TEXT.search(text) is None  # then no cell needs the check
    for name, text_cell in row.items():
        column = COLUMN.get(name, _PARAMETER)
        value, trouble = _read_text(column, text_cell.strip()) if is_text else read_cell(column, text_cell)
        read[name] = value
        if trouble is not None:
            problems.append(trouble if name in COLUMN else f"{_shown(name, 30)}: {trouble}")
    mid = read.get("mission_id") or ""
    problems += _row_problems(row, read, seen, number, expected)
    if problems:
        table.damaged.append(Damage(number, mid, "; ".join(problems)))
        return
    seen[mid] = number
    table.missions.append(_mission(row, read, table.swept, number))


def _row_problems(
    row: Mapping[str, str],
    read: Mapping[str, Any],
    seen: Mapping[str, int],
    number: int,
    expected: Expected | None,
) -> list[str]:
    """What is wrong with a row whose cells are each readable: a repeated mission, an error counted as a
    success, ids that disagree with each other or with the campaign's plan."""
    mid, cid, preset, rep = (read.get(k) for k in ("mission_id", "condition_id", "preset", "replicate"))
    if not (mid and cid and preset):
        return []  # already damaged
    if mid in seen:
        return [f"mission_id: repeats line {seen[mid]}"]
    problems = []
    if read.get("outcome") == "error" and read.get("success"):
        problems.append("success: 1 for an error (a mission that did not fly)")
    if isinstance(rep, int) and mid != f"{cid}-{preset}-r{rep:03d}":
        problems.append(f"mission_id: does not match condition {cid}, preset {preset}, replicate {rep}")
    if expected is not None:
        plan = expected.get(mid)
        if plan is None:
            return [*problems, "mission_id: not a mission of this campaign (campaign.lock.json)"]
        for name, want in plan.items():
            if name in row and row[name].strip() != want:
                problems.append(f"{name}: {_shown(row[name].strip())}, the campaign planned {_shown(want)}")
    return problems


def _mission(row: Mapping[str, str], read: Mapping[str, Any], swept: Sequence[str], number: int) -> Mission:
    return Mission(
        mission_id=read["mission_id"],
        condition_id=read["condition_id"],
        preset=read["preset"],
        params={p: row.get(p, "").strip() for p in swept},
        outcome=read["outcome"],
        success=read["success"],
        values={c: read.get(c) for c in NUMERIC_COLUMNS},
        replicate=row.get("replicate", "").strip(),
        seed=row.get("seed", "").strip(),
        mission_dir=row.get("mission_dir", "").strip(),
        error=row.get("error", "").strip(),
        line=number,
    )


def figures_of(row: Mapping[str, str]) -> Mission:
    """One row's figures by the column rules, for statistics over rows held as text (``ValueError``
    naming the cell when one breaks its rule)."""
    read: dict[str, Any] = {}
    for name in ("outcome", "success", *NUMERIC_COLUMNS):
        value, problem = read_cell(COLUMN[name], row.get(name, ""))
        if problem is not None:
            raise ValueError(problem)
        read[name] = value
    return Mission("", "", "", {}, read["outcome"], read["success"], {c: read[c] for c in NUMERIC_COLUMNS})


def write_csv_line(values: Sequence[str]) -> str:
    """One row as the writer writes it (one physical line)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


__all__ = [
    "BLOCK_TIME_COLUMN",
    "BLOCK_TIME_COLUMNS",
    "COLUMNS",
    "ID_COLUMNS",
    "MAX_MAGNITUDE",
    "NUMERIC_COLUMNS",
    "RESULTS_CSV",
    "RESULT_COLUMNS",
    "Column",
    "Damage",
    "Mission",
    "ResultsTable",
    "cell",
    "columns_for",
    "expected_cells",
    "read_cell",
    "read_header",
    "read_rows",
    "read_table",
]
