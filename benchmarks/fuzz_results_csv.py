"""Fuzzer of ``alight report``: damaged results.csv files must be refused in one line or reported honestly.

Run: ``python benchmarks/fuzz_results_csv.py [--n N] [--seed S] [--keep DIR]`` (prints JSON).

The input is a real results.csv: a small campaign (3 speeds x 2 presets x 3 seeds, 18 missions) flown by
the campaign engine with the test fake ``campaign_fakes.by_speed`` (landed or crashed by the seed, an
error at 2 m/s), with its campaign.lock.json. Each variant damages a copy of it in 1 to 3 ways, drawn
from :data:`ROW_DAMAGE` (a cell of a given column made unreadable or implausible: ``garbage``, ``NaN``,
``inf``, ``1e308``, ``-1``, a 1 MB cell, NUL and non-UTF-8 bytes, a stray quote, another row's ids; a row
cut short, with a cell too many, copied, or cut at the end of the file), :data:`HARMLESS` (what a
spreadsheet does: spaces around cells, CRLF, a byte-order mark, blank lines, rows reordered, a 1 MB error
message) and :data:`FILE_DAMAGE` (empty, header only, binary garbage, a required column renamed or
removed, an optional one renamed or removed, a column twice, the header repeated among the rows). Then
``alight report DIR`` runs (in this process, as the command runs: ``alight.cli.main``) and the variant is
classified:

* ``refused``: exit status 2, one line on stderr, no traceback;
* ``reported``: exit status 0, and summary.json's groups and report.html's per-preset success counts
  equal the figures recomputed from the undamaged rows alone (the clean file without the damaged rows,
  through the same statistics), and every damaged line is named: in summary.json's ``damaged_rows``, in
  report.html's Damaged rows table and on stderr (its first lines; the rest are counted there); a removed
  or renamed optional column is named in summary.json's ``results_notes``;
* ``FAILURE``: anything else: an exception (a traceback), another exit status, a refusal in more than
  one line, figures that differ, a damaged line not named or a harmless one named.

Deterministic: the damage comes from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import re
import shutil
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "campaign"))  # campaign_fakes, imported by name by the sandboxes

MB = 1 << 20
REQUIRED = ("mission_id", "condition_id", "preset", "outcome", "success")


# --------------------------------------------------------------------------------------------------
# the clean campaign
# --------------------------------------------------------------------------------------------------


def build_base(work: Path) -> Path:
    """A real campaign directory of 18 missions (6 of them errors), flown with the test fakes."""
    import os

    from alight.campaign import campaign_from_dict, run_campaign

    fakes = str(ROOT / "tests" / "campaign")
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (fakes, os.environ.get("PYTHONPATH")) if p)
    spec = {
        "name": "fuzz",
        "base": {"duration_s": 10.0},
        "presets": ["groundtruth", "falanga2017"],
        "seeds_per_condition": 3,
        "seed": 11,
        "grid": {"platform.speed_mps": [1.0, 1.5, 2.0]},
        "timeout_s": 60.0,
    }
    out = work / "base"
    run_campaign(campaign_from_dict(spec), out, workers=1, mission_fn="campaign_fakes:by_speed", report=False)
    return out


@dataclass
class Line:
    """One physical line of a variant: its text (bytes), the clean row it comes from (None: header or an
    inserted line), and whether it is damaged (must be named and left out)."""

    data: bytes
    row: int | None
    damaged: bool = False


@dataclass
class Variant:
    lines: list[Line]
    header: list[str]
    kinds: list[str] = field(default_factory=list)
    dropped_column: str | None = None
    """An optional column removed or renamed: the figures are recomputed without it."""
    expect_refusal: bool = False
    raw: bytes | None = None
    """The whole file, when a damage replaces it (empty, binary garbage)."""
    no_final_newline: bool = False

    def data(self) -> bytes:
        if self.raw is not None:
            return self.raw
        text = b"".join(line.data + b"\n" for line in self.lines)
        return text[:-1] if self.no_final_newline else text


def _csv_line(cells: list[str]) -> bytes:
    buf = io.StringIO()
    import csv

    csv.writer(buf, lineterminator="").writerow(cells)
    return buf.getvalue().encode("utf-8", "surrogateescape")


def _cells(line: Line) -> list[str]:
    """A line's cells, a 1 MB one included (the limit is put back: the reader under test has its own)."""
    import csv

    before = csv.field_size_limit()
    csv.field_size_limit(1 << 30)
    try:
        return next(csv.reader([line.data.decode("utf-8", "surrogateescape")]))
    finally:
        csv.field_size_limit(before)


# --------------------------------------------------------------------------------------------------
# damage
# --------------------------------------------------------------------------------------------------

NUMERIC_BAD = [
    "garbage",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1",
    "1e999",
    "1,5",
    "\x00",
    "9" * MB,
    "0x1p3",
]
SUCCESS_BAD = ["garbage", "NaN", "2", "", "yes", "-1", "1.0", "x" * MB]
OUTCOME_BAD = ["garbage", "", "LANDED", "landed!", "error;", "\x00", "x" * MB]
ID_BAD = ["", "a b", "x\x00", "c\x01", "z" * MB, "garbage!"]
BINARY = bytes(b for b in range(256) if b not in (0x0A, 0x0D, 0x2C, 0x22))  # no newline, comma, quote


def _one(rng: np.random.Generator, values: Any) -> Any:
    """One of ``values`` (not ``rng.choice``: numpy's string arrays drop a value's trailing NULs)."""
    values = list(values)
    return values[int(rng.integers(len(values)))]


def _pick_rows(rng: np.random.Generator, v: Variant, k: int = 1) -> list[Line]:
    rows = [line for line in v.lines if line.row is not None and not line.damaged]
    if not rows:
        return []
    return [rows[i] for i in rng.choice(len(rows), size=min(k, len(rows)), replace=False)]


def _set_cell(line: Line, header: list[str], column: str, value: str) -> None:
    cells = _cells(line)
    cells[header.index(column)] = value
    line.data = _csv_line(cells)
    line.damaged = True


def _signed(column: str) -> bool:
    """A column whose value has a meaningful sign, where -1 is a plausible value: a vertical speed, the
    platform's turn rate at contact (negative: turning clockwise)."""
    return "vertical" in column or "turn_rate" in column


def _bad_cell(rng: np.random.Generator, v: Variant) -> None:
    """A cell of a column that has a rule made unreadable or implausible for it."""
    numeric = [
        c for c in v.header if c.endswith(("_s", "_m", "_J", "_mps")) or c in ("detections", "go_arounds")
    ]
    ids = [c for c in ("success", "outcome", "preset", "condition_id", "mission_id", "seed") if c in v.header]
    column = str(_one(rng, [*ids, *numeric]))
    if column == "success":
        value = str(_one(rng, SUCCESS_BAD))
    elif column == "outcome":
        value = str(_one(rng, OUTCOME_BAD))
    elif column in ("preset", "condition_id", "mission_id"):
        value = str(_one(rng, ID_BAD))
    elif column == "seed":
        value = str(_one(rng, ["garbage", "-1", "1.5", "12345678901234567890123", "4"]))
    else:
        value = str(_one(rng, [x for x in NUMERIC_BAD if not (x == "-1" and _signed(column))]))
    for line in _pick_rows(rng, v):
        _set_cell(line, v.header, column, value)


def _other_ids(rng: np.random.Generator, v: Variant) -> None:
    """A row's preset, condition, replicate or swept value swapped for another row's valid one."""
    rows = _pick_rows(rng, v, 2)
    if len(rows) < 2:
        return
    a, b = rows
    candidates = [c for c in ("preset", "condition_id", "replicate", "platform.speed_mps") if c in v.header]
    i = v.header.index(str(_one(rng, candidates)))
    ca, cb = _cells(a), _cells(b)
    if ca[i] != cb[i]:
        _set_cell(a, v.header, v.header[i], cb[i])


def _numeric_1e308(rng: np.random.Generator, v: Variant) -> None:
    columns = [c for c in ("controller_time_s", "wall_time_s", "energy_flight_J") if c in v.header]
    for line in _pick_rows(rng, v):
        _set_cell(line, v.header, str(_one(rng, columns)), "1e308")


def _binary_in_row(rng: np.random.Generator, v: Variant) -> None:
    for line in _pick_rows(rng, v):
        at = int(rng.integers(0, len(line.data) + 1))
        junk = bytes(rng.choice(list(BINARY[128:]), size=int(rng.integers(1, 8))))
        line.data = line.data[:at] + junk + line.data[at:]
        line.damaged = True


def _stray_quote(rng: np.random.Generator, v: Variant) -> None:
    if "wall_time_s" not in v.header:
        return
    for line in _pick_rows(rng, v):
        cells = _cells(line)
        i = v.header.index("wall_time_s")
        line.data = _csv_line(cells[:i]) + b',"' + cells[i].encode() + b"," + _csv_line(cells[i + 1 :])
        line.damaged = True


def _short_row(rng: np.random.Generator, v: Variant) -> None:
    for line in _pick_rows(rng, v):
        cells = _cells(line)
        line.data = _csv_line(cells[: int(rng.integers(1, len(cells)))])
        line.damaged = True


def _long_row(rng: np.random.Generator, v: Variant) -> None:
    for line in _pick_rows(rng, v):
        line.data = line.data + b",extra"
        line.damaged = True


def _copied_row(rng: np.random.Generator, v: Variant) -> None:
    for line in _pick_rows(rng, v):
        v.lines.insert(v.lines.index(line) + 1, Line(line.data, None, damaged=True))


def _cut_last_line(rng: np.random.Generator, v: Variant) -> None:
    last = v.lines[-1]
    if last.row is None or last.damaged:
        return
    last.data = last.data[: int(rng.integers(1, len(last.data) + 1))]
    last.damaged = True
    v.no_final_newline = True


ROW_DAMAGE: dict[str, Callable[[np.random.Generator, Variant], None]] = {
    "bad_cell": _bad_cell,
    "bad_cell_2": _bad_cell,
    "other_ids": _other_ids,
    "huge_value": _numeric_1e308,
    "binary_in_row": _binary_in_row,
    "stray_quote": _stray_quote,
    "short_row": _short_row,
    "long_row": _long_row,
    "copied_row": _copied_row,
    "cut_last_line": _cut_last_line,
}


def _spaces(rng: np.random.Generator, v: Variant) -> None:
    for line in _pick_rows(rng, v, 3):
        cells = _cells(line)
        i = int(rng.integers(0, len(cells)))
        if cells[i]:
            cells[i] = f" {cells[i]}  "
        line.data = _csv_line(cells)


def _crlf(rng: np.random.Generator, v: Variant) -> None:
    for line in v.lines:
        line.data += b"\r"


def _bom(rng: np.random.Generator, v: Variant) -> None:
    v.lines[0].data = b"\xef\xbb\xbf" + v.lines[0].data


def _blank_lines(rng: np.random.Generator, v: Variant) -> None:
    for _ in range(int(rng.integers(1, 4))):
        v.lines.insert(int(rng.integers(1, len(v.lines) + 1)), Line(b"", None))


def _reorder(rng: np.random.Generator, v: Variant) -> None:
    body = v.lines[1:]
    order = rng.permutation(len(body))
    v.lines[1:] = [body[i] for i in order]


def _long_error(rng: np.random.Generator, v: Variant) -> None:
    if "error" not in v.header:
        return
    for line in _pick_rows(rng, v):
        cells = _cells(line)
        if cells[v.header.index("outcome")] == "error":
            _set_cell(line, v.header, "error", "RuntimeError: " + "x" * MB)
            line.damaged = False  # a long message is a legal cell


HARMLESS: dict[str, Callable[[np.random.Generator, Variant], None]] = {
    "spaces": _spaces,
    "crlf": _crlf,
    "bom": _bom,
    "blank_lines": _blank_lines,
    "reorder": _reorder,
    "long_error": _long_error,
}


def _drop_column(v: Variant, column: str, rename: str | None) -> None:
    i = v.header.index(column)
    for line in v.lines:
        cells = _cells(line) if line.data else []
        if len(cells) != len(v.header):
            continue
        if rename is None:
            del cells[i]
        elif line.row is None and cells == v.header:
            cells[i] = rename
        line.data = _csv_line(cells)
    v.header = (
        [h for h in v.header if h != column]
        if rename is None
        else [rename if h == column else h for h in v.header]
    )


def _file_damage(rng: np.random.Generator, v: Variant) -> None:
    kind = str(_one(rng, list(FILE_KINDS)))
    v.kinds.append(kind)
    if kind == "empty":
        v.raw, v.expect_refusal = b"", True
    elif kind == "binary":
        v.raw, v.expect_refusal = bytes(rng.integers(0, 256, size=4096, dtype=np.uint8)), True
    elif kind == "header_only":
        for line in v.lines[1:]:
            line.damaged = True  # gone: no row is left to count
        v.lines = v.lines[:1]
    elif kind in ("rename_required", "drop_required"):
        _drop_column(v, str(_one(rng, REQUIRED)), "renamed" if kind == "rename_required" else None)
        v.expect_refusal = True
    elif kind in ("rename_optional", "drop_optional"):
        column = str(_one(rng, ["touchdown_error_m", "wall_time_s", "controller_time_s", "seed", "error"]))
        _drop_column(v, column, f"{column}_old" if kind == "rename_optional" else None)
        v.dropped_column = column
    elif kind == "column_twice":
        _drop_column(v, "wall_time_s", "simulated_time_s")
        v.expect_refusal = True
    elif kind == "header_repeated":
        v.lines.insert(int(rng.integers(2, len(v.lines) + 1)), Line(v.lines[0].data, None, damaged=True))


FILE_KINDS = (
    "empty",
    "binary",
    "header_only",
    "rename_required",
    "drop_required",
    "rename_optional",
    "drop_optional",
    "column_twice",
    "header_repeated",
)


def make_variant(rng: np.random.Generator, clean: list[bytes]) -> Variant:
    """1 to 3 damages of the clean file (one of them, at most, to the file as a whole)."""
    header = _cells(Line(clean[0], None))
    v = Variant([Line(clean[0], None)] + [Line(b, k) for k, b in enumerate(clean[1:])], header)
    if rng.random() < 0.25:
        _file_damage(rng, v)
        if v.raw is not None or v.expect_refusal:
            return v
    pool = {**HARMLESS, **ROW_DAMAGE}
    chosen = {str(k) for k in rng.choice(list(pool), size=int(rng.integers(1, 4)), replace=False)}
    # in this order, so that the lines marked damaged are the ones a reader must name: what a spreadsheet
    # does first, then damage; a copy after the damage (a copy of an intact row is the one to name), and
    # the cut last (it must stay the file's last line)
    for kind in [k for k in pool if k in chosen]:
        v.kinds.append(kind)
        pool[kind](rng, v)
    return v


# --------------------------------------------------------------------------------------------------
# what the report must say
# --------------------------------------------------------------------------------------------------


def expected_figures(base: Path, v: Variant, work: Path) -> dict[str, Any]:
    """summary.json's groups and the per-preset counts, recomputed from the undamaged rows alone (the
    clean file's lines without the damaged ones, and without a dropped column)."""
    from alight.campaign.store import read_lock
    from alight.campaign.summary import group_statistics, read_campaign_table, summarize

    clean = (base / "results.csv").read_bytes().split(b"\n")[:-1]
    kept = {line.row for line in v.lines if line.row is not None and not line.damaged}
    ref = Variant([Line(clean[0], None)] + [Line(b, k) for k, b in enumerate(clean[1:]) if k in kept], [])
    ref.header = _cells(ref.lines[0])
    if v.dropped_column is not None:
        _drop_column(ref, v.dropped_column, None)
    d = work / "reference"
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir()
    shutil.copy(base / "campaign.lock.json", d)
    (d / "results.csv").write_bytes(ref.data())
    lock = read_lock(d)
    assert lock is not None
    table = read_campaign_table(d, lock)
    assert not table.damaged, table.damaged
    presets = {
        p: group_statistics([m for m in table.missions if m.preset == p])
        for p in dict.fromkeys(m.preset for m in table.missions)
    }
    return {"groups": summarize(table, lock)["groups"], "presets": presets}


def _close(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-12)
    return bool(a == b)


def _preset_counts(page: str) -> dict[str, tuple[int, int, int]]:
    """report.html's comparison table: preset -> (missions, successes, flown)."""
    rows = re.findall(
        r'<tr><td><b>([^<]*)</b></td>\s*<td class="num">(\d+)</td>\s*<td class="num"[^>]*><b>[^<]*</b>'
        r'.*?<span class="ci">(\d+)/(\d+)</span>',
        page,
        flags=re.S,
    )
    return {p: (int(n), int(k), int(f)) for p, n, k, f in rows}


def judge(v: Variant, status: int, err: str, out: Path, expected: dict[str, Any] | None) -> str | None:
    """None when the variant was refused or reported honestly; else what is wrong."""
    lines = [ln for ln in err.strip().splitlines() if ln]
    if status == 2:
        return None if len(lines) == 1 and "Traceback" not in err else f"refused in {len(lines)} lines"
    if status != 0:
        return f"exit status {status}"
    if expected is None:
        return "reported a file that had to be refused"
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    page = (out / "report.html").read_text(encoding="utf-8")
    if not _close(summary["groups"], expected["groups"]):
        return "summary.json's groups differ from the figures of the undamaged rows"
    counts = _preset_counts(page)
    want = {p: (g["n"], g["successes"], g["n_flown"]) for p, g in expected["presets"].items()}
    if counts != want:
        return f"report.html's preset counts {counts} differ from {want}"
    damaged = [k + 1 for k, line in enumerate(v.lines) if line.damaged]
    named = [d["line"] for d in summary["damaged_rows"]]
    if sorted(named) != damaged:
        return f"summary.json names lines {named}, the damaged ones are {damaged}"
    missing = [k for k in damaged if f"<tr><td>{k}</td>" not in page]
    if missing:
        return f"report.html does not name damaged lines {missing}"
    said = [k for k in damaged[:10] if f": line {k}" not in err]
    if said:
        return f"stderr does not name damaged lines {said}"
    if v.dropped_column and not any(v.dropped_column in n for n in summary["results_notes"]):
        return f"the missing column {v.dropped_column} is not named"
    return None


# --------------------------------------------------------------------------------------------------
# the run
# --------------------------------------------------------------------------------------------------


def run_one(base: Path, v: Variant, work: Path) -> tuple[str, str | None]:
    from alight.cli import main

    out = work / "variant"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir()
    shutil.copy(base / "campaign.lock.json", out)
    (out / "results.csv").write_bytes(v.data())
    expected = None if v.expect_refusal or v.raw is not None else expected_figures(base, v, work)
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            status = main(["report", str(out)])
    except BaseException:  # noqa: BLE001  (a traceback is what this looks for)
        return "FAILURE", "traceback: " + traceback.format_exc().strip().splitlines()[-1]
    problem = judge(v, status, err.getvalue(), out, expected)
    if problem is not None:
        return "FAILURE", problem
    return ("refused" if status == 2 else "reported"), None


def run(n: int, seed: int, keep: Path | None = None) -> dict[str, Any]:
    t0 = time.monotonic()
    work = Path(tempfile.mkdtemp(prefix="fuzz_results_csv_"))
    try:
        base = build_base(work)
        clean = (base / "results.csv").read_bytes().split(b"\n")[:-1]
        rng = np.random.default_rng(seed)
        counts = {"refused": 0, "reported": 0, "FAILURE": 0}
        by_kind: dict[str, dict[str, int]] = {}
        failures = []
        for i in range(n):
            v = make_variant(rng, clean)
            verdict, problem = run_one(base, v, work)
            counts[verdict] += 1
            for kind in v.kinds:
                by_kind.setdefault(kind, {"refused": 0, "reported": 0, "FAILURE": 0})[verdict] += 1
            if problem is not None:
                failures.append({"variant": i, "kinds": v.kinds, "problem": problem})
                if keep is not None:
                    keep.mkdir(parents=True, exist_ok=True)
                    (keep / f"variant_{i:04d}.csv").write_bytes(v.data())
        return {
            "variants": n,
            "seed": seed,
            "missions_in_the_clean_file": len(clean) - 1,
            **counts,
            "by_kind": dict(sorted(by_kind.items())),
            "failures": failures[:50],
            "wall_time_s": round(time.monotonic() - t0, 1),
        }
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100, help="number of variants")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--keep", type=Path, default=None, help="write the failing variants here")
    args = parser.parse_args(argv)
    summary = run(args.n, args.seed, args.keep)
    print(json.dumps(summary, indent=2))
    return 1 if summary["FAILURE"] else 0


if __name__ == "__main__":
    sys.exit(main())
