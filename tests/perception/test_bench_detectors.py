"""The detector benchmark runs and reports what it promises (a tiny run; the numbers come from
``python benchmarks/bench_detectors.py``)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_detectors.py"


def test_bench_detectors_keys_and_sanity() -> None:
    spec = importlib.util.spec_from_file_location("bench_detectors", BENCH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = mod.bench_detectors(n_per_ground=1, repeats=1)
    assert out["detector_frames"] == 3
    assert all(isinstance(v, float | int) for v in out.values())  # flat, for ``alight bench``
    for key in (
        "detector_ms_per_frame",
        "aruco_apriltag36h11_ms_per_frame",
        "aruco_on_falanga_frames_ms_per_frame",
    ):
        assert out[key] > 0
    assert out["falanga_detection_rate"] == 1.0 and out["aruco_detection_rate"] == 1.0
    for stage in ("threshold", "contours", "quad", "inner", "ransac"):
        assert out[f"falanga_stage_{stage}_ms"] >= 0
    try:
        import pupil_apriltags  # type: ignore[import-not-found]  # noqa: F401

        has_pupil = True
    except ImportError:
        has_pupil = False
    assert ("pupil_apriltags_ms_per_frame" in out) == has_pupil
