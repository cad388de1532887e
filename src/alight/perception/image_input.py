"""One reading of "an image" for every detector: what is accepted, how it is converted, what is refused.

Detectors take whatever a caller hands them (a rendered frame, a file read by OpenCV, a replayed log, a
test's array) and must neither crash nor find a pad in garbage. Each one calls :func:`as_gray_u8` or
:func:`as_bgr_u8` and :func:`check_time` at its public entry point, so they all agree on the rules below.

**No image, no observation.** ``None``, a string, a non-numeric or complex array, an array that is not
2-D ``(H, W)`` or 3-D ``(H, W, C)`` with ``C`` in 1, 3 or 4 (grey, BGR, BGRA), and an empty array are not
images: the readers return None and the detector returns ``[]`` (the Detector protocol: it must not raise
on an empty, tiny or uniform image, and a pipeline must keep flying through a dropped frame).

**Errors** (:class:`alight.errors.ImageError`, a ``ValueError``) for what is a mistake upstream rather
than a bad frame: more than :data:`MAX_PIXELS` pixels (no camera we fly makes one; converting it would
take seconds and gigabytes) and a capture time that is not a finite number (it would end up as a NaN time
stamp in every estimator downstream). A grey image handed to a colour detector is not an error but no
colour: :func:`as_bgr_u8` gives None and the detector ``[]`` (documented on each colour detector).

**Values** are brought to the 0-255 scale of uint8 as follows (the decisions, and why):

- ``uint8``: unchanged, so rendered frames give bit-identical results.
- ``bool``: False 0, True 255.
- ``uint16`` and ``int16`` (camera raw formats): negative values read as 0 (no light is negative).
  When the image's largest value is at most 4095 the data is taken as 12-bit in a 16-bit container (the
  common machine-vision packing; 10-bit data is packed the same way and reads darker, which the
  detectors' local thresholds tolerate) and scaled by 255/4095; otherwise by the type's full range
  (255/65535, 255/32767). A genuinely 16-bit frame whose brightest pixel is below 4096 (1/16 of full
  scale) is therefore brightened 16 times: harmless for detectors that look at contrast, and the price of
  reading the far more common 12-bit packing right.
- other integer types (``int32``, ``int64``, ...: what ``numpy.array`` makes of Python ints): read as
  0-255 values, clipped.
- floating point: non-finite pixels (NaN, inf) carry no reading and are read as 0 (black); when the
  largest finite value is at most 1 the image is taken as 0-1 and scaled by 255, else read as 0-255 and
  clipped.

Non-contiguous views are copied to contiguous memory; colour is converted with OpenCV's BGR(A) to grey
weights.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from alight.errors import ImageError
from alight.types import U8Array

MAX_PIXELS = 1 << 26
"""Largest image, in pixels (H x W), a detector accepts: 67,108,864 (8192 x 8192), above any camera we
fly (the renderer's default is 752 x 480, the largest drone sensors about 48 MP)."""

TWELVE_BIT_MAX = 4095
"""A 16-bit image whose largest value is at most this is read as 12-bit data (see the module docstring)."""


def check_time(t: Any) -> float:
    """The capture time ``t`` (s) as a float; :class:`ImageError` when it is not a finite real number."""
    try:
        value = float(t)
    except (TypeError, ValueError):
        raise ImageError(f"capture time must be a finite number of seconds, got {t!r}") from None
    if not math.isfinite(value):
        raise ImageError(f"capture time must be a finite number of seconds, got {t!r}")
    return value


def _as_array(image: Any) -> NDArray[Any] | None:
    """``image`` as a 2-D or 3-D numeric array with 1, 3 or 4 channels, or None when it is not an image.
    Raises :class:`ImageError` above :data:`MAX_PIXELS`."""
    if isinstance(image, np.ndarray):
        a = image
    elif image is None or isinstance(image, (str, bytes)):
        return None
    else:
        try:
            a = np.asarray(image)
        except Exception:  # any object numpy cannot read (ragged lists, ...) is not an image
            return None
    if a.size == 0 or a.ndim not in (2, 3):
        return None
    if a.ndim == 3 and a.shape[2] not in (1, 3, 4):
        return None
    if a.dtype != np.bool_ and not (
        np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)
    ):
        return None
    if a.shape[0] * a.shape[1] > MAX_PIXELS:
        raise ImageError(
            f"image of {a.shape[0]} x {a.shape[1]} pixels is larger than the {MAX_PIXELS} pixels a detector "
            "accepts"
        )
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    return a


def to_u8(a: NDArray[Any]) -> U8Array:
    """A numeric array on the 0-255 scale as uint8, by the rules of the module docstring (uint8 is
    returned as is)."""
    if a.dtype == np.uint8:
        return a
    if a.dtype == np.bool_:
        return a.astype(np.uint8) * np.uint8(255)
    if np.issubdtype(a.dtype, np.floating):
        f = a.astype(np.float64)
        finite = np.isfinite(f)
        if not finite.all():
            f = np.where(finite, f, 0.0)
        if float(f.max()) <= 1.0:
            f = f * 255.0
        return np.clip(np.round(f), 0, 255).astype(np.uint8)
    if a.dtype in (np.uint16, np.int16):
        f = np.maximum(a.astype(np.float64), 0.0)
        full = TWELVE_BIT_MAX if float(f.max()) <= TWELVE_BIT_MAX else float(np.iinfo(a.dtype).max)
        return np.clip(np.round(f * (255.0 / full)), 0, 255).astype(np.uint8)
    # wider integers: the values are taken as 0-255 already
    out: U8Array = np.clip(a, 0, 255).astype(np.uint8)
    return out


def as_gray_u8(image: Any) -> U8Array | None:
    """The image as a C-contiguous 2-D uint8 array (BGR/BGRA converted to grey), or None when it is not
    an image (module docstring). Raises :class:`ImageError` for an image above :data:`MAX_PIXELS`."""
    a = _as_array(image)
    if a is None:
        return None
    a = to_u8(a)
    if a.ndim == 3:
        code = cv2.COLOR_BGR2GRAY if a.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        a = cv2.cvtColor(np.ascontiguousarray(a), code)
    return np.ascontiguousarray(a)


def as_bgr_u8(image: Any) -> U8Array | None:
    """The image as a C-contiguous (H, W, 3) uint8 BGR array (an alpha channel dropped), or None when it
    is not an image or is grey (2-D or one channel). A grey frame gives None rather than an error: a
    colour detector cannot see its colour in it, and the Detector protocol forbids raising on a uniform
    image, which most grey frames handed to every registered detector are. Raises :class:`ImageError`
    above :data:`MAX_PIXELS`."""
    a = _as_array(image)
    if a is None or a.ndim == 2:
        return None
    if a.shape[2] == 4:
        a = a[:, :, :3]
    return np.ascontiguousarray(to_u8(a))


__all__ = ["MAX_PIXELS", "TWELVE_BIT_MAX", "U8Array", "as_bgr_u8", "as_gray_u8", "check_time", "to_u8"]
