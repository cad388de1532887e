"""A long-crested random sea as a finite sum of cosines, and the frequency a moving vessel meets them at.

The elevation at a point ``x`` along the waves' direction of travel is
``eta(x, t) = sum_i a_i cos(w_i t - k_i x + eps_i)`` with ``a_i = sqrt(2 S(w_i) dw)``, phases ``eps_i``
uniform in [0, 2 pi) and the deep-water wave number ``k_i = w_i^2 / g`` (Faltinsen 1993, as in the
reference sheet sec. 2.2). The band ``[0.4 wp, 4 wp]`` keeps at least 99.7 % of m0 (sheet sec. 2.2).

No periodic repetition: with equally spaced frequencies the sum's envelope repeats every ``2 pi / dw``
(and the sum itself if the frequencies are multiples of dw). The band is therefore cut into bins of equal
ratio (geometric spacing, which the sheet names as the alternative to equal bins) and each frequency is
drawn uniformly inside its own bin: the frequencies are not commensurate and no lag repeats the record.
Geometric bins also put more components at the low frequencies that a long hull responds to (it
averages the short waves out): with equal bins a frigate's heave is carried by a dozen components and
its autocorrelation keeps peaks of 0.5 at lags of minutes; with geometric bins 0.34 at most, measured
over sea states 3-5, head, bow-quartering and beam seas (``docs/sea.md``). ``spacing="linear"`` gives
the sheet's equal bins (its own code's draws, for comparing with it).

Encounter frequency (Lloyd, *Seakeeping*, 1989): a vessel at speed U whose heading makes the angle mu
with the waves' direction of travel (mu = 180 deg head seas, 90 deg beam seas, 0 deg following seas) meets
wave i at ``w_e = w - k U cos mu``. In following seas ``w_e`` falls to zero (the vessel rides the wave)
and below (it overtakes the wave). The sign is kept: a component is ``Re{C e^{j w_e t}}`` and every
transfer function used here satisfies ``H(-j w) = conj(H(j w))``, so a negative ``w_e`` is the same motion
as ``|w_e|`` with the phase reversed, which is what the vessel sees when it overtakes a wave.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from alight.errors import ConfigError
from alight.sim.sea.spectra import spectrum
from alight.types import GRAVITY_MPS2, FloatArray

__all__ = ["BAND_WP", "N_COMPONENTS", "WaveComponents", "encounter_frequency", "synthesise"]

N_COMPONENTS = 300
"""Components of a synthesised sea (the sheet's 200-300)."""
BAND_WP: tuple[float, float] = (0.4, 4.0)
"""Frequency band in units of the peak frequency wp (keeps >= 99.7 % of m0, sheet sec. 6.3)."""


@dataclass(frozen=True)
class WaveComponents:
    """The regular waves whose sum is the sea, at the world origin, along the direction of travel."""

    w: FloatArray
    """Angular frequencies (rad/s), shape (N,)."""
    a: FloatArray
    """Amplitudes (m), shape (N,)."""
    eps: FloatArray
    """Phases (rad), shape (N,)."""

    @property
    def k(self) -> FloatArray:
        """Deep-water wave numbers ``w^2 / g`` (rad/m)."""
        out: FloatArray = self.w**2 / GRAVITY_MPS2
        return out

    @property
    def m0(self) -> float:
        """Variance of the discrete sea's elevation, ``sum a_i^2 / 2`` (m^2)."""
        return float(np.sum(self.a**2) / 2.0)

    def elevation(self, t: FloatArray, x_m: float = 0.0) -> FloatArray:
        """Elevation at distance ``x_m`` along the direction of travel at times t (m), shape (T,)."""
        ph = np.outer(np.asarray(t, dtype=np.float64).reshape(-1), self.w) - self.k * x_m + self.eps
        out: FloatArray = np.cos(ph) @ self.a
        return out


def synthesise(
    hs_m: float,
    tp_s: float,
    rng: np.random.Generator,
    kind: str = "jonswap",
    gamma: float | None = None,
    n: int = N_COMPONENTS,
    band_wp: tuple[float, float] = BAND_WP,
    spacing: str = "geometric",
) -> WaveComponents:
    """A random sea of significant wave height ``hs_m`` and modal period ``tp_s``, drawn from ``rng``
    (first the n in-bin frequency offsets, then the n phases: the same generator state gives the same
    sea), in ``spacing`` bins over ``band_wp``. A zero Hs gives no components (a still sea)."""
    if not (math.isfinite(hs_m) and hs_m >= 0.0):
        raise ConfigError(f"hs_m must be finite and >= 0, got {hs_m}")
    if not (math.isfinite(tp_s) and tp_s > 0.0):
        raise ConfigError(f"tp_s must be finite and > 0, got {tp_s}")
    if n < 1 or not 0.0 < band_wp[0] < band_wp[1]:
        raise ConfigError(f"need n >= 1 components in a band 0 < lo < hi, got n={n}, band={band_wp}")
    if spacing not in ("geometric", "linear"):
        raise ConfigError(f"spacing must be 'geometric' or 'linear', got {spacing!r}")
    if hs_m == 0.0:
        empty = np.zeros(0)
        return WaveComponents(empty, empty.copy(), empty.copy())
    wp = 2.0 * math.pi / tp_s
    lo, hi = band_wp[0] * wp, band_wp[1] * wp
    edges = np.geomspace(lo, hi, n + 1) if spacing == "geometric" else np.linspace(lo, hi, n + 1)
    dw = np.diff(edges)
    w = edges[:-1] + rng.uniform(0.0, 1.0, n) * dw
    a = np.sqrt(2.0 * spectrum(w, hs_m, tp_s, kind, gamma) * dw)
    eps = rng.uniform(0.0, 2.0 * math.pi, n)
    return WaveComponents(w, a, eps)


def encounter_frequency(w: FloatArray, speed_mps: float, mu_rad: float) -> FloatArray:
    """``w_e = w - (w^2 / g) U cos mu`` (rad/s, signed; deep water), for waves of frequency ``w``
    met at speed ``U`` and relative direction ``mu`` (180 deg head, 90 beam, 0 following seas)."""
    w = np.asarray(w, dtype=np.float64)
    out: FloatArray = w - w**2 / GRAVITY_MPS2 * speed_mps * math.cos(mu_rad)
    return out
