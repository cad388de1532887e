"""The measured combination table of docs/blocks_measured.md, from a run of examples/campaigns/blocks.yaml.

    alight campaign examples/campaigns/blocks.yaml --out runs/blocks
    python tools/blocks_table.py runs/blocks [--replicates N] > docs/blocks_measured.md

``--replicates N`` counts only the first N seeds of every combination (for a campaign stopped part way:
the campaign flies seed by seed across all combinations, so the first seeds are complete everywhere).

One row per block combination (camera-pad-detector-geolocator-platform_estimator, the block set's name):
landed / flown, median and worst touchdown error of the landed missions, and the outcomes that were not
landings; then, per stage, each block's landings over every combination it is in, which is where a
reader sees which choice matters; then how the missions that did not land ended (from each mission's
``result.json``: the outcome, the mode it ended in, the abort reason, whether any detection became a
pad measurement), per block.
"""

from __future__ import annotations

import json
import statistics
import sys
from collections import Counter, defaultdict
from pathlib import Path

from alight.campaign.results import read_rows
from alight.errors import AlightError

STAGES = ("camera", "pad", "detector", "geolocator", "platform_estimator")


def main(argv: list[str]) -> int:
    replicates: int | None = None
    if len(argv) == 3 and argv[1] == "--replicates" and argv[2].isdigit():
        replicates = int(argv[2])
        argv = argv[:1]
    if len(argv) != 1:
        print("usage: python tools/blocks_table.py RUN_DIR [--replicates N]", file=sys.stderr)
        return 2
    path = Path(argv[0]) / "results.csv"
    if not path.is_file():
        print(f"{path}: no such file (run the campaign first)", file=sys.stderr)
        return 2
    try:
        rows = read_rows(path)  # the campaign package's one reader of results.csv (checked header and rows)
    except AlightError as err:
        print(err, file=sys.stderr)
        return 2
    if replicates is not None:
        rows = [r for r in rows if int(r["replicate"]) < replicates]
    by_combo: dict[str, list[dict[str, str]]] = defaultdict(list)
    for r in rows:
        by_combo[r["preset"]].append(r)

    out = [
        "# Blocks: measured combinations",
        "",
        "Every compatible combination of camera × (pad, detector) × geolocator × platform estimator in",
        "[blocks.md](blocks.md), on falanga2017's controller, planner and mission, flying a 2 m/s circle,",
        "on the same seeds for every combination:",
        "",
        "    alight campaign examples/campaigns/blocks.yaml --out runs/blocks",
        "    python tools/blocks_table.py runs/blocks > docs/blocks_measured.md",
        "",
        f"{len(rows)} missions over {len(by_combo)} combinations"
        + ("" if replicates is None else f" (the first {replicates} seeds of each)")
        + ".",
        "",
        "| camera-pad-detector-geolocator-estimator | landed / flown | median error (m) | max error (m) | "
        "other outcomes |",
        "|---|---|---|---|---|",
    ]
    per_stage: dict[str, dict[str, list[int]]] = {s: defaultdict(lambda: [0, 0]) for s in STAGES}
    for combo in sorted(by_combo):
        rs = by_combo[combo]
        flown = [r for r in rs if r["outcome"] != "error"]
        landed = [r for r in flown if r["outcome"] == "landed"]
        errs = [float(r["touchdown_error_m"]) for r in landed if r["touchdown_error_m"]]
        other = Counter(r["outcome"] for r in rs if r["outcome"] != "landed")
        med = f"{statistics.median(errs):.3f}" if errs else "-"
        worst = f"{max(errs):.3f}" if errs else "-"
        other_txt = ", ".join(f"{k} {v}" for k, v in sorted(other.items())) or "-"
        out.append(f"| `{combo}` | {len(landed)} / {len(flown)} | {med} | {worst} | {other_txt} |")
        for stage, name in zip(STAGES, combo.split("-"), strict=False):
            per_stage[stage][name][0] += len(landed)
            per_stage[stage][name][1] += len(flown)
    out += ["", "## Which block matters", "", "Landings over every combination a block is in:", ""]
    for stage in STAGES:
        parts = [
            f"`{name}` {v[0]}/{v[1]} ({100.0 * v[0] / v[1]:.0f} %)" if v[1] else f"`{name}` -"
            for name, v in sorted(per_stage[stage].items())
        ]
        out.append(f"- {stage}: " + "; ".join(parts))
    out += failure_modes(Path(argv[0]), rows)
    print("\n".join(out))
    return 0


def failure_mode(result: dict[str, object]) -> str:
    """How a mission that did not land ended, in a few words."""
    outcome, mode = result.get("outcome"), result.get("final_mode")
    if outcome == "error":
        return "error"
    if not result.get("detections"):
        return f"{outcome} in {mode}, no pad measurement"
    reason = result.get("abort_reason")
    if reason:
        return f"{outcome}: {reason}"
    return f"{outcome} in {mode}"


def failure_modes(run_dir: Path, rows: list[dict[str, str]]) -> list[str]:
    """Per stage and block, the commonest ways its missions failed to land."""
    per_block: dict[tuple[str, str], Counter[str]] = defaultdict(Counter)
    for r in rows:
        if r["outcome"] == "landed":
            continue
        result_path = run_dir / r["mission_dir"] / "result.json" if r.get("mission_dir") else None
        if result_path is not None and result_path.is_file():
            mode = failure_mode(json.loads(result_path.read_text(encoding="utf-8")))
        else:
            mode = f"{r['outcome']} (no result.json)"
        for stage, name in zip(STAGES, r["preset"].split("-"), strict=False):
            per_block[(stage, name)][mode] += 1
    out = ["", "## How the others ended", "", "The missions that did not land, by how they ended:", ""]
    for stage, name in sorted(per_block):
        modes = per_block[(stage, name)]
        parts = [f"{mode} {n}" for mode, n in modes.most_common(4)]
        rest = sum(modes.values()) - sum(n for _, n in modes.most_common(4))
        out.append(f"- {stage} `{name}`: " + "; ".join(parts) + (f"; other {rest}" if rest else ""))
    return out


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
