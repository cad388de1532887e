"""The table of docs/paper_conditions.md: each paper preset in its own paper's conditions, per cell.

    alight campaign examples/campaigns/paper000_conditions.yaml --out runs/paper000_conditions
    alight campaign examples/campaigns/paper003_conditions.yaml --out runs/paper003_conditions
    alight campaign examples/campaigns/paper004_conditions.yaml --out runs/paper004_conditions
    python tools/paper_table.py runs/paper000_conditions runs/paper003_conditions \\
        runs/paper004_conditions [MORE_RUN_DIRS...] [--note TEXT] --out docs/paper_conditions.md

One section per campaign output directory (a second run of the same file with another ``seed:`` is a
second section, which is how a reader sees that the figures do not hang on the seeds in the repo). One
row per preset and cell (a condition of the campaign): landed / flown, the rate, its 95 % Wilson
interval, how the others ended (from each mission's ``result.json``) and what the paper itself reports
for that condition. The missions come from the campaign package's results reader; the cells are
labelled from the scenario a mission actually flew (its ``result.json``), so a value set in the
campaign's ``base`` shows as well as a swept one.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

from alight.campaign import wilson95
from alight.campaign.report import Mission, read_results
from alight.sim.wind import GustWind

GUST_DIRECTION_XY = GustWind.DIRECTION
"""Paper 004's fixed gust direction (x_norm, y_norm); the force is minus this times the power."""

TARGET_RATE = 0.95
"""Issue 41's bar: a reproduction lands at least this often in its paper's conditions."""

DEFAULT_AREA = (-20.0, 20.0, -20.0, 20.0)
"""The scenario's default search area (m, W): a cell that flies it does not name it."""

PAPERS = {
    "falanga2017": "paper 000 (Falanga et al. 2017)",
    "kim_kaist": "paper 003 (Kim et al., KAIST)",
    "zamanakos_sdu": "paper 004 (Zamanakos et al., SDU)",
}


def paper_figure(preset: str, scenario: dict[str, Any]) -> str:
    """What the preset's paper reports for the condition of ``scenario``; none of the three papers gives a
    landing rate, so this is the evidence they do give."""
    platform, wind = scenario.get("platform", {}), scenario.get("wind", {})
    path, speed = platform.get("path"), platform.get("speed_mps")
    if preset == "falanga2017":
        if path == "figure8" and speed == 4.2:
            return "Fig. 7: one simulated landing shown; no rate"
        if path == "straight" and speed == 1.2:
            return "Fig. 9: one real landing shown; no rate"
        return "simulated in Sec. III-B (1-4.2 m/s); no rate"
    if preset == "kim_kaist":
        return "Sec. V-C: 'several landing tests ... successful'; no rate"
    if preset == "zamanakos_sdu":
        what = "gusts" if wind.get("model") == "gust" else "calm"
        return f"draft, evaluation empty ({what}); no rate"
    return "-"


def circle_centre_xy(platform: dict[str, Any]) -> tuple[float, float] | None:
    """The centre (m, W) of a circle path: its radius to the left of the start heading (the platform
    model's circle turns left), or None when the scenario does not say where the circle starts."""
    start, heading = platform.get("start_xy"), platform.get("heading_rad")
    if start is None or heading is None:
        return None
    r = float(platform.get("circle_radius_m", 10.0))
    return float(start[0]) - r * math.sin(float(heading)), float(start[1]) + r * math.cos(float(heading))


def angle_off_upwind_rad(heading_rad: float) -> float:
    """How far (rad, in [0, pi]) a heading is from driving straight into paper 004's gust: the gust
    force is ``-(0.8, 0.2) power``, so the wind comes from the direction of (0.8, 0.2)."""
    from_rad = math.atan2(GUST_DIRECTION_XY[1], GUST_DIRECTION_XY[0])
    return abs(math.remainder(heading_rad - from_rad, 2.0 * math.pi))


def _wind_part(platform: dict[str, Any], wind: dict[str, Any]) -> str:
    heading = platform.get("heading_rad")
    text = f"gusts {_num(wind.get('gust_power_N'))} N"
    if platform.get("path") != "straight" or heading is None:
        return text
    off = angle_off_upwind_rad(float(heading))
    way = "upwind" if off < math.pi / 4 else "downwind" if off > 3 * math.pi / 4 else "across the wind"
    heading_deg, off_deg = math.degrees(float(heading)), math.degrees(off)
    return f"{text}, heading {heading_deg:.0f} deg ({way}, {off_deg:.0f} deg off upwind)"


def cell_label(scenario: dict[str, Any]) -> str:
    """A short name of a mission's condition: path, speed, a circle's centre, the wind (in gusts, the
    straight line's heading to them), and the search area when not the default."""
    platform, wind = scenario.get("platform", {}), scenario.get("wind", {})
    area = scenario.get("search_area", {})
    parts = [f"{platform.get('path', '?')} {_num(platform.get('speed_mps'))} m/s"]
    centre = circle_centre_xy(platform) if platform.get("path") == "circle" else None
    if centre is not None:
        parts.append(f"centre ({_num(round(centre[0], 1) + 0.0)}, {_num(round(centre[1], 1) + 0.0)}) m")
    if wind.get("model") == "gust":
        parts.append(_wind_part(platform, wind))
    elif wind.get("model") not in (None, "none"):
        parts.append(f"wind {wind.get('model')}")
    bounds = tuple(area.get(k) for k in ("x_min", "x_max", "y_min", "y_max"))
    if area and bounds != DEFAULT_AREA:
        dx = float(area["x_max"]) - float(area["x_min"])
        dy = float(area["y_max"]) - float(area["y_min"])
        parts.append(f"area {_num(dy)} x {_num(dx)} m")
    return ", ".join(parts)


def _num(v: Any) -> str:
    return "?" if v is None else f"{float(v):g}"


def failure_mode(result: dict[str, Any]) -> str:
    """How a mission that did not land ended, in a few words."""
    outcome, mode = result.get("outcome"), result.get("final_mode")
    if outcome == "error":
        return "error"
    if not result.get("detections"):
        return f"{outcome} in {mode}, 0 detections"
    reason = result.get("abort_reason")
    return f"{outcome}: {reason}" if reason else f"{outcome} in {mode}"


def _result(run_dir: Path, m: Mission) -> dict[str, Any]:
    path = run_dir / m.mission_dir / "result.json" if m.mission_dir else None
    if path is None or not path.is_file():
        return {"outcome": m.outcome}
    data: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    return data


def cell_rows(run_dir: Path) -> list[dict[str, Any]]:
    """Per (preset, condition) of a campaign output directory: its label, counts, interval and endings."""
    res = read_results(run_dir)  # the campaign package's reader of results.csv: the one call
    cells: dict[tuple[str, str], list[Mission]] = defaultdict(list)
    for m in res.missions:
        cells[(m.preset, m.condition_id)].append(m)
    rows = []
    order = sorted(cells, key=lambda key: (res.presets.index(key[0]), key[1]))
    for preset, cid in order:
        missions = cells[(preset, cid)]
        flown = [m for m in missions if m.flew]
        results = [_result(run_dir, m) for m in missions]
        landed = sum(m.success for m in flown)
        endings = Counter(failure_mode(r) for m, r in zip(missions, results, strict=True) if not m.success)
        scenario = next((r["scenario"] for r in results if isinstance(r.get("scenario"), dict)), {})
        rows.append(
            {
                "preset": preset,
                "condition": cid,
                "label": cell_label(scenario) if scenario else cid,
                "landed": landed,
                "n": len(flown),
                "ci": wilson95(landed, len(flown)),
                "endings": endings,
                "paper": paper_figure(preset, scenario),
            }
        )
    return rows


def _campaign_line(run_dir: Path) -> str:
    lock_path = run_dir / "campaign.lock.json"
    lock = json.loads(lock_path.read_text(encoding="utf-8")) if lock_path.is_file() else {}
    name, seed = lock.get("campaign", run_dir.name), lock.get("campaign_seed", "?")
    n = lock.get("seeds_per_condition", "?")
    seeds = "1 seed" if n == 1 else f"{n} seeds"
    return f"Campaign `{name}`, campaign seed {seed}, {seeds} per cell (output directory `{run_dir.name}`)."


def format_row(row: dict[str, Any]) -> str:
    n, landed, ci = row["n"], row["landed"], row["ci"]
    rate = f"{100.0 * landed / n:.0f} %" if n else "-"
    interval = f"{100.0 * ci[0]:.0f}-{100.0 * ci[1]:.0f} %" if ci else "-"
    met = "yes" if n and landed / n >= TARGET_RATE else "**no**"
    endings = "; ".join(f"{k} {v}" for k, v in row["endings"].most_common()) or "-"
    return (
        f"| `{row['preset']}` | {row['label']} | {landed}/{n} | {rate} | {interval} | {met} | {endings} "
        f"| {row['paper']} |"
    )


def render(run_dirs: list[Path], notes: list[str] | None = None) -> str:
    out = [
        "# The papers' own conditions, measured",
        "",
        "Each paper preset in the conditions its own paper flew (issue 41): the campaign files",
        "`examples/campaigns/paper000_conditions.yaml`, `paper003_conditions.yaml` and",
        "`paper004_conditions.yaml` say in their comments what each paper states and how each choice it",
        "leaves open was made. Generated by `tools/paper_table.py` from the campaigns' outputs:",
        "",
        "    python tools/paper_table.py " + " ".join(f"runs/{d.name}" for d in run_dirs),
        *(["        --note TEXT ...  (one per paragraph after this introduction)"] if notes else []),
        "        --out docs/paper_conditions.md",
        "",
        f"`>= 95 %` is issue 41's bar (landed in at least {100 * TARGET_RATE:.0f} % of the missions of a",
        "cell); the interval is the Wilson score 95 % interval of the landing rate. None of the three papers",
        "gives a landing rate: the last column is the evidence each paper does give for the condition.",
    ]
    for note in notes or []:
        out += ["", note]
    header = "| preset | cell | landed / n | rate | 95 % Wilson | >= 95 % | not landed | paper's own result |"
    for run_dir in run_dirs:
        rows = cell_rows(run_dir)
        papers = sorted({PAPERS.get(r["preset"], r["preset"]) for r in rows})
        out += ["", f"## {', '.join(papers) or run_dir.name}", "", _campaign_line(run_dir), "", header]
        out.append("|---|---|---|---|---|---|---|---|")
        out += [format_row(r) for r in rows]
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(
        prog="tools/paper_table.py", description="docs/paper_conditions.md from campaign outputs"
    )
    parser.add_argument("run_dirs", nargs="+", type=Path, help="campaign output directories")
    parser.add_argument("--out", type=Path, help="write the table here (default: standard output)")
    parser.add_argument("--note", action="append", default=[], help="a paragraph for the introduction")
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:
        return int(exit_.code or 0)
    run_dirs, out_path = list(args.run_dirs), args.out
    for d in run_dirs:
        if not (d / "results.csv").is_file():
            print(f"{d / 'results.csv'}: no such file (run the campaign first)", file=sys.stderr)
            return 2
    text = render(run_dirs, args.note)
    if out_path is None:
        sys.stdout.write(text)
    else:
        out_path.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
