"""ROS camera_info YAML: the distortion model is honoured, never read as another one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from alight.cameras import load_camera
from alight.cameras.pinhole import PinholeCamera
from alight.errors import InputError

_K = "[400.0, 0.0, 375.5, 0.0, 400.0, 239.5, 0.0, 0.0, 1.0]"


def _write(tmp_path: Path, model: str, coeffs: list[float]) -> Path:
    p = tmp_path / "camera_info.yaml"
    p.write_text(
        "image_width: 752\nimage_height: 480\ncamera_name: down\n"
        f"camera_matrix: {{rows: 3, cols: 3, data: {_K}}}\n"
        f"distortion_model: {model}\n"
        f"distortion_coefficients: {{rows: 1, cols: {len(coeffs)}, data: {coeffs}}}\n",
        encoding="utf-8",
    )
    return p


@pytest.mark.parametrize(
    ("model", "coeffs"),
    [
        ("plumb_bob", [-0.08, 0.01, 0.001, -0.002, 0.0]),
        ("rational_polynomial", [-0.08, 0.01, 0, 0, 0.001, 0, 0, 0]),
    ],
)
def test_radial_tangential_models_are_read_with_their_coefficients(
    tmp_path: Path, model: str, coeffs: list[float]
) -> None:
    cam = load_camera(_write(tmp_path, model, coeffs))
    assert isinstance(cam, PinholeCamera) and (cam.width, cam.height) == (752, 480)
    np.testing.assert_array_equal(cam.dist, coeffs)
    assert cam.K[0, 2] == 375.5


@pytest.mark.parametrize("model", ["equidistant", "fisheye", "unknown_model"])
def test_other_models_are_refused_in_one_line(tmp_path: Path, model: str) -> None:
    with pytest.raises(InputError, match=f"distortion_model '{model}' is not supported") as err:
        load_camera(_write(tmp_path, model, [0.01, -0.002, 0.0, 0.0]))
    assert "\n" not in str(err.value)


def test_a_coefficient_count_that_does_not_fit_the_model_is_refused(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="rational_polynomial has"):
        load_camera(_write(tmp_path, "rational_polynomial", [0.1, 0.0, 0.0, 0.0, 0.0]))
