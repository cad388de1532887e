"""results.csv's one reader: summaries that cannot silently lie (issue 39's damaged files, each refused in
one line or reported with the damaged rows named and the figures from the rest."""

from __future__ import annotations

import json
import re
from pathlib import Path

import campaign_fakes
import pytest

from alight.campaign import campaign_from_dict, run_campaign
from alight.campaign.results import COLUMNS, REQUIRED, read_table
from alight.campaign.summary import group_statistics
from alight.cli import main

ROOT = Path(__file__).resolve().parents[2]
SPEC = {
    "name": "reader",
    "base": {"duration_s": 10.0},
    "presets": ["groundtruth", "falanga2017"],
    "seeds_per_condition": 3,
    "seed": 4,
    "grid": {"platform.speed_mps": [1.0, 1.5]},
}


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real campaign directory: 12 missions flown by the fakes (landed or crashed by the seed)."""
    out = tmp_path_factory.mktemp("clean")
    run_campaign(campaign_from_dict(SPEC), out, workers=1, mission_fn=campaign_fakes.instant, report=False)
    return out


def _copy(clean: Path, tmp_path: Path, edit: dict[int, dict[str, str]] | None = None) -> Path:
    """``clean``'s results.csv and lock in ``tmp_path``, with cells of data rows (0-based) replaced."""
    (tmp_path / "campaign.lock.json").write_bytes((clean / "campaign.lock.json").read_bytes())
    lines = (clean / "results.csv").read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    for k, cells in (edit or {}).items():
        row = lines[1 + k].split(",")
        for column, value in cells.items():
            row[header.index(column)] = value
        lines[1 + k] = ",".join(row)
    (tmp_path / "results.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return tmp_path


def _report(out: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    capsys.readouterr()
    status = main(["report", str(out)])
    return status, capsys.readouterr().err


def _preset_counts(page: str) -> dict[str, tuple[int, int]]:
    """report.html's comparison table: preset -> (successes, flown)."""
    rows = re.findall(
        r'<tr><td><b>([^<]*)</b></td><td class="num">\d+</td>.*?<span class="ci">(\d+)/(\d+)<', page
    )
    return {p: (int(k), int(n)) for p, k, n in rows}


def test_the_table_has_one_rule_per_column_and_reads_a_clean_file_whole(clean: Path) -> None:
    assert len({c.name for c in COLUMNS}) == len(COLUMNS)
    assert set(REQUIRED) == {"mission_id", "condition_id", "preset", "outcome", "success"}
    table = read_table(clean / "results.csv")
    assert len(table.missions) == 12 and not table.damaged and not table.notes
    assert table.swept == ["platform.speed_mps"]


@pytest.mark.parametrize("column", ["preset", "condition_id", "success"])
def test_a_renamed_required_column_is_refused_in_one_line(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], column: str
) -> None:
    out = _copy(clean, tmp_path)
    text = (out / "results.csv").read_text(encoding="utf-8")
    (out / "results.csv").write_text(text.replace(column, column + "_x", 1), encoding="utf-8")
    status, err = _report(out, capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1, err
    assert f"no {column} column" in err and "Traceback" not in err


@pytest.mark.parametrize("value", ["garbage", "NaN", "2"])
def test_a_damaged_success_cell_is_named_and_both_summaries_agree(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str
) -> None:
    out = _copy(clean, tmp_path, {0: {"success": value}})
    status, err = _report(out, capsys)
    assert status == 0
    assert f": line 2 (c000-groundtruth-r000): success: '{value}' is not 0 or 1" in err
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["n_damaged_rows"] == 1 and summary["damaged_rows"][0]["line"] == 2
    assert summary["n_missions"] == 11
    # the figures are those of the other 11 rows, in summary.json and report.html alike
    rest = read_table(clean / "results.csv").missions[1:]
    for preset in ("groundtruth", "falanga2017"):
        want = group_statistics([m for m in rest if m.preset == preset])
        in_summary = [g for g in summary["groups"] if g["preset"] == preset]
        assert sum(g["successes"] for g in in_summary) == want["successes"]
        assert sum(g["n_flown"] for g in in_summary) == want["n_flown"]
        page = (out / "report.html").read_text(encoding="utf-8")
        assert _preset_counts(page)[preset] == (want["successes"], want["n_flown"])
    assert "Damaged rows (1)" in page and "c000-groundtruth-r000" in page


@pytest.mark.parametrize(
    ("column", "value"),
    [("outcome", "landed?"), ("preset", "falanga2017"), ("condition_id", "c001"), ("condition_id", "")],
)
def test_a_damaged_id_or_outcome_is_named_not_dropped(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], column: str, value: str
) -> None:
    out = _copy(clean, tmp_path, {0: {column: value}})
    status, err = _report(out, capsys)
    assert status == 0 and ": line 2 (c000-groundtruth-r000): " in err and column in err
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["n_missions"] + summary["n_damaged_rows"] == 12
    assert sum(g["n"] for g in summary["groups"]) == 11


def test_one_absurd_value_never_loses_the_report(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _copy(clean, tmp_path, {3: {"controller_time_s": "1e308", "wall_time_s": "1e308"}})
    status, err = _report(out, capsys)
    assert status == 0 and "controller_time_s: '1e308' is outside [0, 1e+09]" in err
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "Damaged rows (1)" in page and "<h2>Presets</h2>" in page


def test_a_1mb_cell_is_named_by_its_head_and_a_1mb_error_message_is_text(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _copy(clean, tmp_path, {1: {"wall_time_s": "9" * 2**20}, 2: {"error": "x" * 2**20}})
    status, err = _report(out, capsys)
    assert status == 0 and len(err) < 1000, err[:300]
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert [d["line"] for d in summary["damaged_rows"]] == [3]
    assert "(1,048,576 characters)" in summary["damaged_rows"][0]["problem"]


def test_a_cut_last_line_is_named_for_the_report_and_removed_by_a_resume(
    clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = _copy(clean, tmp_path)
    data = (out / "results.csv").read_bytes()
    (out / "results.csv").write_bytes(data[:-20])
    status, err = _report(out, capsys)
    assert status == 0 and ": line 13 (c001-falanga2017-r002): cut short" in err
    run_campaign(campaign_from_dict(SPEC), out, workers=1, mission_fn=campaign_fakes.instant, report=False)
    assert (out / "results.csv").read_bytes() == (clean / "results.csv").read_bytes()  # flown again, same
