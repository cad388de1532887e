"""Frames only when they are used: the runner renders a camera frame only when the detector will read it
(not a lost frame, not a dark one, not one a QoS rate skips), and the mission is bit for bit the one
flown with every frame rendered (``run_mission(render_every_frame=True)``)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from alight.evaluation.replay import FrameRecorder
from alight.evaluation.runner import MissionRun, run_mission
from alight.mission.pipeline import Pipeline
from alight.perception import FrameGate
from alight.perception.qos_detector import QosDetector
from alight.scenario import scenario_from_dict
from alight.sim.render import Renderer

# The pad parked 1.2 m ahead of the take-off point comes into view at about 3 s.
BASE: dict[str, Any] = {
    "seed": 3,
    "duration_s": 6.0,
    "platform": {"path": "straight", "speed_mps": 0.0, "start_xy": [1.2, 0.0], "heading_rad": 0.0},
}
FAULTS: dict[str, Any] = {
    "dropout_prob": 0.4,
    "blackouts": [[3.5, 4.2]],
    "latency_jitter_s": 0.02,
    "corruption": {"noise": {"prob": 0.2}, "occlusion": {"prob": 0.2}, "stripes": {"prob": 0.2}},
}


class _Counts:
    def __init__(self) -> None:
        self.renders: list[float] = []
        self.images: list[tuple[float, bool]] = []  # (capture time, the detector read it)
        self.detectors: list[Any] = []


def _fly(
    monkeypatch: pytest.MonkeyPatch,
    scenario: dict[str, Any],
    *,
    every: bool,
    recorder: FrameRecorder | None = None,
    wanted: bool = True,
) -> tuple[MissionRun, _Counts]:
    c = _Counts()
    render, on_image = Renderer.render, Pipeline.on_image

    def counting_render(self: Renderer, *a: Any, **kw: Any) -> np.ndarray:
        c.renders.append(float(kw["t_s"]))
        return render(self, *a, **kw)

    def spying_on_image(self: Pipeline, t: float, image: np.ndarray) -> Any:
        c.images.append((t, self.will_process_image(t)))
        if not c.detectors:
            c.detectors.append(self.detector)
        return on_image(self, t, image)

    with monkeypatch.context() as m:
        m.setattr(Renderer, "render", counting_render)
        m.setattr(Pipeline, "on_image", spying_on_image)
        run = run_mission(
            scenario_from_dict(scenario),
            record=True,
            render_every_frame=every,
            frame_sink=recorder,
            frame_wanted=recorder.wants if recorder is not None and wanted else None,
        )
    return run, c


_TIMINGS = {"wall_time_s", "block_time_s", "cpu_time_s", "energy_compute_measured_J"}


def _same(a: MissionRun, b: MissionRun) -> None:
    ra = {k: v for k, v in a.result.items() if k not in _TIMINGS}
    rb = {k: v for k, v in b.result.items() if k not in _TIMINGS}
    assert ra == rb
    assert a.log is not None and b.log is not None
    assert sorted(a.log) == sorted(b.log)
    for k in a.log:
        np.testing.assert_array_equal(a.log[k], b.log[k], err_msg=k)
    assert a.events == b.events
    assert a.mode_history == b.mode_history


def test_lost_and_dark_frames_are_never_rendered_and_the_mission_is_unchanged(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    s = {**BASE, "preset": "falanga2017", "faults": FAULTS}
    lazy, c = _fly(monkeypatch, s, every=False)
    full, c_full = _fly(monkeypatch, s, every=True)
    _same(lazy, full)
    # falanga2017's detector reads every frame it is handed: each delivered frame that is not dark is
    # rendered once, nothing else (lost frames never reach on_image)
    delivered = [t for t, _ in c.images]
    dark = [t for t in delivered if 3.5 <= t <= 4.2]
    assert dark and len(delivered) > 20
    assert c.renders == [t for t in delivered if not 3.5 <= t <= 4.2]
    assert c_full.renders == c.renders  # a dark frame is black without rendering in both
    # about 40 % of the captured frames were lost: far fewer renders than captures at 20 Hz
    first = delivered[0]
    captured = round((6.0 - first) * 20.0)
    assert len(c.renders) < 0.75 * captured


def test_frames_a_qos_rate_skips_are_never_rendered_and_the_mission_is_unchanged(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # 20 Hz camera, the SDU detector at 10 Hz: every other frame is skipped by the rate
    s = {**BASE, "preset": "zamanakos_sdu", "perception": {"rate_hz": 20.0}}
    lazy, c = _fly(monkeypatch, s, every=False)
    full, c_full = _fly(monkeypatch, s, every=True)
    _same(lazy, full)
    det = c.detectors[0]
    assert isinstance(det, QosDetector) and isinstance(det, FrameGate)
    read = [t for t, used in c.images if used]
    skipped = [t for t, used in c.images if not used]
    assert skipped and read
    assert c.renders == read  # rendered exactly the frames the detector read
    assert len(c_full.renders) == len(c.images)
    assert det.frames_skipped == len(skipped) and det.frames_processed == len(read)


def test_a_recorder_gets_the_frames_it_keeps_rendered_and_nothing_more(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The campaign records every mission for a failure's replay: with the recorder's frame_wanted, a
    # gated detector's skipped frames are rendered only where the recorder keeps one, the mission is
    # unchanged, and the recorder keeps the same frames as when every frame is rendered for it.
    s = {**BASE, "preset": "zamanakos_sdu", "perception": {"rate_hz": 20.0}}
    lazy, c = _fly(monkeypatch, s, every=False)
    rec = FrameRecorder(rate_hz=8.0)
    kept, c_kept = _fly(monkeypatch, s, every=False, recorder=rec)
    rec_all = FrameRecorder(rate_hz=8.0)
    _, c_all = _fly(monkeypatch, s, every=False, recorder=rec_all, wanted=False)
    _same(lazy, kept)
    read = {t for t, used in c.images if used}
    kept_t = [t for t, _, _ in rec.frames]
    assert c_kept.renders == sorted(read | set(kept_t))
    assert len(c_all.renders) == len(c.images)  # without frame_wanted a sink sees every frame
    assert len(c_kept.renders) < len(c_all.renders)
    # the 20 Hz camera's frames 0.05 s apart, one kept per 0.125 s: alternately 0.15 and 0.10 s apart
    assert np.all(np.round(np.diff(kept_t), 6) >= 0.1) and len(kept_t) > 10
    assert [f[0] for f in rec.frames] == [f[0] for f in rec_all.frames]
    for a, b in zip(rec.frames, rec_all.frames, strict=True):
        np.testing.assert_array_equal(a[1], b[1])
        assert [o.kind for o in a[2]] == [o.kind for o in b[2]]


def test_qos_will_process_answers_what_detect_then_does() -> None:
    from alight.energy.qos import QosSetting

    class Inner:
        def detect(self, image: object, t: float) -> list[Any]:
            return []

    q = QosDetector(Inner(), QosSetting(7.0, 1.0, 41))
    image = np.zeros((8, 8), np.uint8)
    for k in range(200):
        t = k / 30.0
        before = q.frames_processed
        will = q.will_process(t)
        assert q.will_process(t) == will  # no state change
        q.detect(image, t)
        assert (q.frames_processed == before + 1) == will
    assert 0 < q.frames_skipped < 200


def test_noise_offsets_drawn_ahead_keep_later_frames_identical() -> None:
    from alight.cameras.pinhole import PinholeCamera
    from alight.pads import FalangaTag
    from alight.sim.render import RenderOptions
    from alight.sim.textures import make_ground_texture

    def renderer() -> Renderer:
        rng = np.random.default_rng(5)
        ground = make_ground_texture("grass", rng)
        return Renderer(PinholeCamera.default_downward(), ground, FalangaTag(), RenderOptions(), rng)

    a, b = renderer(), renderer()
    R = np.diag([1.0, -1.0, -1.0])  # looking down
    pose = (np.zeros(3), 0.3)
    frames_a = [a.render(np.array([0.1 * k, 0.0, 3.0]), R, pose) for k in range(6)]
    offsets = [b.draw_noise_offset() for _ in range(6)]
    for k in (1, 4, 5):  # frames 0, 2, 3 not rendered
        f = b.render(np.array([0.1 * k, 0.0, 3.0]), R, pose, noise_offset=offsets[k])
        np.testing.assert_array_equal(f, frames_a[k])
