"""The pad stage's registry: :data:`PADS`, the landing-pad designs a scenario's ``blocks.pad`` names."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from alight.blockspec import BlockSpec, NoContext, ResolveContext
from alight.pads.apriltag_pad import AprilTagPad
from alight.pads.falanga_tag import FalangaTag
from alight.pads.red_target import RedTarget
from alight.pads.sdu_pad import SduPad

if TYPE_CHECKING:
    from alight.pads import PadDesign


@dataclass(frozen=True, kw_only=True)
class PadParams:
    """A landing-pad design drawn on the platform."""

    size_m: float | None = None
    """Side of the pad (m); None: the scenario's ``platform.pad_size_m``."""

    def __post_init__(self) -> None:
        if self.size_m is not None and not (math.isfinite(self.size_m) and self.size_m > 0):
            raise ValueError(f"size_m must be finite and > 0, got {self.size_m}")


def _sized(default: Callable[[float], PadDesign]) -> Callable[[PadParams, NoContext], PadDesign]:
    """The factory of a pad class's default layout at the block's ``size_m`` (1.5 m when unset)."""

    def build(p: PadParams, ctx: NoContext) -> PadDesign:
        return default(1.5 if p.size_m is None else p.size_m)

    return build


def _pad_size(ctx: ResolveContext) -> dict[str, float]:
    return {"size_m": ctx.pad_size_m}


_PAD_SIZE = {"size_m": "platform.pad_size_m"}

PadSpec = BlockSpec[NoContext, "PadDesign"]
"""A pad block: parameters -> a pad design."""


def _pad(name: str, summary: str, default: Callable[[float], PadDesign], **provides: int) -> PadSpec:
    return BlockSpec(
        "pad",
        name,
        summary,
        PadParams,
        build=_sized(default),
        context=_PAD_SIZE,
        context_values=_pad_size,
        provides=provides,
    )


PADS: dict[str, PadSpec] = {
    "falanga_tag": _pad("falanga_tag", "paper 000's cross in a ring", FalangaTag.default, yaw_fold=4),
    "apriltag": _pad("apriltag", "AprilTag 36h11 markers in a known layout", AprilTagPad.default),
    "sdu_marker": _pad(
        "sdu_marker",
        "paper 004's n-fold marker and three ArUco landmarks",
        SduPad.default,
        yaw_fold=SduPad.default().nfold_order,  # the n-fold marker's symmetry (its default layout)
    ),
    "red_target": _pad("red_target", "paper 003's red disc (a colour target)", RedTarget.default),
}
"""The pad stage's blocks by name; each builds its design's default layout at ``size_m``."""

__all__ = ["PADS", "PadParams", "PadSpec"]
