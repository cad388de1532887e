"""Landed / safe abort / crash per fault class and preset, from a fault campaign's output directory.

    python examples/campaigns/fault_table.py runs/faults

A class is named by the fault keys its condition sets (``platform.speed_profile`` by its kind). Outcomes:
``landed``; ``safe abort`` = ``aborted``, or ``timeout`` (still flying at the end): the vehicle touched
nothing (any contact is judged at once, ``landed`` or ``crashed``); ``crash`` = ``crashed``; ``refused`` =
an ``error`` row whose message says the fault cannot act on the preset (``faults.corruption needs a
camera preset``); any other error is counted under ``error``.
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any

from alight.campaign.results import read_rows
from alight.scenario import FaultSpec

_DEFAULT_FAULTS = FaultSpec().model_dump(mode="json")


def class_name(params: dict[str, Any]) -> str:
    names: list[str] = []
    faults = params.get("faults")
    if isinstance(faults, dict):
        for key, value in faults.items():
            if key == "corruption" and isinstance(value, dict):
                names += [
                    f"corruption.{k}" for k, v in value.items() if v != _DEFAULT_FAULTS["corruption"][k]
                ]
            elif key == "odometry_jumps" and value and any(j.get("announced") is False for j in value):
                names.append("odometry_jumps.unannounced")
            elif value != _DEFAULT_FAULTS.get(key):
                names.append(key)
        if len([n for n in names if n.startswith("corruption.")]) > 1:
            names = [n for n in names if not n.startswith("corruption.")] + ["corruption"]
    profile = params.get("platform.speed_profile")
    if isinstance(profile, dict):
        names += [f"speed_profile.{k}" for k, v in profile.items() if v is not None]
    return "+".join(names) or "none"


def table(out_dir: Path) -> str:
    lock = json.loads((out_dir / "campaign.lock.json").read_text())
    rows = read_rows(out_dir / "results.csv")  # the campaign package's one reader of results.csv
    cond_name = {c["condition_id"]: class_name(c["params"]) for c in lock["conditions"]}
    counts: dict[tuple[str, str], Counter[str]] = {}
    for r in rows:
        outcome = r["outcome"]
        if outcome in ("aborted", "timeout"):
            outcome = "safe abort"
        elif outcome == "crashed":
            outcome = "crash"
        elif outcome == "error":
            outcome = "refused" if "needs a camera preset" in r.get("error", "") else "error"
        elif outcome != "landed":
            outcome = "other"  # an outcome this table does not know: shown, never dropped
        counts.setdefault((r["condition_id"], r["preset"]), Counter())[outcome] += 1
    cols = ["landed", "safe abort", "crash", "refused", "error", "other"]
    lines = [
        "| condition | class | preset | n | " + " | ".join(cols) + " |",
        "|---|---|---|---|" + "---|" * len(cols),
    ]
    for c in lock["conditions"]:
        cid = c["condition_id"]
        for preset in lock["presets"]:
            k = counts.get((cid, preset))
            if not k:
                continue
            n = sum(k.values())
            cells = " | ".join(str(k.get(col, 0)) for col in cols)
            lines.append(f"| {cid} | {cond_name[cid]} | {preset} | {n} | {cells} |")
    return "\n".join(lines)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: fault_table.py CAMPAIGN_OUTPUT_DIR")
    print(table(Path(sys.argv[1])))
