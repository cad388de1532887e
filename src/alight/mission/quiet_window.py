"""Touchdown in a quiet window (issue 37, point 4): from the deck's predicted trajectory, the next time the
deck's tilt and the relative vertical speed stay inside the limits long enough for contact, and when to
start the final descent to meet the deck then.

Given a prediction on a time grid (from :meth:`alight.estimation.deck_estimator.DeckEstimator.predict`):
the deck tilt is ``arccos(cos roll cos pitch)`` and the closing speed at contact is the vehicle's
touchdown sink rate plus the deck's upward speed. A contact time t_c is *feasible* when, at every grid
time in ``[t_c - timing_tolerance_s, t_c + settle_s]``,

- ``tilt + k sigma_tilt <= max_tilt_rad`` (``sigma_tilt`` is bounded by the larger standard deviation of
  roll and pitch, which holds for any direction of tilt), and
- ``min_closing_mps <= closing - k sigma_v`` and ``closing + k sigma_v <= max_closing_mps``,

with k = ``margin_sigma``. The *window* is the run of consecutive feasible contact times; the first
window whose start allows the descent (``t_c - descent_s >= t_now``) is chosen, and the contact time is
its middle (the largest distance to both ends, so a timing error either way stays inside). The final
descent starts at ``t_c - descent_s``. A window shorter than ``min_window_s`` is not taken.

While descending, :func:`check_commitment` re-tests the committed contact with a fresh prediction: when
the interval around contact is no longer feasible (the window closed before contact, or has not opened),
the answer is a go-around.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from alight.errors import ConfigError, EstimationError
from alight.types import FloatArray

__all__ = ["QuietWindow", "QuietWindowConfig", "check_commitment", "feasible_contacts", "find_quiet_window"]


@dataclass(frozen=True, kw_only=True)
class QuietWindowConfig:
    """Limits and margins of the quiet-window landing."""

    max_tilt_rad: float = math.radians(3.0)
    """Deck tilt at contact (rad). 3 deg: the lower end of the 3-5 deg per-touchdown limit the reference
    sheet proposes for a quadrotor ([MODEL], ship_deck_motion.md sec. 5.2), the pitch limit of helicopter
    deck operations (3 deg significant amplitude, NPS USW 2025 TSSE brief, sheet sec. 3.3) and issue 37's
    acceptance figure (median deck tilt at contact below 3 deg)."""
    max_closing_mps: float = 1.0
    """Largest closing speed at contact (m/s), the vehicle's sink rate plus the deck's rise: the upper end of
    the 0.5-1 m/s a small quadrotor's gear takes (sheet sec. 5.2, [MODEL]); the helicopter figure, 2 m/s
    of deck vertical speed (NPS brief), is for a landing gear built for it."""
    min_closing_mps: float = 0.1
    """Smallest closing speed (m/s): a deck falling as fast as the vehicle descends is never met."""
    touchdown_sink_mps: float = 0.5
    """The vehicle's sink rate at contact (m/s, downward positive)."""
    settle_s: float = 1.0
    """After contact the deck must stay inside the limits this long (s): the motors spin down and the
    vehicle sits on the gear."""
    timing_tolerance_s: float = 0.3
    """Contact may come this much earlier than planned (s): the descent's timing error."""
    margin_sigma: float = 1.0
    """Standard deviations of the prediction kept as margin (k). On the test's simulated sea (patrol boat,
    sea state 3, a 3 s descent) k = 1 gave 44 windows in 51 decisions, with the truth inside the limits
    at contact in 36 (82 %); k = 2 gave none, because 3 s and more ahead the prediction's uncertainty is
    close to the motion's own."""
    min_window_s: float = 0.0
    """Feasible contact times must span at least this long (s) for a window to be taken."""

    def __post_init__(self) -> None:
        for name in ("max_tilt_rad", "max_closing_mps", "touchdown_sink_mps"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ConfigError(f"quiet window: {name} must be finite and > 0, got {v}")
        for name in ("min_closing_mps", "settle_s", "timing_tolerance_s", "margin_sigma", "min_window_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ConfigError(f"quiet window: {name} must be finite and >= 0, got {v}")
        if self.min_closing_mps >= self.max_closing_mps:
            raise ConfigError("quiet window: min_closing_mps must be below max_closing_mps")


@dataclass(frozen=True)
class QuietWindow:
    """The chosen window: contact times in [t_open, t_close] are feasible."""

    t_open: float
    t_close: float
    t_contact: float
    """Planned contact (s): the window's middle."""
    t_start_descent: float
    """When to start the final descent (s): ``t_contact - descent_s``."""


def _check(
    t: FloatArray, heave_rate: FloatArray, roll: FloatArray, pitch: FloatArray, cov: FloatArray
) -> None:
    k = t.shape[0]
    if t.ndim != 1 or k < 2:
        raise EstimationError(f"quiet window: times must be 1-D with at least 2 points, got shape {t.shape}")
    for name, a in (("heave_rate", heave_rate), ("roll", roll), ("pitch", pitch)):
        if a.shape != (k,):
            raise EstimationError(f"quiet window: {name} must have shape ({k},), got {a.shape}")
    if cov.shape != (k, 6, 6):
        raise EstimationError(f"quiet window: cov must have shape ({k}, 6, 6), got {cov.shape}")
    if not all(np.isfinite(a).all() for a in (t, heave_rate, roll, pitch, cov)):
        raise EstimationError("quiet window: the prediction is not finite")
    if not (np.diff(t) > 0.0).all():
        raise EstimationError("quiet window: times must increase")


def feasible_contacts(
    t: FloatArray,
    heave_rate: FloatArray,
    roll: FloatArray,
    pitch: FloatArray,
    cov: FloatArray,
    config: QuietWindowConfig,
) -> NDArray[np.bool_]:
    """Boolean (k,): contact at t[i] is feasible (module docstring). ``cov`` (k, 6, 6) is over [z, z',
    roll, roll', pitch, pitch'] (the deck estimator's order); zeros: an exact trajectory."""
    t, heave_rate, roll, pitch, cov = (
        np.asarray(a, dtype=np.float64) for a in (t, heave_rate, roll, pitch, cov)
    )
    _check(t, heave_rate, roll, pitch, cov)
    c = config
    k_s = c.margin_sigma
    tilt = np.arccos(np.clip(np.cos(roll) * np.cos(pitch), -1.0, 1.0))
    s_tilt = np.sqrt(np.maximum(cov[:, 2, 2], cov[:, 4, 4]))
    s_v = np.sqrt(np.maximum(cov[:, 1, 1], 0.0))
    closing = c.touchdown_sink_mps + heave_rate
    ok = (
        (tilt + k_s * s_tilt <= c.max_tilt_rad)
        & (closing - k_s * s_v >= c.min_closing_mps)
        & (closing + k_s * s_v <= c.max_closing_mps)
    )
    # contact at t_i needs ok over [t_i - tolerance, t_i + settle]: a sliding minimum over the grid
    out: NDArray[np.bool_] = np.zeros(t.shape[0], dtype=bool)
    bad = np.concatenate([[0], np.cumsum(~ok)])
    lo = np.searchsorted(t, t - c.timing_tolerance_s, side="left")
    hi = np.searchsorted(t, t + c.settle_s, side="right")
    inside = (t - c.timing_tolerance_s >= t[0]) & (t + c.settle_s <= t[-1])
    out[:] = inside & (bad[hi] - bad[lo] == 0)
    return out


def find_quiet_window(
    t: FloatArray,
    heave_rate: FloatArray,
    roll: FloatArray,
    pitch: FloatArray,
    cov: FloatArray,
    descent_s: float,
    t_now: float,
    config: QuietWindowConfig | None = None,
) -> QuietWindow | None:
    """The next quiet window reachable with a final descent of ``descent_s`` seconds started at or after
    ``t_now``; None when the prediction holds none (wait, or go around)."""
    c = config if config is not None else QuietWindowConfig()
    if not (math.isfinite(descent_s) and descent_s >= 0.0 and math.isfinite(t_now)):
        raise EstimationError(f"quiet window: descent_s {descent_s} and t_now {t_now} must be finite, >= 0")
    ts = np.asarray(t, dtype=np.float64)
    ok = feasible_contacts(ts, heave_rate, roll, pitch, cov, c)
    ok &= ts - descent_s >= t_now - 1e-12
    i = 0
    n = ts.shape[0]
    while i < n:
        if not ok[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and ok[j + 1]:
            j += 1
        if ts[j] - ts[i] >= c.min_window_s:
            mid = ts[(i + j) // 2] if (j - i) % 2 == 0 else 0.5 * (ts[(i + j) // 2] + ts[(i + j) // 2 + 1])
            return QuietWindow(float(ts[i]), float(ts[j]), float(mid), float(mid - descent_s))
        i = j + 1
    return None


def check_commitment(
    t: FloatArray,
    heave_rate: FloatArray,
    roll: FloatArray,
    pitch: FloatArray,
    cov: FloatArray,
    t_contact: float,
    config: QuietWindowConfig | None = None,
) -> bool:
    """True when a fresh prediction still holds the committed contact at ``t_contact``; False: the
    window closes before contact (or opens after it), go around. A contact outside the prediction's
    grid is not held."""
    c = config if config is not None else QuietWindowConfig()
    ts = np.asarray(t, dtype=np.float64)
    ok = feasible_contacts(ts, heave_rate, roll, pitch, cov, c)
    i = int(np.searchsorted(ts, t_contact))
    if i >= ts.shape[0] or not math.isfinite(t_contact):
        return False
    j = i if abs(ts[i] - t_contact) < 1e-9 or i == 0 else i - 1
    return bool(ok[j] and ok[i])
