"""Sea states and wave spectra: WMO sea-state code -> (Hs, Tp), Pierson-Moskowitz and JONSWAP.

Sources (``shared/references/ship_deck_motion.md`` sec. 1 and 2.1):

- Hs bins: the WMO sea-state code; the value used for a code is the mean Hs of the Bales (1983) open-ocean
  North Atlantic table, and the period its most probable modal period Tp (the table printed in Fossen's
  *Handbook of Marine Craft Hydrodynamics*). Codes 2-6 are the reference sheet's rows. Codes 7 and 8 are
  the same table's next rows (7.5 m / 15.0 s and 11.5 m / 16.4 s) and code 9 the lower edge of its last
  row (Hs > 14 m, Tp 20.0 s); those three are quoted from the table as commonly reproduced, not from the
  sheet. Code 0 (glassy) is a still sea. Code 1 (rippled, Hs up to 0.1 m, mean 0.05 m) has no period in
  the table: a period must be given.
- Spectra, one-sided in angular frequency (rad/s), ``S`` in m^2 s/rad, written in Hs and Tp (DNV-RP-C205
  form): ``S_PM = 5/16 Hs^2 wp^4 w^-5 exp(-5/4 (wp/w)^4)`` and ``S_J = A_g S_PM g^r`` with
  ``r = exp(-(w - wp)^2 / (2 s^2 wp^2))``, ``s`` 0.07 below the peak and 0.09 above, and the DNV
  normalisation ``A_g = 1 - 0.287 ln g`` that keeps m0 = Hs^2/16 nearly unchanged (exactly for g = 1).
"""

from __future__ import annotations

import math

import numpy as np

from alight.errors import ConfigError
from alight.types import FloatArray

__all__ = [
    "SEA_STATES",
    "jonswap",
    "pierson_moskowitz",
    "sea_state_hs_tp",
    "spectral_moment",
    "spectrum",
]

SEA_STATES: dict[int, tuple[float, float | None]] = {
    0: (0.0, None),
    1: (0.05, None),
    2: (0.3, 7.5),
    3: (0.88, 7.5),
    4: (1.88, 8.8),
    5: (3.25, 9.7),
    6: (5.0, 12.4),
    7: (7.5, 15.0),
    8: (11.5, 16.4),
    9: (14.0, 20.0),
}
"""WMO sea-state code -> (significant wave height Hs in m, most probable modal period Tp in s or None)."""

JONSWAP_GAMMA = 3.3
"""The mean peak enhancement of the JONSWAP measurements (Hasselmann et al. 1973), the default."""


def sea_state_hs_tp(code: int, tp_s: float | None = None) -> tuple[float, float]:
    """(Hs, Tp) for a WMO sea-state code; ``tp_s`` replaces the table's period (fetch-limited water,
    lakes and harbours have much shorter periods than the open ocean at the same Hs)."""
    if isinstance(code, bool) or not isinstance(code, int | np.integer) or int(code) not in SEA_STATES:
        raise ConfigError(f"sea_state must be a WMO code, an integer 0-9, got {code!r}")
    hs, tp = SEA_STATES[int(code)]
    if tp_s is not None:
        tp = tp_s
    if tp is None:
        if hs == 0.0:
            return 0.0, 1.0  # a still sea: the period is never used
        raise ConfigError(f"sea_state {code}: the sea-state table gives no period for it, give tp_s")
    return hs, float(tp)


def pierson_moskowitz(w: FloatArray, hs_m: float, tp_s: float) -> FloatArray:
    """Pierson-Moskowitz (Bretschneider, ISSC) spectrum at angular frequencies ``w`` > 0 (m^2 s/rad)."""
    w = np.asarray(w, dtype=np.float64)
    wp = 2.0 * math.pi / tp_s
    pos = w > 0.0
    ws = np.where(pos, w, wp)
    # w^-5 exp(-5/4 (wp/w)^4) as one exponential: no inf * 0 where w is tiny
    out: FloatArray = 5.0 / 16.0 * hs_m**2 * wp**4 * np.exp(-5.0 * np.log(ws) - 1.25 * (wp / ws) ** 4)
    return np.where(pos, out, 0.0)


def jonswap(w: FloatArray, hs_m: float, tp_s: float, gamma: float = JONSWAP_GAMMA) -> FloatArray:
    """JONSWAP spectrum (DNV form, normalised by ``1 - 0.287 ln gamma``) at ``w`` > 0 (m^2 s/rad);
    ``gamma = 1`` is Pierson-Moskowitz."""
    w = np.asarray(w, dtype=np.float64)
    wp = 2.0 * math.pi / tp_s
    sigma = np.where(w <= wp, 0.07, 0.09)
    r = np.exp(-0.5 * ((w - wp) / (sigma * wp)) ** 2)
    a_gamma = 1.0 - 0.287 * math.log(gamma)
    out: FloatArray = a_gamma * pierson_moskowitz(w, hs_m, tp_s) * gamma**r
    return out


def spectrum(w: FloatArray, hs_m: float, tp_s: float, kind: str, gamma: float | None) -> FloatArray:
    """The spectrum ``kind`` (``"pm"`` or ``"jonswap"``; gamma None: 3.3) at ``w`` (m^2 s/rad)."""
    if kind == "pm":
        return pierson_moskowitz(w, hs_m, tp_s)
    if kind == "jonswap":
        return jonswap(w, hs_m, tp_s, JONSWAP_GAMMA if gamma is None else gamma)
    raise ConfigError(f"spectrum must be 'pm' or 'jonswap', got {kind!r}")


def spectral_moment(w: FloatArray, s: FloatArray, n: int) -> float:
    """``m_n = integral of w^n S(w) dw`` by the trapezoidal rule over the grid ``w``."""
    return float(np.trapezoid(np.asarray(w) ** n * np.asarray(s), w))
