"""Fingerprints of the regression missions: every ``result.json`` field but the clocks, and a hash of
each log array, for seeded missions of every preset. A refactoring that must not change behaviour is
checked by writing the fingerprints before and after and comparing them:

    PYTHONPATH=src python tools/regression_fingerprint.py --out before.json
    ... change ...
    PYTHONPATH=src python tools/regression_fingerprint.py --out after.json --compare before.json

``--quick`` flies one mission per preset. Exit 1 when ``--compare`` finds a difference (listed).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

TELEMETRY = {"rate_hz": 10, "noise_m": 0.5, "bias_m": 1.0, "latency_s": 0.2, "dropout_prob": 0.05}

# (name, scenario dict): the closed-loop regression conditions of tests/integration, one or two per preset
CASES: list[tuple[str, dict[str, Any]]] = [
    (
        "groundtruth straight 1.2 s1",
        {"preset": "groundtruth", "seed": 1, "platform": {"path": "straight", "speed_mps": 1.2}},
    ),
    (
        "groundtruth figure8 4.2 s5",
        {"preset": "groundtruth", "seed": 5, "platform": {"path": "figure8", "speed_mps": 4.2}},
    ),
    (
        "falanga2017 circle 2.0 s2",
        {"preset": "falanga2017", "seed": 2, "platform": {"path": "circle", "speed_mps": 2.0}},
    ),
    (
        "falanga2017 figure8 4.2 s3",
        {"preset": "falanga2017", "seed": 3, "platform": {"path": "figure8", "speed_mps": 4.2}},
    ),
    (
        "kim_kaist straight 1.5 s1",
        {"preset": "kim_kaist", "seed": 1, "platform": {"path": "straight", "speed_mps": 1.5}},
    ),
    (
        "zamanakos_sdu straight 1.5 s1",
        {"preset": "zamanakos_sdu", "seed": 1, "platform": {"path": "straight", "speed_mps": 1.5}},
    ),
    (
        "zamanakos_sdu gusts s2",
        {
            "preset": "zamanakos_sdu",
            "seed": 2,
            "platform": {"path": "straight", "speed_mps": 1.5},
            "wind": {"model": "gust", "gust_power_N": 7.76},
        },
    ),
    (
        "alight circle 2 s1",
        {"preset": "alight", "seed": 1, "duration_s": 90, "platform": {"path": "circle", "speed_mps": 2.0}},
    ),
    (
        "alight straight 9 telemetry s2",
        {
            "preset": "alight",
            "seed": 2,
            "duration_s": 90,
            "platform": {"path": "straight", "speed_mps": 9.0, "telemetry": TELEMETRY},
        },
    ),
]
QUICK = {
    "groundtruth straight 1.2 s1",
    "falanga2017 circle 2.0 s2",
    "kim_kaist straight 1.5 s1",
    "zamanakos_sdu straight 1.5 s1",
    "alight circle 2 s1",
}

# result fields measured on the wall clock or the CPU, which no refactoring can keep
CLOCK_WORDS = ("wall", "cpu", "controller_time", "block_time", "compute_time", "elapsed", "per_tick", "_us")


def _is_clock(key: str) -> bool:
    return any(w in key for w in CLOCK_WORDS)


def _scrub(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _scrub(v) for k, v in value.items() if not _is_clock(str(k))}
    if isinstance(value, list | tuple):
        return [_scrub(v) for v in value]
    if isinstance(value, float):
        return repr(value) if not math.isfinite(value) else float.hex(value)
    if isinstance(value, np.generic):
        return _scrub(value.item())
    return value


def fingerprint(case: dict[str, Any]) -> dict[str, Any]:
    from alight.evaluation.runner import run_mission
    from alight.scenario import scenario_from_dict

    run = run_mission(scenario_from_dict(case), record=True)
    logs = {}
    for name, arr in sorted((run.log or {}).items()):
        a = np.ascontiguousarray(arr)
        logs[name] = f"{a.dtype.str}{a.shape}:" + hashlib.sha256(a.tobytes()).hexdigest()[:16]
    return {"result": _scrub(run.result), "log": logs}


def _diff(a: Any, b: Any, where: str, out: list[str]) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{where}.{k}: only in {'after' if k not in a else 'before'}")
            else:
                _diff(a[k], b[k], f"{where}.{k}", out)
    elif a != b:
        out.append(f"{where}: {str(a)[:80]} -> {str(b)[:80]}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--compare")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only", help="comma-separated case names")
    args = ap.parse_args()

    names = [n for n, _ in CASES]
    if args.quick:
        names = [n for n in names if n in QUICK]
    if args.only:
        names = [n for n in names if n in set(args.only.split(","))]
    fps = {}
    for name, case in CASES:
        if name in names:
            fps[name] = fingerprint(case)
            print(f"{name}: {fps[name]['result'].get('outcome')}", file=sys.stderr, flush=True)
    Path(args.out).write_text(json.dumps(fps, indent=1, sort_keys=True))
    if not args.compare:
        return 0
    before = json.loads(Path(args.compare).read_text())
    diffs: list[str] = []
    for name in fps:
        if name not in before:
            diffs.append(f"{name}: not in {args.compare}")
            continue
        _diff(before[name], fps[name], name, diffs)
    for d in diffs:
        print(d)
    print(f"{len(fps)} missions compared, {len(diffs)} differences")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
