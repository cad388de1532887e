"""The campaign engines: failures become error rows (raise, hang, crash), the Wilson interval, the summary,
and the same results whatever the engine and the number of workers."""

from __future__ import annotations

import csv
import json
import math
import sys
import time
from pathlib import Path

import campaign_fakes
import numpy as np
import pytest

from alight.campaign import campaign_from_dict, run_campaign, wilson95
from alight.campaign.store import BLOCK_TIME_COLUMNS
from alight.campaign.summary import group_summary
from alight.errors import AlightError

_CLOCKS = {"wall_time_s", *BLOCK_TIME_COLUMNS}
"""Columns that are wall-clock times: they differ from run to run."""

Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "results.csv").open(newline="") as f:
        return list(csv.DictReader(f))


def _wilson_formula(k: int, n: int) -> tuple[float, float]:
    # Wilson (1927), without continuity correction, written out independently of the module under test.
    p, z2 = k / n, Z95**2
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return centre - half, centre + half


@pytest.mark.parametrize(("k", "n"), [(0, 20), (20, 20), (10, 20), (3, 7), (1, 1)])
def test_wilson_interval_matches_the_formula(k: int, n: int) -> None:
    lo, hi = wilson95(k, n)
    elo, ehi = _wilson_formula(k, n)
    assert lo == pytest.approx(max(elo, 0.0), abs=1e-12) and hi == pytest.approx(min(ehi, 1.0), abs=1e-12)


def test_wilson_interval_known_values() -> None:
    # 0/20: [0, z^2/(n+z^2)]; 20/20 mirrors it; 10/20: the tabulated [0.2993, 0.7007].
    assert wilson95(0, 20) == pytest.approx((0.0, 0.16113), abs=1e-5)
    assert wilson95(20, 20) == pytest.approx((0.83887, 1.0), abs=1e-5)
    assert wilson95(10, 20) == pytest.approx((0.29930, 0.70070), abs=1e-5)
    assert wilson95(0, 0) is None
    with pytest.raises(ValueError):
        wilson95(3, 2)


def test_group_summary_statistics() -> None:
    errs = [0.01, 0.02, 0.05, 0.3]
    rows = [
        {"outcome": "landed", "success": "1", "touchdown_error_m": repr(e), "time_to_land_s": repr(10.0 + i),
         "energy_flight_J": "100.0", "energy_compute_J": ""}
        for i, e in enumerate(errs)
    ] + [
        {"outcome": "crashed", "success": "0", "touchdown_error_m": "0.9", "time_to_land_s": "",
         "energy_flight_J": "300.0", "energy_compute_J": ""},
        {"outcome": "error", "success": "0", "touchdown_error_m": "", "time_to_land_s": "",
         "energy_flight_J": "", "energy_compute_J": ""},
    ]  # fmt: skip
    g = group_summary(rows)
    assert (g["n"], g["n_flown"], g["successes"], g["errors"]) == (6, 5, 4, 1)
    assert g["success_rate"] == pytest.approx(4 / 5)
    assert g["wilson95"] == pytest.approx(list(_wilson_formula(4, 5)))
    # touchdown statistics over landed missions only: the crash's 0.9 m is not among them
    assert g["touchdown_error_m"]["max"] == 0.3
    assert g["touchdown_error_m"]["p90"] == pytest.approx(np.percentile(errs, 90))
    assert g["time_to_land_s"] == {"p50": 11.5, "mean": 11.5}
    assert g["energy_flight_J"]["mean"] == pytest.approx(140.0)
    assert g["energy_compute_J"]["mean"] is None
    # the report's group statistics are the same function: the same figures from the parsed missions
    from alight.campaign.report import Mission, group_stats

    missions = [
        Mission(
            mission_id=str(i), condition_id="c0", preset="p", params={}, outcome=r["outcome"],
            success=r["success"] == "1",
            values={k: float(v) for k, v in r.items() if k not in ("outcome", "success") and v != ""},
        )
        for i, r in enumerate(rows)
    ]  # fmt: skip
    page = group_stats(missions)
    assert {k: page[k] for k in g} == g
    assert page["outcomes"] == {"landed": 4, "crashed": 1, "error": 1}


def _fake_campaign(**over: object) -> dict:
    data: dict = {
        "name": "fakes",
        "base": {"duration_s": 10.0},
        "presets": ["groundtruth"],
        "seeds_per_condition": 1,
        "seed": 3,
    }
    data.update(over)
    return data


def _engines() -> list[str]:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return ["local"]
    return ["local", "dask"]


@pytest.mark.parametrize("engine", _engines())
def test_raise_hang_and_crash_become_error_rows(tmp_path: Path, engine: str) -> None:
    campaign = campaign_from_dict(
        _fake_campaign(
            grid={"platform.speed_mps": [1.0, 2.0, 3.0, 4.0]}, seeds_per_condition=2, timeout_s=2.0
        )
    )
    t0 = time.monotonic()
    result = run_campaign(
        campaign, tmp_path, engine=engine, workers=2, mission_fn=campaign_fakes.by_speed, report=False
    )
    elapsed = time.monotonic() - t0
    rows = {r["mission_id"]: r for r in _rows(tmp_path)}
    assert sorted(rows) == sorted(m.mission_id for m in campaign.missions)
    assert result.n_run == 8 and result.n_errors == 6

    for r in range(2):
        ok = rows[f"c000-groundtruth-r{r:03d}"]
        assert ok["outcome"] in ("landed", "crashed") and ok["error"] == ""
        assert (tmp_path / ok["mission_dir"] / "result.json").is_file()
        if ok["outcome"] == "crashed":  # files the mission wrote reach its directory
            assert (tmp_path / ok["mission_dir"] / "report.html").read_text().startswith("<p>fakes c000")

        raised = rows[f"c001-groundtruth-r{r:03d}"]
        assert raised["outcome"] == "error" and raised["success"] == "0"
        assert raised["error"] == f"RuntimeError: fake failure of fakes c001-groundtruth-r{r:03d}"
        text = (tmp_path / raised["mission_dir"] / "error.txt").read_text()
        assert "Traceback (most recent call last)" in text and "campaign_fakes.py" in text

        hung = rows[f"c002-groundtruth-r{r:03d}"]
        assert hung["outcome"] == "error" and hung["error"].startswith("timeout: no result after 2 s")
        assert 2.0 <= float(hung["wall_time_s"]) < 6.0

        crashed = rows[f"c003-groundtruth-r{r:03d}"]
        assert crashed["outcome"] == "error"
        assert crashed["error"] == "the worker process died during the mission (exit status 3)"
        saved = json.loads((tmp_path / crashed["mission_dir"] / "result.json").read_text())
        assert saved["outcome"] == "error" and saved["scenario"]["platform"]["speed_mps"] == 4.0
    # two hung missions on two workers: killed at their deadlines, not waited for
    assert elapsed < 40.0

    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["n_missions"] == 8 and summary["n_errors"] == 6
    by_cond = {g["condition_id"]: g for g in summary["groups"]}
    assert by_cond["c001"]["errors"] == 2 and by_cond["c001"]["success_rate"] is None
    assert by_cond["c000"]["n"] == 2 and by_cond["c000"]["errors"] == 0


def test_a_result_that_is_not_a_dict_is_an_error(tmp_path: Path) -> None:
    run_campaign(
        campaign_from_dict(_fake_campaign()), tmp_path, workers=1, mission_fn=campaign_fakes.not_a_result
    )
    (row,) = _rows(tmp_path)
    assert row["outcome"] == "error" and "returned int" in row["error"]


def test_bad_mission_function_and_engine_are_one_line_errors(tmp_path: Path) -> None:
    campaign = campaign_from_dict(_fake_campaign())
    with pytest.raises(AlightError, match="cannot be imported"):
        run_campaign(campaign, tmp_path, mission_fn="campaign_fakes:nosuch")
    with pytest.raises(AlightError, match="unknown engine 'spark'"):
        run_campaign(campaign, tmp_path, engine="spark", mission_fn=campaign_fakes.instant)
    with pytest.raises(AlightError, match="--scheduler needs --engine dask"):
        run_campaign(campaign, tmp_path, scheduler="tcp://x:1", mission_fn=campaign_fakes.instant)


def test_dask_engine_missing_is_a_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(AlightError, match=r"pip install 'alight\[dask\]'"):
        run_campaign(
            campaign_from_dict(_fake_campaign()), tmp_path, engine="dask", mission_fn=campaign_fakes.instant
        )


def _tiny_real_campaign() -> dict:
    # A platform that passes near the take-off point: the groundtruth preset lands within ~15 s.
    return {
        "name": "tiny",
        "base": {
            "duration_s": 20.0,
            "platform": {"path": "straight", "speed_mps": 1.0, "start_xy": [6.0, 2.0], "heading_rad": 3.14},
        },
        "presets": ["groundtruth"],
        "seeds_per_condition": 3,
        "seed": 11,
        "timeout_s": 300.0,
    }


@pytest.mark.slow
def test_real_missions_agree_across_engines_and_worker_counts(tmp_path: Path) -> None:
    campaign = campaign_from_dict(_tiny_real_campaign())
    runs = {}
    configs = [("local", 1), ("local", 2)]
    try:
        import distributed  # noqa: F401

        configs.append(("dask", 2))
    except ImportError:
        pass
    for engine, workers in configs:
        out = tmp_path / f"{engine}{workers}"
        run_campaign(campaign, out, engine=engine, workers=workers, report=False)
        runs[(engine, workers)] = {r["mission_id"]: r for r in _rows(out)}
    reference = runs[("local", 1)]
    assert len(reference) == 3
    assert any(r["outcome"] == "landed" for r in reference.values())
    for key, rows in runs.items():
        assert sorted(rows) == sorted(reference), key
        for mid, row in rows.items():
            # every column but the wall clocks (the whole mission's and each block's)
            a = {k: v for k, v in row.items() if k not in _CLOCKS}
            b = {k: v for k, v in reference[mid].items() if k not in _CLOCKS}
            assert a == b, (key, mid)
            assert all(float(row[c]) >= 0 for c in BLOCK_TIME_COLUMNS), row
    # the numbers are the mission's own: flying one of them directly gives the same row
    from alight.evaluation.runner import run_mission
    from alight.scenario import Scenario

    m = campaign.missions[0]
    direct = run_mission(Scenario.model_validate(m.scenario), record=True).result
    row = reference[m.mission_id]
    assert row["outcome"] == direct["outcome"] and row["seed"] == str(direct["seed"])
    assert row["energy_flight_J"] == repr(direct["energy_flight_J"])
