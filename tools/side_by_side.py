"""The same campaign flown different ways, side by side: one row per condition, one column group per
run (alight's simulator, the emulated autopilot, PX4 SITL, ...): landed / flown with the Wilson 95 %
interval, the median touchdown error, the relative horizontal speed at contact (p95), and how the
others ended.

    python tools/side_by_side.py runs/px4=PX4 runs/px4_emulator=emulator runs/px4_sim=sim \\
        [--out table.md]

Each argument is a campaign output directory, optionally with ``=LABEL``. Conditions are matched by
their ``condition_id`` and labelled with the campaign's condition name; a condition missing from a run
shows as ``-``. The rows come from the campaign package's results reader, as the report's do, so a
damaged row is left out here too.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from alight.campaign import wilson95
from alight.campaign.report import Mission, read_results
from alight.errors import AlightError


def _condition_names(out: Path) -> dict[str, str]:
    lock = json.loads((out / "campaign.lock.json").read_text(encoding="utf-8"))
    names: dict[str, str] = {}
    for m in lock["missions"]:
        names.setdefault(m["condition_id"], str(m["scenario"].get("name") or m["condition_id"]))
    return names


def _cell(missions: list[Mission]) -> str:
    """One run's figures of one condition, as table cells."""
    if not missions:
        return "- | - | - | -"
    flown = [m for m in missions if m.flew]
    landed = sum(m.outcome == "landed" for m in flown)
    ci = wilson95(landed, len(flown))
    rate = "-" if ci is None else f"{landed}/{len(flown)} ({100 * ci[0]:.0f}-{100 * ci[1]:.0f} %)"
    err = [m.values.get("touchdown_error_m") for m in flown if m.outcome == "landed"]
    err_f = [e for e in err if e is not None]
    rel = [m.values.get("touchdown_rel_horizontal_speed_mps") for m in flown if m.outcome == "landed"]
    rel_f = [r for r in rel if r is not None]
    others = Counter(m.outcome for m in missions if m.outcome != "landed")
    med = f"{np.median(err_f):.2f}" if err_f else "-"
    p95 = f"{np.percentile(rel_f, 95):.2f}" if rel_f else "-"
    how = ", ".join(f"{n} {k}" for k, n in sorted(others.items())) or "-"
    return f"{rate} | {med} | {p95} | {how}"


def table(runs: list[tuple[Path, str]]) -> str:
    """The markdown table of ``runs`` (directory, label)."""
    by_run: list[dict[str, list[Mission]]] = []
    names: dict[str, str] = {}
    for out, _ in runs:
        cells: dict[str, list[Mission]] = defaultdict(list)
        for m in read_results(out).missions:
            cells[m.condition_id].append(m)
        by_run.append(cells)
        for cid, name in _condition_names(out).items():
            names.setdefault(cid, name)
    head = (
        "| condition | "
        + " | ".join(
            f"{label}: landed (Wilson 95 %) | median error (m) | p95 rel. speed (m/s) | others"
            for _, label in runs
        )
        + " |"
    )
    sep = "|---|" + "---|---|---|---|" * len(runs)
    rows = [
        f"| {names[cid]} | " + " | ".join(_cell(r.get(cid, [])) for r in by_run) + " |"
        for cid in sorted(names)
    ]
    return "\n".join([head, sep, *rows]) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", help="campaign output directory[=LABEL]")
    p.add_argument("--out", default=None, help="write the table here (default: stdout)")
    args = p.parse_args(argv)
    runs = []
    for spec in args.runs:
        path, _, label = spec.partition("=")
        runs.append((Path(path), label or Path(path).name))
    try:
        text = table(runs)
    except (AlightError, OSError, KeyError, ValueError) as err:
        print(f"side_by_side: {err}", file=sys.stderr)
        return 2
    if args.out:
        Path(args.out).write_text(text, encoding="utf-8")
    else:
        print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
