"""Encoded image bytes (a file, a ``CompressedImage`` message) to an image, refusing damaged data.

OpenCV's ``cv2.imdecode`` hands on whatever libjpeg could make of a damaged JPEG: a file cut short comes
back grey below the cut, and a few wrong bytes in the entropy-coded data come back as blocks of shifted
colour for the rest of the scan, with libjpeg's complaint ("Corrupt JPEG data: ...") written to stderr and
nothing returned to the caller. Those blocks are real pixels to a detector: in the detector fuzz harness
(``benchmarks/fuzz_detectors.py``) they gave 6 red "targets" to paper 003's colour filter in 1,800 images.
A damaged frame is the reader's to refuse, once, for every detector: JPEG data is decoded by libjpeg-turbo
through ``simplejpeg`` in its strict mode, where a warning of libjpeg's is an error, and the frame is
refused with libjpeg's own reason. (On every real photo of ``shared/testdata/real`` it gives the same
pixels as OpenCV, which uses the same library and the same default DCT and upsampling.) CMYK and YCCK
JPEGs, which no camera makes, and every other format go to OpenCV: its PNG, TIFF and WebP decoders refuse
a damaged file themselves (libpng checks each chunk's CRC).

A JPEG whose damage libjpeg cannot see (a changed coefficient that still decodes) is a valid image with
wrong content, and no reader can tell; it still reaches the detectors, whose own checks are the last line.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import simplejpeg

from alight.types import U8Array

JPEG_MAGIC = b"\xff\xd8\xff"
"""The first three bytes of every JPEG stream (SOI and the first marker's 0xFF)."""


def is_jpeg(data: bytes) -> bool:
    return data[:3] == JPEG_MAGIC


def decode_image_bytes(data: bytes) -> tuple[np.ndarray | None, str | None]:
    """``(image, None)``, the image as stored (grey ``(H, W)``, BGR ``(H, W, 3)`` or BGRA, 8 or 16-bit, as
    ``cv2.imdecode(..., IMREAD_UNCHANGED)`` gives it), or ``(None, a one-line reason)`` for data that is
    empty, damaged or not an image."""
    if not data:
        return None, "empty (0 bytes)"
    if is_jpeg(data):
        return _decode_jpeg(data)
    try:
        img: Any = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error:
        img = None
    if img is None or img.size == 0:
        return None, f"not a decodable image (corrupt or unsupported format, {len(data)} bytes)"
    return img, None


def _decode_jpeg(data: bytes) -> tuple[np.ndarray | None, str | None]:
    try:
        _, _, colorspace, _ = simplejpeg.decode_jpeg_header(data)
    except ValueError as e:
        return None, f"damaged JPEG: {_reason(e)}"
    if colorspace in ("CMYK", "YCCK"):
        img: Any = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None or img.size == 0:
            return None, f"not a decodable JPEG ({colorspace}, {len(data)} bytes)"
        return img, None
    grey = colorspace == "Gray"
    try:
        out: U8Array = simplejpeg.decode_jpeg(data, colorspace="GRAY" if grey else "BGR", strict=True)
    except ValueError as e:
        return None, f"damaged JPEG: {_reason(e)}"
    return (out[..., 0] if grey and out.ndim == 3 else out), None


def _reason(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return text[:120] if text else type(e).__name__


__all__ = ["JPEG_MAGIC", "decode_image_bytes", "is_jpeg"]
