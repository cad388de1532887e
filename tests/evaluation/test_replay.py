"""The mission replay GIF: frame timing, lossless encoding of what was drawn, size, and the panels'
content (camera image with the detection drawn where it was found, top view, altitude strip)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.evaluation.replay import (
    CAMERA_PANEL_WIDTH_PX,
    FrameRecorder,
    render_replay_frames,
    replay_times,
    write_replay,
)
from alight.evaluation.runner import run_mission
from alight.pads import FalangaTag
from alight.scenario import Scenario
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import Observation, rot_z

UAV_RGB = np.array([31, 119, 180])  # tab:blue, the UAV in the top view
PLATFORM_RGB = np.array([214, 39, 40])  # tab:red
DETECTION_RGB = np.array([44, 160, 44])  # detection points on the camera image
CENTRE_RGB = np.array([255, 230, 0])  # detection centre cross


@pytest.fixture(scope="module")
def mission_log() -> dict[str, np.ndarray]:
    """A short ground-truth mission (seed 1 sees the platform after about 6 s)."""
    s = Scenario(preset="groundtruth", seed=1, duration_s=15.0, platform={"path": "circle", "speed_mps": 1.0})
    run = run_mission(s, record=True)
    assert run.log is not None
    return run.log


def _decoded(path) -> list[np.ndarray]:
    """Every frame of a GIF as RGB, composed as a viewer shows it."""
    out = []
    with Image.open(path) as im:
        for k in range(im.n_frames):
            im.seek(k)
            out.append(np.asarray(im.convert("RGB")))
    return out


def _color_mask(img: np.ndarray, rgb: np.ndarray, tol: int = 12) -> np.ndarray:
    return np.abs(img.astype(int) - rgb).max(axis=2) <= tol


def _synthetic_frames(t_end: float, rate_hz: float, width: int = 752, height: int = 480):
    """Frames whose content encodes their index (a bright square that walks right), each with one
    observation: the square's four corners."""
    frames = []
    for k in range(int(t_end * rate_hz) + 1):
        img = np.full((height, width), 40, np.uint8)
        u0, v0 = 60 + 20 * k % (width - 200), 150
        img[v0 : v0 + 120, u0 : u0 + 120] = 230
        corners = np.array([[u0, v0], [u0 + 119, v0], [u0 + 119, v0 + 119], [u0, v0 + 119]], float)
        frames.append(
            (k / rate_hz, img, [Observation(t=k / rate_hz, kind="quad", quality=0.8, pixels=corners)])
        )
    return frames


# --------------------------------------------------------------------------------------------------


def test_replay_times_closed_form():
    # 15 s at 10 fps: 151 frames 0.1 s apart, the last at the end
    times, speed = replay_times(0.0, 15.0, 10.0, 60.0)
    assert speed == 1.0 and times.shape == (151,) and np.allclose(np.diff(times), 0.1)
    # off the grid by more than half a step: one extra frame at the end
    times, _ = replay_times(0.02, 15.0, 10.0, 60.0)
    assert times.shape == (151,) and times[-1] == 15.0 and math.isclose(times[-2], 14.92)
    # within half a step: the last frame moves to the end instead
    times, _ = replay_times(0.0, 15.04, 10.0, 60.0)
    assert times.shape == (151,) and times[-1] == 15.04
    # 120 s mission, 30 s of playback: 4x, 301 frames
    times, speed = replay_times(0.0, 120.0, 10.0, 30.0)
    assert speed == 4.0 and times.shape == (301,) and np.allclose(np.diff(times), 0.4)
    with pytest.raises(ValueError):
        replay_times(0.0, 1.0, 0.0, 30.0)
    with pytest.raises(ValueError):
        replay_times(0.0, 1.0, 10.0, -1.0)


def test_top_view_only_gif(mission_log, tmp_path):
    path = write_replay(mission_log, tmp_path / "r" / "replay.gif", fps=5.0, title="gt seed 1")
    t = mission_log["t"]
    expected = len(replay_times(t[0], t[-1], 5.0, 30.0)[0])
    frames = _decoded(path)
    assert len(frames) == expected
    with Image.open(path) as im:
        assert im.size == (520, 480)
        assert im.info["loop"] == 0
    # the GIF holds exactly what was drawn (the per-frame differences and the shared palette lose nothing)
    images, durations = render_replay_frames(mission_log, fps=5.0, title="gt seed 1")
    assert len(images) == expected and durations[0] == 200 and durations[-1] >= 1000
    for k in (0, expected // 2, expected - 1):
        assert np.array_equal(frames[k], np.asarray(images[k].convert("RGB")))
    # the UAV marker moves between frames; the first and last frames differ
    first, last = frames[0], frames[-1]
    assert _color_mask(first, UAV_RGB).sum() > 20 and _color_mask(last, UAV_RGB).sum() > 20
    assert _color_mask(last, PLATFORM_RGB).sum() > _color_mask(first, PLATFORM_RGB).sum()  # the trail grows
    # no camera panel: nowhere a dark block
    assert (last.max(axis=2) < 60).mean() < 0.02
    assert path.stat().st_size < 10_000 * expected


def test_camera_panel_shows_frames_and_detections(mission_log, tmp_path):
    frames = _synthetic_frames(float(mission_log["t"][-1]), rate_hz=2.0)
    path = write_replay(mission_log, tmp_path / "replay.gif", frames=frames, fps=4.0, camera_hz=4.0)
    gif = _decoded(path)
    assert gif[0].shape == (430, 860, 3)
    x, y, w, h = 14, 50, CAMERA_PANEL_WIDTH_PX, 240  # the camera panel of the layout
    s = w / 752  # frames are scaled to the panel's width
    t = mission_log["t"]
    times = replay_times(t[0], t[-1], 4.0, 30.0)[0]
    for k in (3, len(gif) // 2, len(gif) - 1):
        j = int(np.searchsorted([f[0] for f in frames], times[k] + 1e-9, side="right")) - 1
        corners = frames[j][2][0].pixels
        panel = gif[k][y : y + h, x : x + w]
        # the bright square is where the frame had it
        bright = panel[30:220].min(axis=2) > 200  # rows clear of the text lines
        vs, us = np.nonzero(bright)
        vs = vs + 30
        assert (
            abs(us.min() - corners[0, 0] * s) < 4
            and abs(vs.min() - (corners[0, 1] * s + (h - 480 * s) / 2)) < 4
        )
        # detection points on its corners, the centre cross in the middle
        centre = (corners.mean(axis=0) + 0.5) * s - 0.5 + (0, (h - 480 * s) / 2)
        cy, cx = np.argwhere(_color_mask(panel, CENTRE_RGB, 40)).mean(axis=0)
        assert math.hypot(cx - centre[0], cy - centre[1]) < 2.0
        dv, du = np.nonzero(_color_mask(panel, DETECTION_RGB, 30))
        assert du.size > 8
        c0 = (corners[0] + 0.5) * s - 0.5 + (0, (h - 480 * s) / 2)
        assert np.min(np.hypot(du - c0[0], dv - c0[1])) < 2.0
        # right of the camera: the top view with both vehicles
        right = gif[k][:, x + w + 40 :]
        assert _color_mask(right, UAV_RGB).sum() > 20 and _color_mask(right, PLATFORM_RGB).sum() > 20
        assert _color_mask(right, CENTRE_RGB).sum() == 0 and (right.min(axis=2) > 200).mean() > 0.5


def test_rendered_camera_frames_size_bound(mission_log, tmp_path):
    """Frames from the renderer along the logged flight (level attitude), recorded as a frame sink
    would: the GIF stays within 10 kB a frame (3 MB for the 300 frames of a long mission)."""
    camera = PinholeCamera.default_downward()
    mount = CameraMount.downward()
    pad = FalangaTag.default(size_m=1.5)
    rng = np.random.default_rng(3)
    renderer = Renderer(camera, make_ground_texture("grass", rng, size_px=512), pad, RenderOptions(), rng)
    rec = FrameRecorder(rate_hz=5.0)
    t, p_WB, p_WP, v_WP = (mission_log[k] for k in ("t", "p_WB", "p_WP", "v_WP"))
    for i in range(0, t.shape[0], 2):  # the log is at 50 Hz: a 25 Hz camera, thinned to 5 Hz
        p_WC, R_WC = camera_pose_W(p_WB[i], rot_z(0.0), mount)
        yaw = math.atan2(v_WP[i, 1], v_WP[i, 0])
        img = renderer.render(p_WC, R_WC, (p_WP[i], yaw))
        uv = camera.project((p_WP[i][None, :] - p_WC) @ R_WC)
        inside = np.isfinite(uv).all() and 0 <= uv[0, 0] < camera.width and 0 <= uv[0, 1] < camera.height
        obs = [Observation(t=t[i], kind="truth", quality=1.0, pixels=uv)] if inside else []
        rec(t[i], img, obs)
    assert len(rec.frames) == pytest.approx(t[-1] * 5.0, abs=2)
    assert rec.frames[0][1].shape == (240, CAMERA_PANEL_WIDTH_PX)
    path = write_replay(mission_log, tmp_path / "replay.gif", frames=rec.frames, fps=10.0)
    n = len(replay_times(t[0], t[-1], 10.0, 30.0)[0])
    with Image.open(path) as im:
        assert im.n_frames == n
    assert path.stat().st_size < 10_000 * n
    last = _decoded(path)[-1]
    panel = last[50:290, 14 : 14 + CAMERA_PANEL_WIDTH_PX]
    assert panel.std() > 8  # a textured ground image, not the empty panel


def test_frame_recorder_thins_and_scales():
    rec = FrameRecorder(rate_hz=10.0, max_width_px=376)
    img = np.zeros((480, 752), np.uint8)
    img[300:304, 500:504] = 255  # a 4x4 block with its centre at pixel (501.5, 301.5)
    obs = Observation(t=0.0, kind="blob", quality=0.5, pixels=[[501.5, 301.5]])
    for k in range(30):  # 30 Hz for 1 s
        rec(k / 30.0, img, [obs])
    assert [round(f[0] * 30) for f in rec.frames] == list(range(0, 30, 3))
    small, observations = rec.frames[0][1], rec.frames[0][2]
    assert small.shape == (240, 376)
    vs, us = np.nonzero(small)
    weights = small[vs, us].astype(float)
    centroid = np.array([np.average(us, weights=weights), np.average(vs, weights=weights)])
    assert np.allclose(observations[0].pixels[0], centroid, atol=1e-9)
    with pytest.raises(ValueError):
        FrameRecorder(rate_hz=0.0)


def test_bad_input(tmp_path):
    with pytest.raises(ValueError):
        write_replay({"t": np.zeros(0), "p_WB": np.zeros((0, 3))}, tmp_path / "a.gif")
    with pytest.raises(ValueError):
        write_replay({"t": np.arange(3.0)}, tmp_path / "a.gif")
    log = {"t": np.arange(3.0), "p_WB": np.zeros((3, 3))}
    with pytest.raises(ValueError):
        write_replay(log, tmp_path / "a.gif", frames=[(0.0, np.zeros((4, 4)), [])])  # float image
    # a minimal log (no platform, no modes) still gives a GIF
    path = write_replay(log, tmp_path / "a.gif", fps=2.0)
    assert len(_decoded(path)) == 5


def test_frame_recorder_turns_the_cameras_bgr_into_rgb():
    bgr = np.zeros((20, 30, 3), np.uint8)
    bgr[..., 2] = 200  # red in OpenCV's channel order
    rec = FrameRecorder(rate_hz=10.0, max_width_px=376)
    rec(0.0, bgr, [])
    rgb = rec.frames[0][1]
    assert rgb[0, 0].tolist() == [200, 0, 0]


def test_frame_recorder_bounds_its_frames_and_keeps_them_even_over_a_long_mission():
    # A 20 Hz camera over 130 s into a recorder of 10 Hz and at most 40 frames: the rate halves at the
    # 40th frame (3.9 s: 20 left, 0.2 s apart), at 7.9 s and so on; every halving keeps the first frame.
    rec = FrameRecorder(rate_hz=10.0, max_frames=40)
    img = np.zeros((48, 64), np.uint8)
    wanted = []
    for k in range(2600):
        t = k * 0.05
        wanted.append(rec.wants(t))
        rec(t, img, [])
    t_kept = np.array([f[0] for f in rec.frames])
    assert 20 <= len(t_kept) < 40
    assert t_kept[0] == 0.0
    # evenly spaced at the final period, which is a power-of-two multiple of 0.1 s
    period = rec.period_s
    assert math.log2(period / 0.1) == pytest.approx(round(math.log2(period / 0.1)))
    np.testing.assert_allclose(np.diff(t_kept), period, atol=1e-9)
    # the end of the mission is within one period of the last kept frame (the replay's end is shown)
    assert 129.95 - t_kept[-1] < period
    # wants() said yes for the frames kept at the time (some later dropped), never for more
    assert len(t_kept) <= sum(wanted) < 2600 / 2


def test_frame_recorder_at_its_default_bound_serves_every_camera_refresh_of_a_long_replay():
    # 200 s of a 20 Hz camera: the replay is sped up to 30 s of playback and refreshes its camera panel
    # at most 3 times a second of it, every 200 / 90 = 2.2 s of the mission; the 400-frame bound keeps
    # at least 200 frames over the mission, at most 1 s apart.
    rec = FrameRecorder()
    img = np.zeros((48, 64), np.uint8)
    for k in range(4000):
        rec(k * 0.05, img, [])
    t_kept = np.array([f[0] for f in rec.frames])
    assert 200 <= len(t_kept) < 400
    assert rec.period_s <= 1.0 < 200.0 / 90.0
    np.testing.assert_allclose(np.diff(t_kept), rec.period_s, atol=1e-9)


def test_frame_recorder_below_its_bound_keeps_every_tenth_of_a_second():
    rec = FrameRecorder(rate_hz=10.0)  # 400 frames: 40 s at 10 Hz before any halving
    img = np.zeros((48, 64), np.uint8)
    for k in range(30 * 20):
        rec(k * 0.05, img, [])
    assert len(rec.frames) == 300 and rec.period_s == pytest.approx(0.1)
    with pytest.raises(ValueError, match="max_frames"):
        FrameRecorder(max_frames=1)
