"""The campaign report: numbers against SciPy/numpy computed here, links, robustness to empty and
damaged results, self-containment, and a headless-Chromium rendering of the page."""

from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy.stats import binomtest

from alight.campaign.report import (
    group_stats,
    informative_params,
    param_axis,
    read_results,
    write_campaign_report,
)
from alight.campaign.summary import wilson95
from alight.errors import InputError

CHROMIUM = Path("/usr/bin/chromium")

ID_COLUMNS = ["mission_id", "condition_id", "preset", "replicate", "seed"]
RESULT_COLUMNS = [
    "outcome",
    "success",
    "touchdown_error_m",
    "touchdown_rel_speed_mps",
    "touchdown_rel_vertical_speed_mps",
    "time_to_land_s",
    "time_first_detection_s",
    "energy_flight_J",
    "energy_compute_J",
    "detections",
    "go_arounds",
    "platform_estimate_rmse_m",
    "simulated_time_s",
    "wall_time_s",
    "mission_dir",
    "error",
]
PATHS = ["straight", "circle", "figure8"]
SPEEDS = [1.0, 2.0, 3.0, 4.2]


# --------------------------------------------------------------------------------------------------
# a synthetic campaign directory, written per the campaign output schema (docs/campaigns.md)
# --------------------------------------------------------------------------------------------------


def _p_success(preset: str, path: str, speed: float) -> float:
    """A plausible ground truth: vision fails more at speed and on curved paths."""
    base = 0.97 if preset == "groundtruth" else 0.9
    slope = 0.04 if preset == "groundtruth" else 0.14
    bend = {"straight": 0.0, "circle": 0.05, "figure8": 0.12}.get(path, 0.08)
    return float(np.clip(base - slope * (speed - 1.0) - bend * (preset != "groundtruth"), 0.02, 0.99))


def make_campaign(
    out: Path,
    *,
    presets=("groundtruth", "falanga2017"),
    seeds: int = 20,
    grid=(("platform.path", PATHS), ("platform.speed_mps", SPEEDS)),
    error_rate: float = 0.01,
    summary: bool = True,
    rng_seed: int = 0,
) -> list[dict[str, str]]:
    """Write results.csv (and summary.json, computed here with numpy/SciPy) and mission directories for
    failures (report.html, and replay.gif for every other one); return the rows as written."""
    rng = np.random.default_rng(rng_seed)
    out.mkdir(parents=True, exist_ok=True)
    names = [g[0] for g in grid]
    conditions = [dict(zip(names, combo, strict=True)) for combo in _product([g[1] for g in grid])]
    rows: list[dict[str, str]] = []
    for ci, params in enumerate(conditions):
        cid = f"c{ci:03d}"
        for r in range(seeds):
            seed = int(rng.integers(2**31))
            for preset in presets:
                mid = f"{cid}-{preset}-r{r:03d}"
                path = str(params.get("platform.path", "straight"))
                speed = float(params.get("platform.speed_mps", 1.0))
                u = rng.random()
                if u < error_rate:
                    outcome = "error"
                elif u < _p_success(preset, path, speed):
                    outcome = "landed"
                else:
                    outcome = str(rng.choice(["crashed", "timeout", "aborted"], p=[0.5, 0.3, 0.2]))
                landed = outcome == "landed"
                flew = outcome != "error"
                t_land = 18.0 + 6.0 * speed + rng.gamma(2.0, 4.0) if landed else None
                td = float(rng.lognormal(math.log(0.08 + 0.03 * speed * (preset != "groundtruth")), 0.5))
                row = {
                    "mission_id": mid,
                    "condition_id": cid,
                    "preset": preset,
                    "replicate": str(r),
                    "seed": str(seed),
                    **{k: str(v) for k, v in params.items()},
                    "outcome": outcome,
                    "success": "1" if landed else "0",
                    "touchdown_error_m": repr(td) if landed or outcome == "crashed" else "",
                    "touchdown_rel_speed_mps": repr(float(rng.uniform(0.2, 1.0))) if landed else "",
                    "touchdown_rel_vertical_speed_mps": repr(float(rng.uniform(0.1, 0.5))) if landed else "",
                    "time_to_land_s": repr(t_land) if landed else "",
                    "time_first_detection_s": repr(float(rng.uniform(3, 15))) if flew else "",
                    "energy_flight_J": repr(float(160.0 * (t_land or 60.0))) if flew else "",
                    "energy_compute_J": repr(float(4.0 * (t_land or 60.0)))
                    if flew and preset != "groundtruth"
                    else "",
                    "detections": str(int(rng.integers(0, 400))) if flew else "",
                    "go_arounds": str(int(rng.integers(0, 2))) if flew else "",
                    "platform_estimate_rmse_m": repr(float(rng.uniform(0.05, 0.4))) if flew else "",
                    "simulated_time_s": repr(float((t_land or 60.0) + 1.0)) if flew else "",
                    "wall_time_s": repr(float(rng.uniform(0.4, 2.5))),
                    "mission_dir": "",
                    "error": "RuntimeError: numerical blow-up in the estimator" if not flew else "",
                }
                if outcome != "landed":
                    d = out / "missions" / mid
                    d.mkdir(parents=True, exist_ok=True)
                    (d / "result.json").write_text(json.dumps({"outcome": outcome}), encoding="utf-8")
                    if flew:
                        (d / "report.html").write_text("<!DOCTYPE html><title>m</title>", encoding="utf-8")
                        if len(rows) % 2 == 0:
                            Image.new("P", (4, 4)).save(d / "replay.gif")
                    else:
                        (d / "error.txt").write_text("Traceback ...", encoding="utf-8")
                    row["mission_dir"] = f"missions/{mid}"
                rows.append(row)
    header = ID_COLUMNS + names + RESULT_COLUMNS
    with open(out / "results.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    if summary:
        (out / "summary.json").write_text(json.dumps(_summary(out.name, rows, names, presets, conditions)))
    return rows


def _product(levels):
    if not levels:
        return [()]
    return [(a, *rest) for a in levels[0] for rest in _product(levels[1:])]


def _summary(name, rows, names, presets, conditions) -> dict:
    """summary.json per the schema, computed independently of the report (numpy percentiles, SciPy's
    Wilson interval)."""
    groups = []
    for ci, params in enumerate(conditions):
        cid = f"c{ci:03d}"
        for p in presets:
            g = [r for r in rows if r["condition_id"] == cid and r["preset"] == p]
            errors = sum(r["outcome"] == "error" for r in g)
            k = sum(r["success"] == "1" for r in g)
            flown = len(g) - errors
            ci95 = binomtest(k, flown).proportion_ci(method="wilson") if flown else None
            td = [float(r["touchdown_error_m"]) for r in g if r["outcome"] == "landed"]
            ttl = [float(r["time_to_land_s"]) for r in g if r["outcome"] == "landed"]
            groups.append(
                {
                    "preset": p,
                    "condition_id": cid,
                    "params": params,
                    "n": len(g),
                    "n_flown": flown,
                    "successes": k,
                    "errors": errors,
                    "success_rate": k / flown if flown else None,
                    "wilson95": [ci95.low, ci95.high] if ci95 else None,
                    "touchdown_error_m": {
                        q: (float(np.percentile(td, v)) if td else None)
                        for q, v in (("p50", 50), ("p90", 90), ("p95", 95), ("max", 100))
                    },
                    "time_to_land_s": {
                        "p50": float(np.percentile(ttl, 50)) if ttl else None,
                        "mean": float(np.mean(ttl)) if ttl else None,
                    },
                    "energy_flight_J": {"mean": None},
                    "energy_compute_J": {"mean": None},
                }
            )
    return {
        "campaign": name,
        "created": "2026-01-01T00:00:00+00:00",
        "alight_version": "0.1.0",
        "n_missions": len(rows),
        "n_errors": sum(r["outcome"] == "error" for r in rows),
        "presets": list(presets),
        "swept_parameters": list(names),
        "groups": groups,
    }


class _Page(HTMLParser):
    """Links, image sources, scripts and the text of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.hrefs: list[str] = []
        self.srcs: list[str] = []
        self.scripts = 0
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "href" in a:
            self.hrefs.append(a["href"] or "")
        if "src" in a:
            self.srcs.append(a["src"] or "")
        self.scripts += tag == "script"

    def handle_data(self, data):
        self.text.append(data)


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


# --------------------------------------------------------------------------------------------------
# numbers
# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> tuple[Path, list[dict[str, str]]]:
    """A 2 presets x 12 conditions x 12 seeds campaign with its report written."""
    out = tmp_path_factory.mktemp("camp") / "paper_like"
    rows = make_campaign(out, seeds=12)
    write_campaign_report(out)
    return out, rows


def test_wilson_interval_is_scipys():
    for k, n in ((0, 10), (3, 10), (10, 10), (17, 20), (1, 1)):
        ci = binomtest(k, n).proportion_ci(method="wilson")
        assert wilson95(k, n) == pytest.approx((ci.low, ci.high), abs=1e-15)
        # and it is Wilson's closed form (z = 1.96)
        z, p = 1.959963984540054, k / n
        c = (p + z * z / (2 * n)) / (1 + z * z / n)
        h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        assert wilson95(k, n) == pytest.approx((c - h, c + h), abs=1e-12)
    assert wilson95(0, 0) is None


def test_per_preset_numbers(campaign):
    out, rows = campaign
    text = (out / "report.html").read_text(encoding="utf-8")
    res = read_results(out)
    for preset in ("groundtruth", "falanga2017"):
        mine = [r for r in rows if r["preset"] == preset]
        flown = [r for r in mine if r["outcome"] != "error"]
        k = sum(r["success"] == "1" for r in flown)
        ci = binomtest(k, len(flown)).proportion_ci(method="wilson")
        td = [float(r["touchdown_error_m"]) for r in mine if r["outcome"] == "landed"]
        st = group_stats([m for m in res.missions if m.preset == preset])
        assert st["n"] == len(mine) and st["n_flown"] == len(flown) and st["successes"] == k
        assert st["success_rate"] == pytest.approx(k / len(flown), abs=1e-15)
        assert st["wilson95"] == pytest.approx([ci.low, ci.high], abs=1e-15)
        assert st["touchdown_error_m"]["p50"] == pytest.approx(np.percentile(td, 50), abs=1e-12)
        assert st["touchdown_error_m"]["p90"] == pytest.approx(np.percentile(td, 90), abs=1e-12)
        assert st["errors"] == len(mine) - len(flown)
        # the page shows them: rate to 0.1 %, interval to 1 %, TD quantiles as format_quantity does
        row = re.search(rf"<tr><td><b>{preset}</b></td>.*?</tr>", text, re.S)
        assert row is not None
        cells = row.group(0)
        assert f"{100 * k / len(flown):.1f}%" in cells
        assert f"[{100 * ci.low:.0f}\u2013{100 * ci.high:.0f}%]" in cells
        assert f"{k}/{len(flown)}" in cells
        assert f"{np.percentile(td, 50):.3f} m" in cells and f"{np.percentile(td, 90):.3f} m" in cells


def test_condition_table_uses_summary_json(campaign, tmp_path):
    out, rows = campaign
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    summary = json.loads((copy / "summary.json").read_text())
    g = summary["groups"][5]
    g["wilson95"] = [0.123456, 0.654321]  # a marker: the page must show summary.json's numbers
    (copy / "summary.json").write_text(json.dumps(summary))
    text = write_campaign_report(copy).read_text(encoding="utf-8")
    assert "[12\u201365%]" in text
    # without summary.json the same numbers come from results.csv
    (copy / "summary.json").unlink()
    text = write_campaign_report(copy).read_text(encoding="utf-8")
    assert "[12\u201365%]" not in text
    k, n = g["successes"], g["n_flown"]
    ci = binomtest(k, n).proportion_ci(method="wilson")
    assert f"[{100 * ci.low:.0f}\u2013{100 * ci.high:.0f}%]" in text
    # a summary.json that does not match results.csv (written before the last rows) is not trusted
    make_campaign(tmp_path / "stale", seeds=2)
    s = json.loads((tmp_path / "stale" / "summary.json").read_text())
    s["n_missions"] += 3
    s["groups"][0]["wilson95"] = [0.123456, 0.654321]
    (tmp_path / "stale" / "summary.json").write_text(json.dumps(s))
    text = write_campaign_report(tmp_path / "stale").read_text(encoding="utf-8")
    assert "[12\u201365%]" not in text and "computed from results.csv" in text


def test_failure_links_are_relative_and_exist(campaign):
    out, rows = campaign
    page = _parse(out / "report.html")
    failed = [r for r in rows if r["outcome"] != "landed"]
    links = [h for h in page.hrefs if h.startswith("missions/")]
    for r in failed:
        d = r["mission_dir"]
        if r["outcome"] == "error":
            assert f"{d}/error.txt" in links and f"{d}/report.html" not in links
        else:
            assert f"{d}/report.html" in links
            assert ((out / d / "replay.gif").is_file()) == (f"{d}/replay.gif" in links)
    for h in page.hrefs:
        assert "://" not in h and not h.startswith("/") and ".." not in h
        assert (out / h).is_file(), h
    landed_ids = {r["mission_id"] for r in rows if r["outcome"] == "landed"}
    assert not any(h.split("/")[1] in landed_ids for h in links)


def test_self_contained(campaign):
    out, _ = campaign
    path = out / "report.html"
    text = path.read_text(encoding="utf-8")
    page = _parse(path)
    assert not re.search(
        r"(?i)(https?:)?//[a-z0-9]", re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "", text)
    )
    assert page.scripts == 0  # the report uses no JavaScript at all
    assert page.srcs and all(s.startswith("data:image/png;base64,") for s in page.srcs)
    assert "<link" not in text and "@import" not in text and "url(" not in text
    assert len(page.srcs) >= 4  # outcome bars, two heatmaps, touchdown distributions


# --------------------------------------------------------------------------------------------------
# swept parameters
# --------------------------------------------------------------------------------------------------


def test_param_axis_levels_and_bins():
    a = param_axis("platform.speed_mps", ["3.0", "1.0", "", "2.0", "1.0"])
    assert a.labels == ["\u2014", "1.0", "2.0", "3.0"] and a.index["3.0"] == 3 and a.index[""] == 0
    b = param_axis("platform.path", ["straight", "circle", "straight", "figure8"])
    assert b.labels == ["straight", "circle", "figure8"]
    values = [repr(float(x)) for x in np.linspace(0.0, 10.0, 60)]
    c = param_axis("wind.gust_power_N", values)
    assert len(c.labels) == 7 and len(set(c.index.values())) == 7
    # bins are ordered and every value sits in the bin whose label brackets it
    for v in values:
        lo, hi = (float(x) for x in re.findall(r"[-\d.e]+", c.labels[c.index[v]]))
        assert lo <= float(v) <= hi


def test_informative_params_pick_the_ones_that_matter(tmp_path):
    out = tmp_path / "c"
    # success depends on speed and path only; the third parameter is noise
    make_campaign(
        out,
        seeds=8,
        grid=(("platform.path", PATHS), ("camera.noise_dn", [1.0, 2.0, 3.0]), ("platform.speed_mps", SPEEDS)),
    )
    res = read_results(out)
    assert set(informative_params(res.missions, res.swept)) == {"platform.path", "platform.speed_mps"}
    html = write_campaign_report(out).read_text(encoding="utf-8")
    assert "aggregated over camera.noise_dn" in html
    # nothing to explain (every mission landed): the campaign's order; single-level parameters dropped
    for m in res.missions:
        m.outcome, m.success = "landed", True
    assert informative_params(res.missions, ["camera.noise_dn", "platform.path", "platform.speed_mps"]) == [
        "camera.noise_dn",
        "platform.path",
    ]
    for m in res.missions:
        m.params["camera.noise_dn"] = "2.0"
    assert informative_params(res.missions, res.swept, 3) == ["platform.path", "platform.speed_mps"]


# --------------------------------------------------------------------------------------------------
# robustness
# --------------------------------------------------------------------------------------------------


def test_empty_and_missing_results(tmp_path):
    (tmp_path / "a").mkdir()
    text = write_campaign_report(tmp_path / "a").read_text(encoding="utf-8")
    assert "No missions in results.csv yet" in text and "results.csv is missing" in text
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "results.csv").write_text(",".join(ID_COLUMNS + RESULT_COLUMNS) + "\n")
    text = write_campaign_report(tmp_path / "b").read_text(encoding="utf-8")
    assert "No missions in results.csv yet" in text
    with pytest.raises(InputError):
        write_campaign_report(tmp_path / "nope")


def test_all_errors_one_preset(tmp_path):
    out = tmp_path / "err"
    rows = make_campaign(out, presets=("falanga2017",), seeds=3, error_rate=1.0, summary=False)
    text = write_campaign_report(out).read_text(encoding="utf-8")
    assert "Every mission ended in an error" in text
    assert f"{len(rows)}\u00d7</span> <code>RuntimeError: numerical blow-up in the estimator" in text
    assert "No mission landed" in text and f"Failures ({len(rows)})" in text


def test_no_swept_parameter_and_one_swept_parameter(tmp_path):
    make_campaign(tmp_path / "none", grid=(), seeds=15)
    page = _parse(write_campaign_report(tmp_path / "none"))
    assert "No parameter was swept" in "".join(page.text)
    make_campaign(tmp_path / "one", grid=(("platform.speed_mps", SPEEDS),), seeds=10)
    text = "".join(_parse(write_campaign_report(tmp_path / "one")).text)
    assert "Wilson 95% intervals per value of platform.speed_mps" in text


def test_damaged_cells(tmp_path):
    out = tmp_path / "bad"
    rows = make_campaign(out, seeds=3, summary=False)
    lines = (out / "results.csv").read_text().splitlines()
    header = lines[0].split(",")
    i_td = header.index("touchdown_error_m")
    i_wall = header.index("wall_time_s")
    damaged = []
    for k, line in enumerate(lines[1:], start=1):
        cells = next(csv.reader([line]))
        if k == 1:
            cells[i_td] = "not-a-number"
        if k == 2:
            cells[i_wall] = "nan"
        if k == 3:
            cells = cells[:7]  # cut short
        if k == 4:
            cells[header.index("success")] = "yes?"  # falls back to the outcome
        if k in (5, 6):  # absolute paths and paths with '..' are never linked, even to files that exist
            (out / "x").mkdir(exist_ok=True)
            (out / "x" / "report.html").write_text("x")
            cells[header.index("outcome")] = "crashed"
            cells[header.index("mission_dir")] = str((out / "x").resolve()) if k == 5 else "missions/../x"
        damaged.append(cells)
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        w.writerows(damaged)
    res = read_results(out)
    # each damaged row is named and left out of every figure; the other rows are read as written
    assert [(d.line, d.mission_id) for d in res.damaged] == [
        (k + 1, rows[k - 1]["mission_id"]) for k in range(1, 5)
    ]
    problems = [d.problem for d in res.damaged]
    assert problems[0].startswith("touchdown_error_m: 'not-a-number' is not a number")
    assert problems[1].startswith("wall_time_s: 'nan' is outside")
    assert problems[2] == f"has 7 cells, the header {len(header)}"
    assert problems[3] == "success: 'yes?' is not 0 or 1"
    assert [m.mission_id for m in res.missions] == [r["mission_id"] for r in rows[4:]]
    assert res.missions[0].values["wall_time_s"] == float(rows[4]["wall_time_s"])
    text = write_campaign_report(out).read_text(encoding="utf-8")
    assert "Damaged rows (4)" in text and "left out of every figure" in text
    assert all(rows[k]["mission_id"] in text for k in range(4))
    hrefs = _parse(out / "report.html").hrefs
    assert hrefs and all(h.startswith(("missions/c", "results.csv")) and ".." not in h for h in hrefs)
    # summary.json unreadable, or with a damaged group: the numbers come from results.csv
    (out / "summary.json").write_text("{not json")
    assert "summary.json could not be read" in write_campaign_report(out).read_text(encoding="utf-8")
    good = _summary("bad", rows, ["platform.path", "platform.speed_mps"], ("groundtruth", "falanga2017"), [])
    good["groups"] = [
        {"preset": "groundtruth", "condition_id": "c000", "n": "six", "wilson95": [0.123456, 0.654321]}
    ]
    (out / "summary.json").write_text(json.dumps(good))
    assert "[12\u201365%]" not in write_campaign_report(out).read_text(encoding="utf-8")


def test_many_conditions(tmp_path):
    """72 conditions (and a continuous parameter binned) still give readable maps."""
    speeds = [round(x, 3) for x in np.linspace(0.5, 5.0, 24)]
    make_campaign(tmp_path / "many", grid=(("platform.path", PATHS), ("platform.speed_mps", speeds)), seeds=2)
    res = read_results(tmp_path / "many")
    assert len({m.condition_id for m in res.missions}) == 72
    axis = param_axis("platform.speed_mps", (m.params["platform.speed_mps"] for m in res.missions))
    assert len(axis.labels) == 7  # 24 speeds binned
    text = write_campaign_report(tmp_path / "many").read_text(encoding="utf-8")
    assert "Conditions (72)" in text


# --------------------------------------------------------------------------------------------------
# in a browser
# --------------------------------------------------------------------------------------------------


def _chromium(args: list[str], tmp: Path) -> subprocess.CompletedProcess:
    cmd = [
        str(CHROMIUM),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp / 'profile'}",
        "--enable-logging=stderr",
        "--v=0",
        *args,
    ]
    env = dict(os.environ, HOME=str(tmp))
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env, check=False)


def _console_errors(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if "CONSOLE" in ln or "Uncaught" in ln]


@pytest.mark.skipif(not CHROMIUM.exists(), reason="headless Chromium (/usr/bin/chromium) is not installed")
def test_report_renders_in_chromium(campaign, tmp_path):
    out, _ = campaign
    path = out / "report.html"
    shot = tmp_path / "shot.png"
    proc = _chromium([f"--screenshot={shot}", "--window-size=1400,2400", path.resolve().as_uri()], tmp_path)
    assert shot.is_file(), proc.stderr[-2000:]
    assert not _console_errors(proc.stderr), _console_errors(proc.stderr)
    img = np.asarray(Image.open(shot).convert("RGB")).astype(float)
    assert img.shape == (2400, 1400, 3)
    assert img.std() > 20  # not a blank page
    # the figures are drawn: the outcome bars' colours and the heatmaps' red-to-green cells are on screen
    landed = np.array([0x1A, 0x7F, 0x37], float)
    assert (np.abs(img - landed).max(axis=2) < 10).sum() > 2000
    rows_with_colour = (np.ptp(img, axis=2) > 60).any(axis=1).sum()
    assert rows_with_colour > 600
    # the page in the DOM Chromium built has every section
    dom = _chromium(["--dump-dom", path.resolve().as_uri()], tmp_path).stdout
    for heading in (
        "Presets",
        "Success rate over the swept parameters",
        "Touchdown error",
        "Failures",
        "Conditions",
    ):
        assert f"<h2>{heading}" in dom
    assert dom.count("<img") == len(_parse(path).srcs)


@pytest.mark.skipif(not CHROMIUM.exists(), reason="headless Chromium (/usr/bin/chromium) is not installed")
def test_console_error_detection_works(tmp_path):
    """The console check above can fail: a page with a script error is caught by it."""
    bad = tmp_path / "bad.html"
    bad.write_text("<!DOCTYPE html><html><body><p>x</p><script>nosuchfunction();</script></body></html>")
    proc = _chromium(["--dump-dom", bad.resolve().as_uri()], tmp_path)
    assert _console_errors(proc.stderr)


# --------------------------------------------------------------------------------------------------
# compute per block
# --------------------------------------------------------------------------------------------------


def test_compute_per_simulated_second_is_a_ratio_of_sums() -> None:
    from alight.campaign.summary import compute_per_simulated_s
    from alight.types import PIPELINE_BLOCKS

    def times(detector: float, other: float) -> dict[str, float | None]:
        return {b: (detector if b == "detector" else other) for b in PIPELINE_BLOCKS}

    missions = [
        (times(0.1, 0.01), 10.0, 1.0),
        (times(0.3, 0.02), 30.0, 2.0),
        ({**times(5.0, 5.0), "mission": None}, 10.0, 50.0),  # an older row without every block: left out
        (times(5.0, 5.0), None, 50.0),  # no simulated time: left out
        ({**times(5.0, 5.0), "detector": float("nan")}, 10.0, 50.0),  # a damaged cell: left out
        (times(5.0, 5.0), 10.0, float("inf")),
    ]
    got = compute_per_simulated_s(missions)
    assert got["detector"] == pytest.approx(1e3 * 0.4 / 40.0)
    for b in PIPELINE_BLOCKS:
        if b != "detector":
            assert got[b] == pytest.approx(1e3 * 0.03 / 40.0)
    blocks_s = 0.4 + 0.03 * (len(PIPELINE_BLOCKS) - 1)
    assert got["simulator"] == pytest.approx(1e3 * (3.0 - blocks_s) / 40.0)
    assert compute_per_simulated_s([]) == dict.fromkeys([*PIPELINE_BLOCKS, "simulator"])


def test_report_compares_the_presets_compute_when_the_rows_have_block_times(tmp_path: Path) -> None:
    from alight.campaign.store import BLOCK_TIME_COLUMNS, RESULT_COLUMNS, columns_for

    header = columns_for(["platform.speed_mps"])
    assert set(BLOCK_TIME_COLUMNS) <= set(RESULT_COLUMNS)
    rows = []
    for preset, detector_s in (("groundtruth", 0.0), ("falanga2017", 0.8)):
        for r in range(2):
            row = dict.fromkeys(header, "")
            row.update(
                {
                    "mission_id": f"c000-{preset}-r{r:03d}",
                    "condition_id": "c000",
                    "preset": preset,
                    "replicate": str(r),
                    "seed": str(r),
                    "platform.speed_mps": "1.2",
                    "outcome": "landed",
                    "success": "1",
                    "touchdown_error_m": "0.05",
                    "simulated_time_s": "20.0",
                    "wall_time_s": "1.5",
                    **{c: "0.01" for c in BLOCK_TIME_COLUMNS},
                    "detector_time_s": repr(detector_s),
                }
            )
            rows.append(row)
    with (tmp_path / "results.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header)
        w.writeheader()
        w.writerows(rows)
    res = read_results(tmp_path)
    vision = group_stats([m for m in res.missions if m.preset == "falanga2017"])
    assert vision["compute_ms_per_simulated_s"]["detector"] == pytest.approx(1e3 * 1.6 / 40.0)
    truth = group_stats([m for m in res.missions if m.preset == "groundtruth"])
    assert truth["compute_ms_per_simulated_s"]["detector"] == 0.0
    page = write_campaign_report(tmp_path).read_text(encoding="utf-8")
    assert "<h2>Compute</h2>" in page and "milliseconds per simulated second" in page
    assert "40.00" in page  # falanga2017's detector: 1.6 s over 40 simulated seconds


def test_report_of_a_campaign_without_block_times_has_no_compute_section(tmp_path: Path) -> None:
    make_campaign(tmp_path, seeds=2, grid=(("platform.speed_mps", [1.0]),))
    page = write_campaign_report(tmp_path).read_text(encoding="utf-8")
    assert "<h2>Compute</h2>" not in page and "<h2>Presets</h2>" in page
