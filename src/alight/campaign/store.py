"""results.csv, the mission directories and the lock file of a campaign's output directory.

results.csv is the campaign's record: one row per finished mission, appended by the campaign process
only, flushed and fsynced before the next mission's result is handled. A row is written after the
mission's directory is complete, so a row always means "done, with its files". A campaign killed in
the middle of writing a row leaves a last line without its newline: ``ResultsStore.open`` cuts it off
(that mission is flown again), and rejects any other damage with one line. The file's columns and its
one reader are :mod:`alight.campaign.results`.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import shutil
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import IO, Any

# results.csv's columns, cell rule and reader live in alight.campaign.results; re-exported here, where
# the campaign's other files are
from alight.campaign.results import BLOCK_TIME_COLUMN as BLOCK_TIME_COLUMN
from alight.campaign.results import BLOCK_TIME_COLUMNS as BLOCK_TIME_COLUMNS
from alight.campaign.results import ID_COLUMNS as ID_COLUMNS
from alight.campaign.results import NUMERIC_COLUMNS as NUMERIC_COLUMNS
from alight.campaign.results import RESULT_COLUMNS as RESULT_COLUMNS
from alight.campaign.results import RESULTS_CSV as RESULTS_CSV
from alight.campaign.results import cell as cell
from alight.campaign.results import columns_for as columns_for
from alight.campaign.results import read_header, write_csv_line
from alight.campaign.results import read_rows as read_rows
from alight.errors import InputError
from alight.evaluation.result import OUTCOMES as OUTCOMES  # re-exported: the report reads it here
from alight.evaluation.result import SCENARIO_YAML, write_scenario_yaml

SUMMARY_JSON = "summary.json"
LOCK_JSON = "campaign.lock.json"
CAMPAIGN_YAML = "campaign.yaml"
MISSIONS_DIR = "missions"
ERROR_TXT = "error.txt"
RESULT_JSON = "result.json"


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


class ResultsStore:
    """results.csv of one output directory, open for appending."""

    def __init__(self, path: Path, columns: list[str], rows: list[dict[str, str]], handle: IO[str]) -> None:
        self.path = path
        self.columns = columns
        self.rows = rows
        """The rows already in the file (column -> cell text), in file order."""
        self.done = {r["mission_id"] for r in rows}
        self._file = handle

    @classmethod
    def open(cls, path: Path, columns: list[str]) -> ResultsStore:
        """Open (or create) ``path`` for appending, locked against a second campaign process writing into
        the same directory; a truncated last line is removed from the file."""
        handle = path.open("a", encoding="utf-8", newline="")
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            raise InputError(f"{path}: another campaign process is writing to this directory") from None
        try:
            if b"\n" not in path.read_bytes():
                # new, or killed while writing the header: nothing was recorded yet
                _write_synced(path, write_csv_line(columns))
                return cls(path, columns, [], handle)
            rows = read_rows(path, repair=True)
            found = read_header(path)
            if found != columns:
                raise InputError(
                    f"{path}: its columns are not this campaign's ({_diff(found, columns)}); "
                    "the campaign file changed since this output directory was started: use another --out"
                )
        except BaseException:
            handle.close()
            raise
        return cls(path, columns, rows, handle)

    def append(self, row: Mapping[str, Any]) -> None:
        """Write one row and make it durable (flush + fsync) before returning."""
        values = [cell(row.get(c)) for c in self.columns]
        self._file.write(write_csv_line(values))
        self._file.flush()
        os.fsync(self._file.fileno())
        as_text = dict(zip(self.columns, values, strict=True))
        self.rows.append(as_text)
        self.done.add(as_text["mission_id"])

    def close(self) -> None:
        self._file.close()


def _diff(found: list[str], wanted: list[str]) -> str:
    extra = [c for c in found if c not in wanted]
    missing = [c for c in wanted if c not in found]
    parts = []
    if missing:
        parts.append(f"missing {', '.join(missing)}")
    if extra:
        parts.append(f"unexpected {', '.join(extra)}")
    return "; ".join(parts) or "different order"


def _write_synced(path: Path, text: str) -> None:
    with path.open("w", encoding="utf-8", newline="") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    _fsync_dir(path.parent)


def json_safe(value: Any) -> Any:
    """NaN and inf become null: a JSON reader should see null, not a parse error."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value


def write_json(path: Path, data: Any) -> None:
    """Write ``data`` as JSON atomically (a reader never sees half a file)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(json_safe(data), indent=2, allow_nan=False), encoding="utf-8")
    tmp.replace(path)


def write_mission_dir(
    out_dir: Path,
    mission_id: str,
    result: Mapping[str, Any],
    files: Mapping[str, bytes] | None = None,
    error_text: str | None = None,
) -> str:
    """Write ``missions/<mission_id>/`` afresh (files of an earlier, unfinished attempt are removed);
    its path relative to ``out_dir``."""
    rel = f"{MISSIONS_DIR}/{mission_id}"
    target = out_dir / rel
    if target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    for name, data in (files or {}).items():
        dest = (target / name).resolve()
        if target.resolve() not in dest.parents:
            raise InputError(f"mission {mission_id}: refusing to write {name!r} outside its directory")
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes(data)
    if error_text is not None:
        (target / ERROR_TXT).write_text(error_text, encoding="utf-8")
    scenario = result.get("scenario")
    if isinstance(scenario, Mapping):
        write_scenario_yaml(target / SCENARIO_YAML, scenario)
    write_json(target / RESULT_JSON, dict(result))
    return rel


def write_lock(out_dir: Path, lock: Mapping[str, Any]) -> None:
    write_json(out_dir / LOCK_JSON, lock)


def read_lock(out_dir: Path) -> dict[str, Any] | None:
    path = out_dir / LOCK_JSON
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: unreadable ({err})") from None
    if not isinstance(data, dict) or not isinstance(data.get("missions"), list):
        raise InputError(f"{path}: not a campaign lock file")
    return data


def rows_by_id(rows: Iterable[Mapping[str, str]]) -> dict[str, Mapping[str, str]]:
    return {r["mission_id"]: r for r in rows}
