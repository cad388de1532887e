"""Faults.fate draws a camera frame's fate before it is rendered, in the same order as Faults.frame did
when it was handed the rendered image: the delivered frames are the same whether or not the frames that
are lost or dark were rendered."""

from __future__ import annotations

import hashlib

import numpy as np

from alight.scenario import scenario_from_dict
from alight.sim.faults import Faults

SPEC = {
    "dropout_prob": 0.3,
    "blackouts": [[2.0, 3.0]],
    "corruption": {
        "noise": {"prob": 0.2},
        "occlusion": {"prob": 0.2},
        "exposure": {"prob": 0.2},
        "frozen": {"prob": 0.2},
        "stripes": {"prob": 0.2},
    },
}
# Faults.frame over these 200 frames before fate/deliver existed (commit c89f392)
DIGEST = "8ffd6cff4f45e89645a7cbeb2a447cdc83bfad2f54f389a125480227bf7fa6cf"


def _faults() -> Faults:
    spec = scenario_from_dict({"preset": "falanga2017", "faults": SPEC}).faults
    return Faults(spec, np.random.SeedSequence(7), camera=True, latency_s=0.1)


def _image(k: int) -> np.ndarray:
    return np.random.default_rng(k).integers(0, 256, (48, 64), dtype=np.uint8)


def test_frame_delivers_what_it_did_before_fate_existed() -> None:
    f = _faults()
    h = hashlib.sha256()
    for k in range(200):
        out = f.frame(k / 20.0, _image(k))
        h.update(b"none" if out is None else np.asarray(out).tobytes())
    assert h.hexdigest() == DIGEST


def test_lost_and_dark_frames_need_no_image() -> None:
    f = _faults()
    h = hashlib.sha256()
    lost = dark = 0
    for k in range(200):
        fate = f.fate(k / 20.0)
        if fate.dropped:
            lost += 1
            out = f.deliver(fate, None)
        elif fate.dark:
            dark += 1
            out = f.deliver(fate, np.full((48, 64), 77, np.uint8))  # any image of the shape: black
            assert out is not None and not out.any()
        else:
            out = f.deliver(fate, _image(k))
        h.update(b"none" if out is None else np.asarray(out).tobytes())
    assert lost > 30 and dark > 5
    assert h.hexdigest() == DIGEST
