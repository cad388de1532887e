"""The scenario fuzz harness in short (benchmarks/fuzz_scenarios.py, issue 39; the long run is in the
branch's report): mutated scenario files through ``alight fly --print-config`` and the flight's build
give no traceback, no hang, and every refusal in one line that names the file."""

from __future__ import annotations

import importlib.util
import signal
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _harness() -> ModuleType:
    spec = importlib.util.spec_from_file_location("fuzz_scenarios", ROOT / "benchmarks" / "fuzz_scenarios.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def harness() -> ModuleType:
    return _harness()


def test_mutated_scenarios_are_refused_in_one_line_or_accepted(harness: ModuleType) -> None:
    # 40 variants: each of the 29 mutations once, then at random
    summary: dict[str, Any] = harness.run(n=40, seed=2, limit_s=60.0)
    assert summary["variants"] == 40
    assert summary["failures"] == 0, summary["examples"]
    assert summary["refused"] > 20 and summary["accepted"] > 0


def test_a_traceback_is_counted(harness: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The harness can fail: a loader that raises a raw exception, or refuses in two lines, is caught."""
    path = tmp_path / "bad.yaml"
    path.write_text("preset: groundtruth\n", encoding="utf-8")

    def broken(argv: list[str]) -> int:
        raise KeyError("x")

    signal.signal(signal.SIGALRM, harness._on_alarm)  # the watchdog's handler, as run() sets it
    counts = harness.Counts()
    monkeypatch.setattr(harness, "alight_main", broken)
    harness.check_variant(path, "k", counts, 10.0, set())
    assert counts.c["tracebacks"] == 1

    def two_lines(argv: list[str]) -> int:
        print("alight fly: bad.yaml: one\nand two", file=sys.stderr)
        return 2

    monkeypatch.setattr(harness, "alight_main", two_lines)
    harness.check_variant(path, "k", counts, 10.0, set())
    assert counts.c["not_one_line"] == 1


def test_every_mutation_is_drawn(harness: ModuleType, tmp_path: Path) -> None:
    kinds = [k for k, _ in harness.variants(29, 0, tmp_path)]
    drawn = {":".join(k.split(":")[:2]) for k in kinds}
    assert drawn == {f"tree:{m}" for m in harness.TREE_MUTATIONS} | {
        f"text:{m}" for m in harness.TEXT_MUTATIONS
    }
