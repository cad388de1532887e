"""A small run of the detector acceptance benchmark (``benchmarks/detector_acceptance.py``, issue 3): the
first 60 frames of its seeded acceptance set (the full run uses 2,000) and 30 frames without the pad,
asserting the issue's targets, so that CI keeps checking them."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "detector_acceptance.py"


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("detector_acceptance", BENCH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    return _load()


@pytest.fixture(scope="module")
def run(bench: ModuleType) -> tuple[dict, list]:  # type: ignore[type-arg]
    out = bench.run_acceptance(frames=60, seed=0, negatives=30, small_frames=0, repeats=2, use_pupil=False)
    return out  # type: ignore[no-any-return]


def test_sampled_views_respect_the_issue(bench: ModuleType) -> None:
    """Every kept view: camera 1-20 m above the pad, optical axis <= 30 deg off the vertical, the whole
    pad outline inside the image with the margin, shortest side >= 40 px."""
    rng = np.random.default_rng(5)
    for _ in range(40):
        v, _ = bench.sample_view(rng, bench.ALTITUDE_M, (bench.MIN_SIZE_PX, math.inf))
        assert 1.0 <= v.altitude_m <= 20.0
        assert v.p_WC[2] - v.p_WP[2] == pytest.approx(v.altitude_m)
        assert math.degrees(math.acos(-v.R_WC[2, 2])) <= 30.0 + 1e-9
        assert np.linalg.norm(v.w_WB_B) <= bench.MAX_RATE
        R_CP = v.R_WC.T @ np.array(
            [[math.cos(v.yaw), -math.sin(v.yaw), 0], [math.sin(v.yaw), math.cos(v.yaw), 0], [0, 0, 1]]
        )
        px = bench.CAM.project(bench.TAG.quad_corners_P() @ R_CP.T + v.p_CP)
        m = bench.MARGIN_PX
        assert np.all(px >= m)
        assert np.all(px[:, 0] <= bench.CAM.width - 1 - m) and np.all(px[:, 1] <= bench.CAM.height - 1 - m)
        sides = np.linalg.norm(px - np.roll(px, -1, axis=0), axis=1)
        assert sides.min() == pytest.approx(v.size_px) and v.size_px >= 40.0


def test_negative_views_do_not_see_the_deck(bench: ModuleType) -> None:
    """Moving the platform another 5 km away changes no pixel: no part of the deck is in view."""
    textures = bench.make_textures(np.random.SeedSequence(0))
    rng = np.random.default_rng(6)
    for _ in range(8):
        v = bench.sample_negative(rng)
        farther = v._replace(p_WP=v.p_WP + np.array([5000.0, -5000.0, 0.0]))
        a = bench.render(v, bench.TAG, textures, bench.SensorNoise(np.random.default_rng(1)))
        b = bench.render(farther, bench.TAG, textures, bench.SensorNoise(np.random.default_rng(1)))
        assert a.shape == (480, 752) and np.array_equal(a, b)


def test_detection_pose_and_negatives(run: tuple[dict, list]) -> None:  # type: ignore[type-arg]
    s, records = run
    f = s["falanga"]
    assert s["frames"] == 60 and len(records) == 60
    assert f["detection_rate"] >= 0.99  # i.e. all 60
    assert f["pnp_rel_error_median"] <= 0.01 and f["wrong_detections"] == 0
    assert f["false_detections_on_negatives"] == 0
    assert sum(f["kinds"].values()) == 60
    assert f["detection_rate"] >= s["aruco_apriltag36h11"]["detection_rate"]


def test_stage_timings_are_reported(run: tuple[dict, list]) -> None:  # type: ignore[type-arg]
    """The stage table is produced; the speed targets themselves (< 1.5 ms, >= 6x ArUco) are measured by
    ``alight bench`` / benchmarks/detector_acceptance.py, never asserted in a unit test (wall-clock
    checks fail on a loaded machine for reasons that are not the code's)."""
    s, _ = run
    stages = s["falanga"]["stages_ms"]
    assert set(stages) == {"threshold", "contours", "quad", "inner", "ransac", "total", "pnp"}
    assert all(v["mean"] >= 0 for v in stages.values())


def test_sensor_noise_is_the_renderers(bench: ModuleType) -> None:
    """The added noise has the configured standard deviation (2 DN) and zero mean on a mid-grey image."""
    noise = bench.SensorNoise(np.random.default_rng(2))
    d = np.concatenate([noise.add(np.full((480, 752), 128, np.uint8)).astype(float) - 128 for _ in range(4)])
    assert abs(d.mean()) < 0.02
    assert d.std() == pytest.approx(bench.NOISE_DN, rel=0.03)


def test_a_short_run_leaves_the_docs_plot_alone(
    bench: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Only the full acceptance run replaces ``docs/detection_vs_pad_size.png``; a short one writes a plot
    only where ``--plot`` says."""
    docs_plot = bench._DOCS_PLOT
    before = docs_plot.read_bytes() if docs_plot.exists() else None
    tiny = ["--frames", "4", "--negatives", "1", "--small-frames", "2", "--repeats", "1", "--no-pupil"]
    assert bench.main(tiny) == 0
    assert "plot" not in json.loads(capsys.readouterr().out)
    asked = tmp_path / "by_size.png"
    assert bench.main([*tiny, "--plot", str(asked)]) == 0
    assert json.loads(capsys.readouterr().out)["plot"] == str(asked)
    assert asked.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (docs_plot.read_bytes() if docs_plot.exists() else None) == before
