"""The work behind ``alight detect IMAGE... --detector NAME [--camera FILE]``: run a detector on image
files and print one JSON line per image.

This is the command's implementation (the CLI in ``alight.cli`` parses the arguments and calls
:func:`run_detect`); it reads files and writes lines, unlike the detectors themselves.

Output, one line per image, in the order given::

    {"image": PATH, "ok": true, "detector": NAME, "found": N,
     "observations": [{"kind": ..., "quality": ..., "pixels" | "corners": [[u, v], ...]}, ...],
     "pose": {"p_CP": [x, y, z], "R_CP": [[...]], "rvec": [...], "reproj_rms_px": e, "n_points": n} | null,
     "time_ms": T}

``corners`` (4 points, OpenCV's order) for markers (kinds ``aruco:ID``), ``pixels`` otherwise. ``pose``
is present only with ``--camera`` and when the observations carry pad points (``falanga``, ``aruco``):
one PnP over all of them; null when it has no solution. ``time_ms`` is the detector's time alone.
A file that cannot be read (missing, a directory, empty, not a decodable image) gives
``{"image": PATH, "ok": false, "error": MESSAGE}`` and the next file is processed.

Exit status (returned): 0 when every file was read, 2 when any could not be. A detector name that is not
known raises :class:`alight.errors.ConfigError`, a camera file that cannot be loaded
:class:`alight.errors.InputError`, before any image is read (the CLI prints those as one line, status 2).
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Sequence
from typing import Any, TextIO

import numpy as np

from alight.blockspec import NoContext
from alight.cameras import PinholeCamera
from alight.errors import ConfigError
from alight.pads import PADS
from alight.perception import DETECTORS, Detector, DetectorContext
from alight.perception.aruco import merge_observations
from alight.perception.image_decode import decode_image_bytes
from alight.perception.pnp import solve_pnp
from alight.types import Observation


def detector_names() -> list[str]:
    """The detectors ``alight detect`` runs: the detector stage's blocks that read an image
    (:data:`alight.perception.DETECTORS`), in the table's order."""
    return [name for name, spec in DETECTORS.items() if spec.provides.get("image", True)]


def make_detector(name: str) -> Detector:
    """The detector block ``name`` at its default parameters, on its pad's default layout (1.5 m);
    :class:`~alight.errors.ConfigError` (one line, the known names) for a name it does not know."""
    known = detector_names()
    if name not in known:
        raise ConfigError(f"unknown detector {name!r}; known: {', '.join(sorted(known))}")
    spec = DETECTORS[name]
    pad_names = spec.needs.get("pad", ())
    pad = None
    if pad_names:
        pad_spec = PADS[pad_names[0]]
        pad = pad_spec.build(pad_spec.default_params(), NoContext())
    det = spec.build(spec.default_params(), DetectorContext(pad=pad))
    if det is None:  # a block that reads no image is not in detector_names()
        raise ConfigError(f"detector {name!r} reads no image")
    return det


def read_image(path: str) -> tuple[np.ndarray | None, str | None]:
    """(image, None) or (None, a one-line reason). 8/16-bit grey, BGR or BGRA as stored."""
    try:
        if os.path.isdir(path):
            return None, "is a directory, not an image file"
        with open(path, "rb") as fh:
            data = fh.read()
    except FileNotFoundError:
        return None, "file not found"
    except PermissionError:
        return None, "permission denied"
    except OSError as e:
        return None, f"cannot read file ({e.strerror or e})"
    if not data:
        return None, "empty file (0 bytes)"
    return decode_image_bytes(data)


def _obs_json(o: Observation) -> dict[str, Any]:
    pts = np.round(o.pixels, 2).tolist()
    key = "corners" if o.kind.startswith("aruco:") else "pixels"
    return {"kind": o.kind, "quality": round(float(o.quality), 4), key: pts}


def _pose_json(observations: Sequence[Observation], camera: PinholeCamera) -> dict[str, Any] | None:
    merged = merge_observations(observations, kind="all")
    if merged is None or merged.points_P is None:
        return None
    try:
        res = solve_pnp(merged.pixels, merged.points_P, camera)
    except ValueError:
        return None
    if res is None:
        return None
    return {
        "p_CP": np.round(res.p_CP, 5).tolist(),
        "R_CP": np.round(res.R_CP, 6).tolist(),
        "rvec": np.round(res.rvec, 6).tolist(),
        "reproj_rms_px": round(res.reprojection_rms_px, 4),
        "n_points": res.n_points,
    }


def run_detect(
    paths: list[str], detector: str, camera_path: str | None = None, out: TextIO | None = None
) -> int:
    """Run the detector ``detector`` (one of :func:`detector_names`) on every image in ``paths`` and write
    one JSON line per image to ``out`` (stdout by default). ``camera_path``: a calibration file (OpenCV
    YAML/XML/JSON) for the pose. Returns 0 when every image was read, 2 when any could not be."""
    stream = sys.stdout if out is None else out
    det = make_detector(detector)  # raises ConfigError for an unknown name
    camera = None
    if camera_path is not None:
        from alight.cameras import load_camera

        camera = load_camera(camera_path)  # raises InputError with the file name
    status = 0
    for path in paths:
        img, err = read_image(path)
        if img is None:
            status = 2
            stream.write(json.dumps({"image": path, "ok": False, "error": err}) + "\n")
            continue
        t0 = time.perf_counter()
        obs = det.detect(img, 0.0)
        dt_ms = (time.perf_counter() - t0) * 1e3
        rec: dict[str, Any] = {
            "image": path,
            "ok": True,
            "detector": detector,
            "found": len(obs),
            "observations": [_obs_json(o) for o in obs],
        }
        if camera is not None and any(o.points_P is not None for o in obs):
            if isinstance(camera, PinholeCamera):
                rec["pose"] = _pose_json(obs, camera)
                h, w = img.shape[:2]
                if (camera.width, camera.height) != (w, h):
                    rec["camera_size_mismatch"] = True
            else:
                rec["pose"] = None
                rec["pose_error"] = "the camera model is not a pinhole model (no K); PnP needs one"
        rec["time_ms"] = round(dt_ms, 3)
        stream.write(json.dumps(rec) + "\n")
    stream.flush()
    return status


__all__ = ["detector_names", "make_detector", "read_image", "run_detect"]
