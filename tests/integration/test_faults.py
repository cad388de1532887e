"""Faults reach every preset: each fault key, flown on every preset, changes what the pipeline receives
(the frames the detector sees, the detections, odometry, range, optical-flow and IMU messages), or is
refused with one line. And the closed-loop acceptance: a blacked-out or fully dropping camera never
detects, never lands.

The matrix flies short missions (4.5 s: take-off, with the parked pad coming into view at about 3 s) and
records what reaches the pipeline through its sensor entry points, against the same mission without
faults (the same seed: until a fault acts, both flights are the same bit for bit)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from alight.errors import ConfigError
from alight.evaluation.runner import run_mission
from alight.mission.pipeline import Pipeline
from alight.scenario import scenario_from_dict

PRESETS = ["groundtruth", "falanga2017", "kim_kaist", "zamanakos_sdu"]
BASE: dict[str, Any] = {
    "seed": 3,
    "duration_s": 4.5,
    "platform": {"path": "straight", "speed_mps": 0.0, "start_xy": [1.2, 0.0], "heading_rad": 0.0},
    "optical_flow": {},  # for the flow faults; the module changes nothing else in the flight
}


@dataclass
class Received:
    """What the pipeline was handed, each with the simulated time it arrived (the last IMU sample's)."""

    imu: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)
    odometry: list[tuple[float, np.ndarray]] = field(default_factory=list)
    odometry_resets: list[tuple[float, int | None]] = field(default_factory=list)
    ranges: list[tuple[float, float | None]] = field(default_factory=list)
    flows: list[float] = field(default_factory=list)
    """Times of the optical-flow samples."""
    frames: list[tuple[float, float, Any]] = field(default_factory=list)
    """(arrival time, capture time, image for a camera preset or the observations for groundtruth)."""
    p_WP: np.ndarray | None = None

    @property
    def now(self) -> float:
        return self.imu[-1][0] if self.imu else 0.0


def _spy(monkeypatch: pytest.MonkeyPatch, rec: Received) -> Callable[[float, np.ndarray, list[Any]], None]:
    on_imu, on_odo, on_range, on_obs, on_flow = (
        Pipeline.on_imu,
        Pipeline.on_odometry,
        Pipeline.on_range,
        Pipeline.on_observations,
        Pipeline.on_flow,
    )

    def imu(self: Pipeline, t: float, f: np.ndarray, w: np.ndarray) -> None:
        rec.imu.append((t, np.array(f), np.array(w)))
        on_imu(self, t, f, w)

    def odo(
        self: Pipeline,
        t: float,
        p: np.ndarray,
        q: np.ndarray,
        v: np.ndarray | None = None,
        reset_counter: int | None = None,
    ) -> None:
        rec.odometry.append((t, np.array(p)))
        rec.odometry_resets.append((t, reset_counter))
        on_odo(self, t, p, q, v, reset_counter)

    def rng(self: Pipeline, t: float, r: float | None) -> None:
        # a valid reading, or None for what the sensor reports as invalid (+-inf: out of range or in its
        # blind zone, REP 117; None)
        rec.ranges.append((t, r if r is not None and math.isfinite(r) else None))
        on_range(self, t, r)

    def flow(self: Pipeline, t: float, flow_B: np.ndarray, distance_m: float) -> None:
        rec.flows.append(t)
        on_flow(self, t, flow_B, distance_m)

    def obs(self: Pipeline, t: float, o: list[Any]) -> Any:
        if self.detector is None:  # the ground-truth sensor's reports come straight here
            rec.frames.append((rec.now, t, list(o)))
        return on_obs(self, t, o)

    monkeypatch.setattr(Pipeline, "on_imu", imu)
    monkeypatch.setattr(Pipeline, "on_odometry", odo)
    monkeypatch.setattr(Pipeline, "on_range", rng)
    monkeypatch.setattr(Pipeline, "on_observations", obs)
    monkeypatch.setattr(Pipeline, "on_flow", flow)

    def sink(t_cap: float, image: np.ndarray, _obs: list[Any]) -> None:
        rec.frames.append((rec.now, t_cap, image.copy()))

    return sink


def _fly(
    monkeypatch: pytest.MonkeyPatch, preset: str, faults: dict[str, Any], platform: dict[str, Any]
) -> Received:
    rec = Received()
    with monkeypatch.context() as m:
        sink = _spy(m, rec)
        s = scenario_from_dict(
            {**BASE, "preset": preset, "faults": faults, "platform": {**BASE["platform"], **platform}}
        )
        run = run_mission(s, record=True, frame_sink=sink)
    assert run.log is not None
    rec.p_WP = run.log["p_WP"]
    return rec


_BASELINES: dict[str, Received] = {}


@pytest.fixture
def baseline(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[str], Received]]:
    def get(preset: str) -> Received:
        if preset not in _BASELINES:
            _BASELINES[preset] = _fly(monkeypatch, preset, {}, {})
        return _BASELINES[preset]

    yield get


def _seen(frame: Any) -> bool:
    """A frame of the ground-truth sensor that reported the pad."""
    return isinstance(frame, list) and len(frame) > 0


def _window(msgs: list[tuple[float, np.ndarray, np.ndarray]], i: int, t0: float, t1: float) -> np.ndarray:
    return np.array([m[i] for m in msgs if t0 <= m[0] < t1])


# -- what each fault must do to what the pipeline receives: (fault keys, platform keys, check) -----------


def _dropout(base: Received, got: Received, camera: bool) -> None:
    if camera:
        assert len(base.frames) > 40 and got.frames == []  # no frame reaches the detector
    else:
        assert any(_seen(f) for _, _, f in base.frames) and not any(_seen(f) for _, _, f in got.frames)


def _blackout(base: Received, got: Received, camera: bool) -> None:
    if camera:  # dark frames are delivered
        assert len(got.frames) == len(base.frames) and all(f.max() == 0 for _, _, f in got.frames)
        assert all(f.max() > 0 for _, _, f in base.frames)
    else:
        assert any(_seen(f) for _, _, f in base.frames) and not any(_seen(f) for _, _, f in got.frames)


def _lags(rec: Received) -> np.ndarray:
    return np.array([arrived - cap for arrived, cap, _ in rec.frames])


def _latency(base: Received, got: Received, camera: bool) -> None:
    assert _lags(got).mean() == pytest.approx(_lags(base).mean() + 0.3, abs=0.006)


def _jitter(base: Received, got: Received, camera: bool) -> None:
    assert _lags(base).std() < 1e-3 and _lags(got).std() > 0.015
    caps = [cap for _, cap, _ in got.frames]
    assert caps == sorted(caps)  # delivered in capture order


def _first_frame_differs(base: Received, got: Received, camera: bool) -> None:
    a, b = base.frames[0], got.frames[0]
    assert a[1] == b[1] and not np.array_equal(a[2], b[2])  # same capture, different image


def _frozen(base: Received, got: Received, camera: bool) -> None:
    def repeats(rec: Received) -> int:
        n = 0
        for (_, _, a), (_, _, b) in zip(rec.frames, rec.frames[1:], strict=False):
            if camera:
                n += int(np.array_equal(a, b))
            elif _seen(a) and _seen(b):
                n += int(np.array_equal(a[0].p_CP, b[0].p_CP))
        return n

    assert repeats(base) == 0 and repeats(got) > 0


def _accel_bias(base: Received, got: Received, camera: bool) -> None:
    d = _window(got.imu, 1, 1.0, 1.1).mean(axis=0) - _window(base.imu, 1, 1.0, 1.1).mean(axis=0)
    assert np.allclose(d, [0.5, 0.0, 0.0], atol=0.05), d
    before = _window(got.imu, 1, 0.5, 1.0) - _window(base.imu, 1, 0.5, 1.0)
    assert np.all(before == 0.0)


def _gyro_bias(base: Received, got: Received, camera: bool) -> None:
    d = _window(got.imu, 2, 1.0, 1.1).mean(axis=0) - _window(base.imu, 2, 1.0, 1.1).mean(axis=0)
    assert np.allclose(d, [0.0, 0.0, 0.05], atol=0.005), d


def _odometry_jump(base: Received, got: Received, camera: bool) -> None:
    a = next(p for t, p in base.odometry if t >= 1.0)
    b = next(p for t, p in got.odometry if t >= 1.0)
    assert np.allclose(b - a, [0.5, 0.0, 0.0], atol=0.01)
    # announced (the default): the reset counter goes up with the jump, as a VIO's does
    assert all(c == 0 for t, c in base.odometry_resets)
    assert all(c == (1 if t >= 1.0 else 0) for t, c in got.odometry_resets)


def _odometry_dropout(base: Received, got: Received, camera: bool) -> None:
    assert sum(1.0 <= t <= 1.5 for t, _ in base.odometry) >= 19
    assert sum(1.0 <= t <= 1.5 for t, _ in got.odometry) == 0


def _range_dropout_prob(base: Received, got: Received, camera: bool) -> None:
    assert sum(r is not None for _, r in base.ranges) > 100 and all(r is None for _, r in got.ranges)


def _range_dropouts(base: Received, got: Received, camera: bool) -> None:
    # after the climb has left the sensor's 0.2 m blind zone, where every reading is invalid anyway
    assert all(r is not None for t, r in base.ranges if 2.5 <= t <= 3.0)
    assert all(r is None for t, r in got.ranges if 2.5 <= t <= 3.0)
    assert any(r is not None for t, r in got.ranges if t > 3.0)


def _range_spurious(base: Received, got: Received, camera: bool) -> None:
    b = {t: r for t, r in base.ranges if r is not None}
    diffs = [abs(r - b[t]) for t, r in got.ranges if r is not None and t in b]
    assert len(diffs) > 100 and np.mean(np.array(diffs) > 0.2) > 0.8


def _flow_dropout_prob(base: Received, got: Received, camera: bool) -> None:
    assert len(base.flows) > 50 and not got.flows


def _flow_dropouts(base: Received, got: Received, camera: bool) -> None:
    assert sum(1.0 <= t <= 1.5 for t in base.flows) >= 20
    assert not any(1.0 <= t <= 1.5 for t in got.flows) and any(t > 1.5 for t in got.flows)


def _speed_profile(base: Received, got: Received, camera: bool) -> None:
    assert base.p_WP is not None and got.p_WP is not None
    assert np.allclose(base.p_WP[-1], base.p_WP[0])  # parked
    assert np.linalg.norm(got.p_WP[-1] - got.p_WP[0]) > 3.0  # ramped to 2 m/s from 0.5 s


CORRUPTIONS = ["noise", "occlusion", "exposure", "stripes"]
CASES: dict[str, tuple[dict[str, Any], dict[str, Any], Callable[[Received, Received, bool], None]]] = {
    "dropout_prob": ({"dropout_prob": 1.0}, {}, _dropout),
    "blackouts": ({"blackouts": [[0.0, 100.0]]}, {}, _blackout),
    "latency_s": ({"latency_s": 0.3}, {}, _latency),
    "latency_jitter_s": ({"latency_jitter_s": 0.05}, {}, _jitter),
    **{
        f"corruption.{k}": ({"corruption": {k: {"prob": 1.0}}}, {}, _first_frame_differs) for k in CORRUPTIONS
    },
    "corruption.frozen": ({"corruption": {"frozen": {"prob": 0.5}}}, {}, _frozen),
    "accel_bias_steps": ({"accel_bias_steps": [{"t_s": 1.0, "delta": [0.5, 0, 0]}]}, {}, _accel_bias),
    "gyro_bias_steps": ({"gyro_bias_steps": [{"t_s": 1.0, "delta": [0, 0, 0.05]}]}, {}, _gyro_bias),
    "odometry_jumps": ({"odometry_jumps": [{"t_s": 1.0, "offset_m": [0.5, 0, 0]}]}, {}, _odometry_jump),
    "odometry_dropouts": ({"odometry_dropouts": [[1.0, 1.5]]}, {}, _odometry_dropout),
    "range_dropout_prob": ({"range_dropout_prob": 1.0}, {}, _range_dropout_prob),
    "range_dropouts": ({"range_dropouts": [[2.5, 3.0]]}, {}, _range_dropouts),
    "range_spurious_prob": ({"range_spurious_prob": 1.0}, {}, _range_spurious),
    "flow_dropout_prob": ({"flow_dropout_prob": 1.0}, {}, _flow_dropout_prob),
    "flow_dropouts": ({"flow_dropouts": [[1.0, 1.5]]}, {}, _flow_dropouts),
    "platform.speed_profile": (
        {},
        {"speed_profile": {"ramp": {"t_s": 0.5, "speed_mps": 2.0, "accel_mps2": 2.0}}},
        _speed_profile,
    ),
}
# Refused: image corruptions on the preset without an image.
REFUSED = {("groundtruth", f"corruption.{k}") for k in CORRUPTIONS}


def test_every_fault_key_is_in_the_matrix() -> None:
    from alight.scenario import CorruptionSpec, FaultSpec

    keys = {k for k in FaultSpec.model_fields if k != "corruption"}
    keys |= {f"corruption.{k}" for k in CorruptionSpec.model_fields}
    assert keys | {"platform.speed_profile"} == set(CASES)


@pytest.mark.slow
@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("key", list(CASES))
def test_fault_acts_on_every_preset_or_is_refused(
    monkeypatch: pytest.MonkeyPatch, baseline: Callable[[str], Received], key: str, preset: str
) -> None:
    faults, platform, check = CASES[key]
    if (preset, key) in REFUSED:
        with pytest.raises(ConfigError, match="faults.corruption needs a camera preset") as err:
            _fly(monkeypatch, preset, faults, platform)
        assert "\n" not in str(err.value)
        return
    check(baseline(preset), _fly(monkeypatch, preset, faults, platform), preset != "groundtruth")


# -- closed-loop acceptance ---------------------------------------------------------------------------


def _falanga(faults: dict[str, Any], duration_s: float = 60.0) -> dict[str, Any]:
    s = scenario_from_dict(
        {
            "preset": "falanga2017",
            "seed": 1,
            "duration_s": duration_s,
            "platform": {"path": "straight", "speed_mps": 1.2},
            "faults": faults,
        }
    )
    return run_mission(s, record=False).result


@pytest.mark.slow
def test_falanga2017_blacked_out_camera_never_detects_never_lands() -> None:
    # Without the fault this mission lands at 19.9 s with 194 detections (tests/integration/test_missions).
    r = _falanga({"blackouts": [[0.0, 1000.0]]})
    assert r["detections"] == 0 and r["time_first_detection_s"] is None
    assert r["outcome"] != "landed" and r["touchdown_error_m"] is None
    assert r["frames_processed"] > 0  # the detector ran, on dark frames


@pytest.mark.slow
def test_falanga2017_camera_losing_every_frame_never_detects() -> None:
    r = _falanga({"dropout_prob": 1.0}, duration_s=30.0)
    assert r["detections"] == 0 and r["time_first_detection_s"] is None
    assert r["outcome"] != "landed" and r["frames_processed"] == 0
    assert not math.isnan(r["simulated_time_s"])


@pytest.mark.slow
def test_falanga2017_blackout_during_the_descent_goes_around_then_lands() -> None:
    # The descent starts at 12.8 s from 2.5 m at 0.4 m/s: the camera goes dark at 13.5 s, well above the
    # commit height (0.6 m), for 4 s (longer than the 3 s lost timeout).
    r = _falanga({"blackouts": [[13.5, 17.5]]})
    modes = [h["mode"] for h in r["mode_history"]]
    i_ga = modes.index("go_around")
    assert modes[i_ga - 1] == "land" and 13.5 < r["mode_history"][i_ga]["t"] < 17.5
    assert r["go_arounds"] >= 1 and "land" in modes[i_ga + 1 :]
    assert r["outcome"] == "landed" and r["time_to_land_s"] > 17.5


@pytest.mark.slow
def test_an_odometry_jump_in_the_committed_descent_does_not_throw_the_vehicle_off_the_pad() -> None:
    # zamanakos_sdu, seed 147213886 of examples/campaigns/faults.yaml (c003): the descent starts at
    # 10.1 s and the odometry jumps 0.5 m at 15 s, 0.1 m above the deck. Announced (the VIO's reset
    # counter), the pipeline keeps one continuous frame across the ego estimator's restart and lands.
    def fly(announced: bool) -> dict[str, Any]:  # unannounced: the unit tests (test_pipeline_hooks)
        jump = {"t_s": 15.0, "offset_m": [0.5, 0.0, 0.0], "announced": announced}
        s = scenario_from_dict(
            {
                "preset": "zamanakos_sdu",
                "seed": 147213886,
                "duration_s": 90.0,
                "platform": {"path": "straight", "speed_mps": 1.2},
                "faults": {"odometry_jumps": [jump]},
            }
        )
        return run_mission(s, record=False).result

    r = fly(announced=True)
    assert r["outcome"] == "landed" and r["touchdown_error_m"] < 0.1
    assert r["time_first_contact_s"] > 15.0  # the jump came before the touchdown
    assert r["go_arounds"] == 0
