"""The robustness harness in short (benchmarks/robustness_harness.py; the full run is in the issue notes):
garbage frames give no detection and no crash, bad measurements no crash, no NaN state, no blocked filter."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _harness() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "robustness_harness", ROOT / "benchmarks" / "robustness_harness.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def summary() -> dict:
    # aruco/apriltag take seconds per noise frame in OpenCV: fewer frames for them keep this short
    h = _harness()
    out = h.run(
        n_frames=50, n_measurements=50, seed=1, limit_s=30.0, detectors=["falanga", "nfold", "red", "sdu"]
    )
    out["detectors"].update(h.run_detectors(8, 1, 30.0, ["aruco", "apriltag"]))
    return out


def test_no_detector_crashes_hangs_or_finds_a_pad_in_garbage(summary: dict) -> None:
    assert set(summary["detectors"]) == {"falanga", "nfold", "red", "sdu", "aruco", "apriltag"}
    for name, d in summary["detectors"].items():
        assert d["crashes"] == d["hangs"] == d["false_detections"] == 0, (name, d)


def test_no_estimator_crashes_goes_nan_or_stays_blocked(summary: dict) -> None:
    for name, e in summary["platform_estimators"].items():
        assert e["crashes"] == e["hangs"] == e["nan_states"] == 0, (name, e)
        assert e["refused"] == e["bad"], (name, e)  # every bad measurement refused ...
        assert e["good_used_frac"] >= 0.9 and e["final_error_m"] < 0.5, (name, e)  # ... and nothing blocked
    for name, e in summary["ego_estimators"].items():
        assert e["crashes"] == e["hangs"] == e["nan_states"] == 0 and e["final_error_m"] < 0.5, (name, e)
