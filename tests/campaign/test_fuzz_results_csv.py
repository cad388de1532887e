"""The results.csv fuzz harness in short (benchmarks/fuzz_results_csv.py; the 500-variant run is in the
issue notes): every damaged file refused in one line or reported honestly."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]


def test_fuzz_harness_short_run_finds_no_failure() -> None:
    spec = importlib.util.spec_from_file_location(
        "fuzz_results_csv", ROOT / "benchmarks" / "fuzz_results_csv.py"
    )
    assert spec is not None and spec.loader is not None
    module: ModuleType = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    env = dict(os.environ)
    try:
        summary = module.run(40, seed=2)  # a seed whose 40 variants include refused files (5 of 40)
    finally:
        os.environ.clear()
        os.environ.update(env)
    assert summary["FAILURE"] == 0, summary["failures"]
    assert summary["refused"] > 0 and summary["reported"] > 0, {
        k: summary[k] for k in ("refused", "reported")
    }
