"""A campaign's views of its failures (figures, report.html, replay.gif): every failure keeps its log, and
the first ``views_per_cell`` failures of each (preset, condition) cell, by replicate, are flown again
after the sweep to draw them."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import campaign_fakes
import pytest

import alight.campaign.run as campaign_run
from alight.campaign import campaign_from_dict, run_campaign
from alight.campaign.run import VIEWS_TXT
from alight.errors import AlightError, ConfigError


def _campaign(**over: object) -> dict:
    data: dict = {
        "name": "views",
        "base": {"duration_s": 10.0},
        "presets": ["groundtruth"],
        "grid": {"platform.speed_mps": [1.0, 2.0]},
        "seeds_per_condition": 8,
        "seed": 11,
        "views_per_cell": 2,
    }
    data.update(over)
    return data


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "results.csv").open(newline="") as f:
        return list(csv.DictReader(f))


def _failures_by_cell(out: Path) -> dict[str, list[dict[str, str]]]:
    cells: dict[str, list[dict[str, str]]] = {}
    for row in _rows(out):
        if row["outcome"] == "crashed":
            cells.setdefault(row["condition_id"], []).append(row)
    return {c: sorted(rows, key=lambda r: int(r["replicate"])) for c, rows in cells.items()}


def _has_views(out: Path, row: dict[str, str]) -> bool:
    return (out / row["mission_dir"] / "report.html").is_file()


def _run(out: Path, views_fn: object = campaign_fakes.views, engine: str = "local", **over: object):  # type: ignore[no-untyped-def]
    return run_campaign(
        campaign_from_dict(_campaign(**over)),
        out,
        engine=engine,
        workers=2,
        mission_fn=campaign_fakes.with_log,
        views_fn=views_fn,  # type: ignore[arg-type]
        report=False,
    )


def test_the_first_failures_of_each_cell_get_their_views_and_every_failure_its_log(tmp_path: Path) -> None:
    result = _run(tmp_path)
    cells = _failures_by_cell(tmp_path)
    # the seeds make failures in both cells, more than two in each (else the test shows nothing)
    assert len(cells) == 2 and all(len(rows) > 2 for rows in cells.values())
    for rows in cells.values():
        assert [_has_views(tmp_path, r) for r in rows] == [True, True] + [False] * (len(rows) - 2)
        for row in rows:
            d = tmp_path / row["mission_dir"]
            assert (d / "log.npz").read_bytes() == f"log {row['seed']}".encode()
            assert not (d / VIEWS_TXT).exists()
            # the sweep's result.json is the record: the views' flight does not replace it
            recorded = json.loads((d / "result.json").read_text())
            assert recorded["campaign"]["mission_id"] == row["mission_id"]
        assert (tmp_path / rows[0]["mission_dir"] / "replay.gif").read_bytes() == b"GIF89a"
    assert result.n_views == 4 and result.views_problems == []
    for row in _rows(tmp_path):
        if row["outcome"] == "landed":
            assert not _has_views(tmp_path, row)

    # more views later: the sweep flies nothing again, and only the views still missing are drawn
    more = _run(tmp_path, views_per_cell=3)
    assert more.n_run == 0 and more.n_views == 2
    for rows in cells.values():
        assert [_has_views(tmp_path, r) for r in rows] == [True] * 3 + [False] * (len(rows) - 3)
    assert _run(tmp_path, views_per_cell=3).n_views == 0


def test_the_same_missions_get_views_on_every_engine(tmp_path: Path) -> None:
    pytest.importorskip("distributed", reason="the dask engine needs distributed (pip install alight[dask])")
    chosen = {}
    for engine in ("local", "dask"):
        assert _run(tmp_path / engine, engine=engine).n_views == 4
        rows = _rows(tmp_path / engine)
        chosen[engine] = sorted(r["mission_id"] for r in rows if _has_views(tmp_path / engine, r))
    assert chosen["local"] == chosen["dask"] and len(chosen["local"]) == 4


def test_views_per_cell_all_draws_every_failure_in_the_sweep_and_zero_none(tmp_path: Path) -> None:
    every = _run(tmp_path / "all", views_per_cell="all")
    failures = [r for rows in _failures_by_cell(tmp_path / "all").values() for r in rows]
    assert failures and all(_has_views(tmp_path / "all", r) for r in failures)
    assert every.n_views == 0  # drawn from the one flight, nothing flown again

    none = _run(tmp_path / "none", views_per_cell=0)
    failures = [r for rows in _failures_by_cell(tmp_path / "none").values() for r in rows]
    assert failures and not any(_has_views(tmp_path / "none", r) for r in failures)
    assert none.n_views == 0


def test_a_views_flight_that_differs_from_the_record_is_said(tmp_path: Path) -> None:
    result = _run(tmp_path, views_fn=campaign_fakes.views_of_another_flight, views_per_cell=1)
    assert result.n_views == 0 and len(result.views_problems) == 2
    for rows in _failures_by_cell(tmp_path).values():
        d = tmp_path / rows[0]["mission_dir"]
        text = (d / VIEWS_TXT).read_text()
        assert "differed from the recorded one" in text and "touchdown_error_m" in text
        # the views are kept, beside the record: the sweep's result.json and log stay
        assert (d / "report.html").is_file()
        assert json.loads((d / "result.json").read_text())["campaign"]["mission_id"] == rows[0]["mission_id"]
        assert result.views_problems[0].count("\n") == 0


def test_views_that_fail_are_said_and_drawn_on_the_next_run(tmp_path: Path) -> None:
    result = _run(tmp_path, views_fn=campaign_fakes.views_that_raise, views_per_cell=1)
    assert result.n_views == 0 and len(result.views_problems) == 2
    assert all("could not be drawn" in p and "RuntimeError" in p for p in result.views_problems)
    rows = [rows[0] for rows in _failures_by_cell(tmp_path).values()]
    assert all((tmp_path / r["mission_dir"] / VIEWS_TXT).is_file() for r in rows)
    assert not any(_has_views(tmp_path, r) for r in rows)

    again = _run(tmp_path, views_per_cell=1)
    assert again.n_views == 2 and again.views_problems == []
    assert all(_has_views(tmp_path, r) for r in rows)
    assert not any((tmp_path / r["mission_dir"] / VIEWS_TXT).exists() for r in rows)


def test_an_engine_that_cannot_fly_the_views_costs_neither_results_nor_report(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real = campaign_run.make_engine

    class Broken:
        name = "local"

        def run(self, tasks: object) -> object:
            raise AlightError("campaign worker process ended during start-up (killed by signal 9)")

    def make_engine(engine: str, *, fn_spec: str, **kw: object) -> object:
        return Broken() if fn_spec.endswith(":views") else real(engine, fn_spec=fn_spec, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(campaign_run, "make_engine", make_engine)
    result = run_campaign(
        campaign_from_dict(_campaign()),
        tmp_path,
        workers=2,
        mission_fn=campaign_fakes.with_log,
        views_fn=campaign_fakes.views,
    )
    assert result.n_run == 16 and len(_rows(tmp_path)) == 16
    assert result.report_path is not None and result.report_path.is_file()
    assert result.n_views == 0 and len(result.views_problems) == 1
    assert "were not drawn" in result.views_problems[0] and "start-up" in result.views_problems[0]
    # the next run, with an engine that works, draws them
    monkeypatch.undo()
    assert _run(tmp_path).n_views == 4


def test_views_per_cell_is_refused_where_no_function_draws_views(tmp_path: Path) -> None:
    with pytest.raises(
        ConfigError, match="views_per_cell: the mission function .* no views function"
    ) as info:
        run_campaign(campaign_from_dict(_campaign()), tmp_path, workers=1, mission_fn=campaign_fakes.with_log)
    assert "\n" not in str(info.value)
    # left out, the key's default stays silent: a custom mission writes what it writes
    spec = _campaign()
    del spec["views_per_cell"]
    result = run_campaign(
        campaign_from_dict(spec), tmp_path, workers=1, mission_fn=campaign_fakes.with_log, report=False
    )
    assert result.n_run == 16 and result.n_views == 0


@pytest.mark.parametrize("value", [-1, "some", 1.5])
def test_a_bad_views_per_cell_is_refused_with_one_line(value: object) -> None:
    with pytest.raises(ConfigError, match="views_per_cell") as info:
        campaign_from_dict(_campaign(views_per_cell=value))
    assert "\n" not in str(info.value)


def test_a_real_campaign_draws_the_views_of_the_same_flight(tmp_path: Path) -> None:
    # falanga2017 with the pad parked ahead of the take-off point: it sees the pad at about 3 s and cannot
    # land in 6 s, so every mission times out.
    base = {
        "duration_s": 6.0,
        "platform": {"path": "straight", "speed_mps": 0.0, "start_xy": [1.2, 0.0], "heading_rad": 0.0},
    }
    spec = _campaign(name="real", base=base, presets=["falanga2017"], grid={}, seeds_per_condition=2)
    spec["views_per_cell"] = 1
    result = run_campaign(campaign_from_dict(spec), tmp_path, workers=1, report=True)
    rows = sorted(_rows(tmp_path), key=lambda r: int(r["replicate"]))
    assert [r["outcome"] for r in rows] == ["timeout", "timeout"]
    # the second flight, with the recorder, flew the recorded flight: no views.txt
    assert result.n_views == 1 and result.views_problems == []
    first, second = (tmp_path / r["mission_dir"] for r in rows)
    assert {"log.npz", "report.html", "replay.gif", "result.json", "scenario.yaml"} <= {
        p.name for p in first.iterdir()
    }
    assert not (first / VIEWS_TXT).exists()
    assert {p.name for p in second.iterdir()} == {
        "log.npz",
        "log.csv",
        "log_detections.csv",
        "result.json",
        "scenario.yaml",
    }
    page = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert f"{rows[0]['mission_dir']}/replay.gif" in page and f"{rows[1]['mission_dir']}/log.npz" in page
    assert f"{rows[1]['mission_dir']}/replay.gif" not in page
