"""The one image reader of every detector (alight.perception.image_input): conversions and refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import ImageError
from alight.perception.detect_cli import detector_names, make_detector
from alight.perception.image_input import MAX_PIXELS, as_bgr_u8, as_gray_u8, check_time, to_u8


def test_uint8_is_passed_through_unchanged() -> None:
    a = np.arange(256, dtype=np.uint8).reshape(16, 16)
    assert as_gray_u8(a) is a or np.shares_memory(as_gray_u8(a), a)


@pytest.mark.parametrize(
    ("a", "expected"),
    [
        (np.array([[0, 65535]], np.uint16), [0, 255]),  # full 16-bit range
        (np.array([[0, 4095]], np.uint16), [0, 255]),  # 12-bit in 16-bit: max <= 4095
        (np.array([[0, 2048]], np.uint16), [0, 128]),
        (np.array([[-5, 32767]], np.int16), [0, 255]),  # negatives read as 0
        (np.array([[0.0, 1.0]], np.float32), [0, 255]),  # 0-1 floats
        (np.array([[0.0, 200.0]], np.float64), [0, 200]),  # 0-255 floats
        (np.array([[math.nan, 1.0]]), [0, 255]),  # NaN reads as black
        (np.array([[math.inf, 100.0]]), [0, 100]),
        (np.array([[True, False]]), [255, 0]),
        (np.array([[-3, 300]], np.int64), [0, 255]),  # Python ints: clipped 0-255
    ],
)
def test_values_are_brought_to_the_8_bit_scale(a: np.ndarray, expected: list[int]) -> None:
    assert to_u8(a).tolist() == [expected]


@pytest.mark.parametrize(
    "image",
    [
        None,
        "x.png",
        [[1, 2], [3]],
        np.zeros((0, 5)),
        np.zeros((4, 4, 2)),
        np.zeros((2, 2, 2, 2)),
        np.array([[1j]]),
    ],
)
def test_what_is_not_an_image_reads_as_none(image: object) -> None:
    assert as_gray_u8(image) is None and as_bgr_u8(image) is None


def test_grey_has_no_colour() -> None:
    assert as_bgr_u8(np.zeros((4, 4), np.uint8)) is None
    assert as_bgr_u8(np.zeros((4, 4, 4), np.uint8)).shape == (4, 4, 3)  # type: ignore[union-attr]


def test_an_oversized_image_is_an_error_for_every_detector() -> None:
    huge = np.broadcast_to(np.uint8(0), (MAX_PIXELS // 4096 + 1, 4096))  # no memory behind it
    for name in detector_names():
        with pytest.raises(ImageError, match="larger than"):
            make_detector(name).detect(huge, 0.0)
        assert make_detector(name).detect(np.zeros((64, 64), np.uint8), 0.0) == [], name


@pytest.mark.parametrize("t", [math.nan, -math.inf, "now", None])
def test_every_detector_checks_the_capture_time(t: object) -> None:
    with pytest.raises(ImageError, match="capture time"):
        check_time(t)
    for name in detector_names():
        with pytest.raises(ImageError, match="capture time"):
            make_detector(name).detect(np.zeros((64, 64, 3), np.uint8), t)  # type: ignore[arg-type]
