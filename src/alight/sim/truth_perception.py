"""Ground-truth perception: what a perfect detector + PnP would report, with configurable imperfections.

It stands in for camera + detector (preset ``groundtruth``, and the "perfect perception" ablation): at a
set rate it reports the pad centre in the camera frame, ``p_CP``, taken from the simulator's truth, with
Gaussian noise, a field-of-view and range check (the pad must be where a camera could see it), random
dropouts and blackout intervals. The measurement is relative, like a real detector's, so the pipeline
geolocates it with its own ego estimate (and VIO drift affects it as it would a real detection). The
latency is applied by the runner, which delivers each observation ``latency_s`` after its capture time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from alight.types import FloatArray, Observation


@dataclass(frozen=True, kw_only=True)
class TruthPerceptionConfig:
    rate_hz: float = 20.0
    noise_m: float = 0.05
    """Per-axis standard deviation of the reported p_CP (m)."""
    latency_s: float = 0.1
    dropout_prob: float = 0.0
    blackouts: tuple[tuple[float, float], ...] = ()
    hfov_rad: float = math.radians(90.0)
    vfov_rad: float = math.radians(64.0)
    max_range_m: float = 25.0

    def __post_init__(self) -> None:
        if not (self.rate_hz > 0 and self.noise_m >= 0 and self.latency_s >= 0):
            raise ValueError("rate_hz must be > 0, noise_m and latency_s >= 0")
        if not 0.0 <= self.dropout_prob <= 1.0:
            raise ValueError(f"dropout_prob must be in [0, 1], got {self.dropout_prob}")


class TruthPerception:
    """Reports the true pad position relative to the camera, degraded as configured."""

    def __init__(
        self, config: TruthPerceptionConfig, R_BC: FloatArray, p_BC: FloatArray, rng: np.random.Generator
    ) -> None:
        self.config = config
        self.R_BC = np.asarray(R_BC, dtype=np.float64)
        self.p_BC = np.asarray(p_BC, dtype=np.float64)
        self.rng = rng
        self._tan_h = math.tan(config.hfov_rad / 2)
        self._tan_v = math.tan(config.vfov_rad / 2)
        self._cov = np.eye(3) * max(config.noise_m, 1e-3) ** 2

    def visible(self, p_CP: FloatArray) -> bool:
        """True when the pad centre is in front of the camera, inside its field of view and range."""
        x, y, z = p_CP
        return bool(
            z > 0.0
            and abs(x) <= self._tan_h * z
            and abs(y) <= self._tan_v * z
            and math.sqrt(x * x + y * y + z * z) <= self.config.max_range_m
        )

    def observe(self, t: float, p_WB: FloatArray, R_WB: FloatArray, p_WP: FloatArray) -> list[Observation]:
        """The observations of a frame captured at ``t`` with the vehicle at the true pose (p_WB, R_WB)
        and the pad centre at ``p_WP``; an empty list when the pad is not seen."""
        cfg = self.config
        # Draw every random number each frame, seen or not, so one fault setting does not shift the
        # random sequence of the others (comparable runs across settings with the same seed).
        noise = self.rng.standard_normal(3) * cfg.noise_m
        dropped = self.rng.random() < cfg.dropout_prob
        if dropped or any(t0 <= t <= t1 for t0, t1 in cfg.blackouts):
            return []
        R_WC = R_WB @ self.R_BC
        p_WC = p_WB + R_WB @ self.p_BC
        p_CP = R_WC.T @ (p_WP - p_WC)
        if not self.visible(p_CP):
            return []
        return [Observation(t=t, kind="truth", quality=1.0, p_CP=p_CP + noise, cov_p_CP=self._cov)]
