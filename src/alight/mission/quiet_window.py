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
from dataclasses import dataclass, replace
from typing import Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from alight.errors import ConfigError, EstimationError
from alight.estimation.deck_estimator import DeckPrediction
from alight.types import FloatArray

__all__ = [
    "DeckPredictor",
    "QuietWindow",
    "QuietWindowConfig",
    "QuietWindowGate",
    "check_commitment",
    "contact_times",
    "feasible_contacts",
    "find_quiet_window",
    "plan_descent",
]


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
    hold_clearance_m: float = 0.6
    """The descent waits this far above the deck's highest predicted point (its height plus k sigma over
    ``horizon_s``) (m): the mission's commit height (``land_commit_height_m``, 0.6 m), below which the
    camera may lose the pad; so the wait is above every gate's reach and the final descent is the
    committed one."""
    horizon_s: float = 10.0
    """How far ahead the deck is predicted for the wait's height and the window (s): more than the
    final descent from the hold (about 2-4 s at 0.4 m/s) plus a wave period's worth of choice."""
    grid_step_s: float = 0.1
    """Time step of that prediction (s)."""
    replan_every_s: float = 0.2
    """A new prediction and plan at most this often while waiting or descending (s)."""
    max_wait_s: float = 60.0
    """Longest wait for a window before a go-around (s): several wave periods with no quiet one."""

    def __post_init__(self) -> None:
        for name in ("max_tilt_rad", "max_closing_mps", "touchdown_sink_mps"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ConfigError(f"quiet window: {name} must be finite and > 0, got {v}")
        for name in ("hold_clearance_m", "horizon_s", "grid_step_s", "replan_every_s", "max_wait_s"):
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


# -- timing a descent from a hold into a window ----------------------------------------------------------


def contact_times(t: FloatArray, z_deck: FloatArray, z_start: float, sink_mps: float) -> FloatArray:
    """For a descent at ``sink_mps`` from the height ``z_start`` (m) started at each grid time t[s], the
    first grid time at or after it where the descending height meets the deck's ``z_deck`` (k,); NaN
    where it does not within the grid. (k,) s."""
    ts = np.asarray(t, dtype=np.float64)
    z = np.asarray(z_deck, dtype=np.float64)
    # ramp[s, i] = z_start - sink (t_i - t_s), valid for i >= s
    ramp = z_start - sink_mps * (ts[None, :] - ts[:, None])
    met = (ramp <= z[None, :]) & (ts[None, :] >= ts[:, None])
    first = np.argmax(met, axis=1)
    out: FloatArray = ts[first].astype(np.float64)
    out[~met.any(axis=1)] = math.nan
    return out


def plan_descent(
    pred: DeckPrediction, z_start: float, t_now: float, config: QuietWindowConfig
) -> QuietWindow | None:
    """The quiet window to meet from a hold at ``z_start`` (m) with a descent at the config's
    ``touchdown_sink_mps``: the first window (run of feasible contact times, :func:`feasible_contacts`)
    that some descent started at or after ``t_now`` reaches, and of the starts that reach it the one
    whose contact is nearest the window's middle. None: no window in the prediction."""
    c = config
    t = pred.t
    ok = feasible_contacts(t, pred.heave_rate, pred.roll, pred.pitch, pred.cov, c)
    tc = contact_times(t, pred.heave, z_start, c.touchdown_sink_mps)
    run = np.concatenate([[0], np.cumsum(np.diff(ok.astype(np.int64)) == 1)]) + (1 if ok[0] else 0)
    run = np.where(ok, run, 0)  # the window number of each grid time (0: not feasible)
    starts = np.nonzero((t >= t_now - 1e-12) & np.isfinite(tc))[0]
    if starts.size == 0:
        return None
    idx = np.searchsorted(t, tc[starts])
    idx = np.minimum(idx, t.shape[0] - 1)
    hit = run[idx]
    good = hit > 0
    if not good.any():
        return None
    first = int(hit[good].min())
    members = np.nonzero(run == first)[0]
    t_open, t_close = float(t[members[0]]), float(t[members[-1]])
    if t_close - t_open < c.min_window_s:
        return None
    mid = 0.5 * (t_open + t_close)
    cand = starts[hit == first]
    best = int(cand[np.argmin(np.abs(tc[cand] - mid))])
    return QuietWindow(t_open, t_close, float(tc[best]), float(t[best]))


class DeckPredictor(Protocol):
    """What the gate reads: the deck predicted at absolute times (None before any measurement)."""

    def predict_deck(self, times: FloatArray) -> DeckPrediction | None: ...


GateDecision = Literal["descend", "hold", "go_around"]


class QuietWindowGate:
    """The quiet-window touchdown's decisions, step by step, for the mission's landing (the state
    machine's hook): wait above the deck's highest predicted point, start the final descent so that it
    meets the deck inside the next quiet window, and go around when a fresh prediction says the window
    closes (or opens too late) for the contact the descent is heading for.

    :meth:`step` is called at the mission's rate in the landing with the body's height ``z_WB``:

    - ``"descend"`` above the wait's height (the descent approaches it), and once the final descent has
      started;
    - ``"hold"`` at or below that height until the planned start of the final descent;
    - ``"go_around"`` when, descending, the contact predicted from the descent's own start and speed is
      no longer feasible, or no window came within ``max_wait_s``; :attr:`reason` says which.
    """

    def __init__(self, deck: DeckPredictor, config: QuietWindowConfig, sink_mps: float) -> None:
        self.deck = deck
        self.config = replace(config, touchdown_sink_mps=sink_mps)
        self.window: QuietWindow | None = None
        self.reason = ""
        self._t_plan = -math.inf
        self._z_start = math.nan
        self._descending = False
        self._t_start = math.nan
        self._t_wait: float | None = None
        self.n_plans = 0

    def reset(self) -> None:
        """A new approach (after a go-around): no plan, not waiting."""
        self.window, self._descending, self._t_wait, self._t_plan = None, False, None, -math.inf

    def _predict(self, t: float) -> DeckPrediction | None:
        c = self.config
        return self.deck.predict_deck(t + np.arange(0.0, c.horizon_s + 0.5 * c.grid_step_s, c.grid_step_s))

    def hold_height(self, pred: DeckPrediction) -> float:
        """The wait's height (m): the highest predicted deck point, k sigma up, plus the clearance."""
        c = self.config
        top = pred.heave + c.margin_sigma * np.sqrt(np.maximum(pred.cov[:, 0, 0], 0.0))
        return float(top.max()) + c.hold_clearance_m

    def step(self, t: float, z_WB: float) -> GateDecision:
        """The decision at ``t`` (class docstring)."""
        c = self.config
        if self._descending:
            return self._check(t)
        if t - self._t_plan < c.replan_every_s and self._t_wait is not None:
            return self._hold_or_go(t)
        pred = self._predict(t)
        self._t_plan = t
        if pred is None or z_WB > self.hold_height(pred):
            self._t_wait = None
            return "descend"  # still above the wait's height: keep approaching it
        if self._t_wait is None:
            self._t_wait, self._z_start = t, z_WB  # the guidance holds the height it had here
        self.window = plan_descent(pred, self._z_start, t, c)
        self.n_plans += 1
        return self._hold_or_go(t)

    def _hold_or_go(self, t: float) -> GateDecision:
        w = self.window
        if w is not None and t >= w.t_start_descent - 1e-9:
            self._descending, self._t_plan = True, t
            self._t_start = t
            return "descend"
        if self._t_wait is not None and t - self._t_wait > self.config.max_wait_s:
            self.reason = "no quiet window in the deck's motion"
            return "go_around"
        return "hold"

    def _check(self, t: float) -> GateDecision:
        """Descending: the contact the descent heads for, with a fresh prediction, still feasible."""
        c = self.config
        if t - self._t_plan < c.replan_every_s:
            return "descend"
        self._t_plan = t
        pred = self._predict(t)
        if pred is None:
            return "descend"
        z_now = self._z_start - c.touchdown_sink_mps * (t - self._t_start)
        tc = contact_times(pred.t[:1], pred.heave[:1], z_now, c.touchdown_sink_mps)
        if math.isfinite(float(tc[0])):
            return "descend"  # at the deck now: the touchdown is the land detector's
        tc = contact_times(pred.t, pred.heave, z_now, c.touchdown_sink_mps)
        t_contact = float(tc[0])
        if math.isfinite(t_contact) and t_contact - t <= c.timing_tolerance_s + c.grid_step_s:
            return "descend"  # contact within the timing tolerance: too late and too low to turn back
        if not math.isfinite(t_contact) or not check_commitment(
            pred.t, pred.heave_rate, pred.roll, pred.pitch, pred.cov, t_contact, c
        ):
            self.reason = "the deck's quiet window closed before contact"
            return "go_around"
        return "descend"
