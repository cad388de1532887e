"""Rendered frames and shared helpers for the perception tests (imported by the test modules; the
fixtures are in ``conftest.py``).

Frames come from the real renderer (``alight.sim.render.Renderer``) through the default downward camera
(with its lens distortion), so the detectors are tested on what the simulator feeds them. A scene is
described by the camera pose in W and the platform pose; the truth for a detection is ``(R_CP, p_CP)``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import rot_z


@dataclass
class Scene:
    image: np.ndarray
    """Grey frame, uint8 (H, W)."""
    R_CP: np.ndarray
    p_CP: np.ndarray
    p_WB: np.ndarray
    R_WB: np.ndarray
    p_WP: np.ndarray
    yaw: float


_RENDERERS: dict[tuple[object, ...], Renderer] = {}


def renderer(
    pad: object, ground: str = "grass", options: RenderOptions | None = None, seed: int = 0
) -> Renderer:
    """A cached renderer for the default downward camera (textures are built once per key)."""
    opt = RenderOptions() if options is None else options
    key = (pad, ground, opt, seed)
    if key not in _RENDERERS:
        rng = np.random.default_rng(seed)
        _RENDERERS[key] = Renderer(
            PinholeCamera.default_downward(), make_ground_texture(ground, rng, size_px=512), pad, opt, rng
        )
    return _RENDERERS[key]


def tilt(roll: float, pitch: float, yaw: float = 0.0) -> np.ndarray:
    """R_WB from yaw, pitch, roll (z-y-x)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    return rot_z(yaw) @ Ry @ Rx


def render_scene(
    pad: object,
    p_WB: np.ndarray,
    R_WB: np.ndarray,
    p_WP: np.ndarray,
    yaw: float,
    *,
    ground: str = "grass",
    options: RenderOptions | None = None,
    seed: int = 0,
) -> Scene:
    """Render the pad seen from the body pose (p_WB, R_WB) with the downward mount."""
    mount = CameraMount.downward()
    p_WC, R_WC = camera_pose_W(np.asarray(p_WB, float), np.asarray(R_WB, float), mount)
    r = renderer(pad, ground, options, seed)
    img = r.render(p_WC, R_WC, (np.asarray(p_WP, float), yaw))
    R_WP = rot_z(yaw)
    return Scene(
        img,
        R_WC.T @ R_WP,
        R_WC.T @ (np.asarray(p_WP, float) - p_WC),
        np.asarray(p_WB, float),
        np.asarray(R_WB, float),
        np.asarray(p_WP, float),
        yaw,
    )


def pad_fully_in_view(pad: object, sc: Scene, margin_px: float = 4.0) -> bool:
    """True when the pad's 4 corners project inside the image with a margin."""
    cam = PinholeCamera.default_downward()
    c = (sc.R_CP @ pad.quad_corners_P().T).T + sc.p_CP  # type: ignore[attr-defined]
    px = cam.project(c)
    return bool(
        np.isfinite(px).all()
        and (px[:, 0] > margin_px).all()
        and (px[:, 1] > margin_px).all()
        and (px[:, 0] < cam.width - 1 - margin_px).all()
        and (px[:, 1] < cam.height - 1 - margin_px).all()
    )


def random_scenes(
    pad: object, rng: np.random.Generator, n: int, z_range=(2.0, 14.0), max_tilt=0.3, **kw
) -> list[Scene]:  # type: ignore[no-untyped-def]
    """``n`` frames with the pad fully in view: random altitude, offset, attitude and platform heading."""
    out: list[Scene] = []
    while len(out) < n:
        z = rng.uniform(*z_range)
        R_WB = tilt(
            rng.uniform(-max_tilt, max_tilt), rng.uniform(-max_tilt, max_tilt), rng.uniform(-math.pi, math.pi)
        )
        p_WB = np.array([rng.uniform(-0.4, 0.4) * z, rng.uniform(-0.3, 0.3) * z, z + 0.5])
        sc = render_scene(pad, p_WB, R_WB, np.array([0.0, 0.0, 0.5]), rng.uniform(-math.pi, math.pi), **kw)
        if pad_fully_in_view(pad, sc):
            out.append(sc)
    return out


def testdata_dir() -> Path:
    env = os.environ.get("ALIGHT_TESTDATA")
    return Path(env) if env else Path(__file__).resolve().parents[2].parent / "shared" / "testdata" / "real"


def real_dir_or_skip() -> Path:
    """The folder of real photos (env ``ALIGHT_TESTDATA``, default ``<repo>/../shared/testdata/real``), or
    a pytest skip that says why."""
    d = testdata_dir()
    if not (d / "MANIFEST.md").is_file():
        pytest.skip(f"real test photos not found at {d} (set ALIGHT_TESTDATA to the folder with MANIFEST.md)")
    return d


__all__ = ["Scene", "random_scenes", "real_dir_or_skip", "render_scene", "renderer", "testdata_dir", "tilt"]
