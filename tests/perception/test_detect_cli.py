"""``run_detect``: the body of ``alight detect`` (JSON lines, bad files, exit status, the pose)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from perception_scenes import random_scenes

from alight.cameras import PinholeCamera
from alight.errors import ConfigError, InputError
from alight.pads import FalangaTag
from alight.perception.detect_cli import detector_names, run_detect


def run(paths: list[str], detector: str, camera: str | None = None) -> tuple[int, list[dict]]:  # type: ignore[type-arg]
    buf = io.StringIO()
    status = run_detect(paths, detector, camera, buf)
    return status, [json.loads(line) for line in buf.getvalue().splitlines()]


def write_camera(path: Path, cam: PinholeCamera) -> None:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", cam.width)
    fs.write("image_height", cam.height)
    fs.write("camera_matrix", np.asarray(cam.K))
    fs.write("distortion_coefficients", np.asarray(cam.dist).reshape(1, -1))
    fs.release()


def test_bad_files_are_reported_and_the_rest_go_on(tmp_path: Path, real_dir: Path) -> None:
    empty = tmp_path / "empty.png"
    empty.write_bytes(b"")
    corrupt = tmp_path / "corrupt.jpg"
    corrupt.write_bytes(b"\xff\xd8\xff\xe0" + b"not really a jpeg" * 20)
    text = tmp_path / "notes.png"
    text.write_text("hello")
    good = real_dir / "apriltag_real_photos" / "34139872896_defdb2f8d9_c.jpg"
    paths = [str(empty), str(corrupt), str(tmp_path / "missing.jpg"), str(tmp_path), str(text), str(good)]
    status, lines = run(paths, "apriltag")
    assert status == 2
    assert [d["image"] for d in lines] == paths
    for d, word in zip(
        lines[:5],
        ["empty", "damaged JPEG", "not found", "directory", "not a decodable"],
        strict=True,
    ):
        assert d["ok"] is False and word in d["error"]
    last = lines[-1]
    assert last["ok"] is True and last["detector"] == "apriltag" and last["found"] >= 14
    assert len(last["observations"]) == last["found"]
    assert all(len(o["corners"]) == 4 and o["kind"].startswith("aruco:") for o in last["observations"])
    assert last["time_ms"] > 0 and "pose" not in last


def test_all_good_files_exit_zero_and_falanga_finds_nothing_on_photos(real_dir: Path) -> None:
    paths = sorted(str(p) for p in (real_dir / "aruco_charuco_real_photos").glob("*.jpg"))
    status, lines = run(paths, "falanga")
    assert status == 0 and len(lines) == len(paths)
    assert all(d["ok"] and d["found"] == 0 and d["observations"] == [] for d in lines)


def test_falanga_pose_with_a_camera_file(tmp_path: Path) -> None:
    cam = PinholeCamera.default_downward()
    cam_file = tmp_path / "camera.yaml"
    write_camera(cam_file, cam)
    scenes = random_scenes(FalangaTag.default(), np.random.default_rng(9), 2, z_range=(3.0, 6.0))
    paths = []
    for i, sc in enumerate(scenes):
        p = tmp_path / f"frame{i}.png"
        cv2.imwrite(str(p), sc.image)
        paths.append(str(p))
    status, lines = run(paths, "falanga", str(cam_file))
    assert status == 0
    for d, sc in zip(lines, scenes, strict=True):
        assert d["found"] == 1 and d["observations"][0]["kind"] == "circle"
        pose = d["pose"]
        assert np.linalg.norm(np.array(pose["p_CP"]) - sc.p_CP) < 0.01 * np.linalg.norm(sc.p_CP)
        # the tag's yaw is ambiguous by 90 deg; its normal is not
        assert np.allclose(np.array(pose["R_CP"])[:, 2], sc.R_CP[:, 2], atol=0.01)
        assert pose["reproj_rms_px"] < 0.5
        assert pose["n_points"] >= 51 and "camera_size_mismatch" not in d


def test_aruco_pose_on_a_colour_frame(tmp_path: Path) -> None:
    from alight.pads import AprilTagPad

    cam = PinholeCamera.default_downward()
    cam_file = tmp_path / "camera.yml"
    write_camera(cam_file, cam)
    sc = random_scenes(AprilTagPad.default(), np.random.default_rng(1), 1, z_range=(3.0, 4.0))[0]
    p = tmp_path / "frame.jpg"
    cv2.imwrite(str(p), cv2.cvtColor(sc.image, cv2.COLOR_GRAY2BGR), [cv2.IMWRITE_JPEG_QUALITY, 95])
    status, (d,) = run([str(p)], "aruco", str(cam_file))
    assert status == 0 and d["found"] >= 3
    assert np.linalg.norm(np.array(d["pose"]["p_CP"]) - sc.p_CP) < 0.02 * np.linalg.norm(sc.p_CP)


def test_unknown_detector_and_bad_camera_raise_before_any_image(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="unknown detector"):
        run_detect(["x.png"], "nope", None, io.StringIO())
    with pytest.raises(InputError):
        run_detect(["x.png"], "falanga", str(tmp_path / "missing.yaml"), io.StringIO())
    assert set(detector_names()) == {"falanga", "aruco", "apriltag", "nfold", "sdu", "red"}
