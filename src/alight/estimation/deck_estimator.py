"""Estimator and predictor of a ship's deck (issue 37, point 3): the horizontal motion as the platform EKF
tracks it, plus the pad's height, roll and pitch with a model of wave motion, predicted seconds ahead.

**Horizontal.** A :class:`alight.estimation.platform_ekf.PlatformEkf` (unicycle model) is fed the pad's
horizontal position. Its vertical channel is not used: it is given a fixed height, and the pad's height
comes from the heave channel below.

**Heave, roll, pitch.** Each of the three channels c (the pad's height z in W, the deck's roll, its pitch)
is a slowly wandering mean b (a random walk: the mean height, the list and trim) plus a stationary
continuous-time autoregression of order p (CAR(p), p = ``order``; p = 4 is two damped oscillators)::

    y_c = b + x,    x^(p) + a_1 x^(p-1) + ... + a_p x = w,   w white with density q

Its state is ``[b, x, x', ..., x^(p-1)]``: the value and the rate (z and dz/dt, roll and its rate) are
states, and the poles of the polynomial are the oscillators' frequencies and damping. The model is
*fitted online*: every ``refit_every_s`` the channel's measurements of the last ``fit_window_s``,
averaged in bins of ``fit_dt_s``, are fitted by least squares with a discrete AR(p); its poles, mapped to
continuous time (s = ln(lambda) / dt), give the polynomial, and q is set so that the model's stationary
variance (a Lyapunov equation) equals the variance of the binned record minus the bins' noise. Before
the first fit (less than ``fit_min_s`` of record) the model is ``prior_period_s`` with
``prior_damping`` as a double oscillator and ``prior_std`` as its standard deviation. The three channels
are one joint linear Kalman filter (block-diagonal model): the measurements' cross-covariances are kept.
Discretisation is exact (Van Loan's matrix exponential), so the filter is an exact Kalman filter of the
model; what can make it inconsistent is only the model's fit to the sea (the tests measure its NEES).

**Measurements.** :meth:`DeckEstimator.update_pose`: the pad's position (3,) with covariance and the
deck's (roll, pitch) with covariance, as PnP gives them, stamped at capture. :meth:`update_mru`: a motion
reference unit's (roll, pitch) and the heave rate at the pad, stamped at the sample. Latency: each is
fused at its stamp. Messages of the two streams arrive out of stamp order (the camera's latency is longer
than the MRU's); a message older than the filter's time but within ``replay_window_s`` is inserted in
stamp order and the later ones are fused again from a checkpoint (exact); older ones are refused and
counted (``n_too_late``).

**Prediction.** :meth:`DeckEstimator.predict` gives, at future times, the pad's height and vertical
speed, the roll and pitch and their rates, with their covariance (the model's exact transition and
process noise over each horizon), as a :class:`DeckPrediction`.

**Bad input** (:mod:`alight.estimation.guards`): a non-finite or out-of-bounds time, position or
attitude, a wrong shape or a covariance that is not symmetric positive semi-definite raises
:class:`alight.errors.MeasurementError` and leaves the filter untouched; a message stamped more than
``FUTURE_TOLERANCE_S`` after the clock given to :meth:`DeckEstimator.set_clock` is refused and counted
(``n_future``), as the other estimators do. An innovation beyond ``GATE_SIGMA`` (Mahalanobis) is refused
(``n_gated``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import expm, solve_continuous_lyapunov

from alight.errors import EstimationError, MeasurementError
from alight.estimation.guards import (
    FUTURE_TOLERANCE_S,
    GATE_SIGMA,
    MAX_HORIZON_S,
    MAX_POSITION_M,
    MAX_SPEED_MPS,
    check_covariance,
    check_time,
    check_vector,
)
from alight.estimation.platform_ekf import PlatformEkf, PlatformEkfConfig
from alight.types import FloatArray, PlatformEstimate, PlatformMeasurement

__all__ = ["CHANNELS", "DeckEstimator", "DeckEstimatorConfig", "DeckPrediction", "car_model_from_ar"]

CHANNELS: tuple[str, ...] = ("heave", "roll", "pitch")
MAX_ANGLE_RAD = 1.0
"""Largest deck roll or pitch accepted as a measurement (rad, 57 deg): beyond, no deck is landable and
the number is a fault."""


def _horizontal_default() -> PlatformEkfConfig:
    # the pad on a deck also sways with roll (a 2 m high pad at 10 deg moves 0.35 m) and surges with the
    # waves: a horizontal random walk well above the ground vehicles' 0.05 m/s/sqrt(Hz)
    return PlatformEkfConfig(horizontal_noise=0.5, vertical_noise=0.0)


@dataclass(frozen=True, kw_only=True)
class DeckEstimatorConfig:
    """Settings of :class:`DeckEstimator` (module docstring)."""

    order: int = 4
    """Order p of each channel's CAR model: 2 (one oscillator) or 4 (two). Order 6 was tried: its fitted
    fast poles made the roll prediction diverge, and it predicted no better."""
    fit_dt_s: float = 0.4
    """Bin width of the record the model is fitted to (s); its Nyquist frequency (7.9 rad/s) is above
    every packaged vessel's resonance. 0.25 s and 0.5 s were measured too (patrol boat, sea state 4): the
    heave's 1 s error was 0.34 and 0.25 of its std, roll 0.26 and 0.22, pitch 0.45 either way."""
    fit_window_s: float = 120.0
    """Length of that record (s): several tens of wave periods."""
    fit_min_s: float = 30.0
    """Record needed before the first fit (s)."""
    refit_every_s: float = 5.0
    """Time between fits (s)."""
    min_damping: float = 0.02
    """Smallest damping ratio a fitted pole keeps (a stable model whatever the fit)."""
    prior_period_s: float = 6.0
    """Oscillation period (s) of the model before the first fit."""
    prior_damping: float = 0.2
    """Its damping ratio."""
    prior_std: tuple[float, float, float] = (0.5, 0.05, 0.05)
    """Its standard deviations: heave (m), roll and pitch (rad)."""
    mean_noise: tuple[float, float, float] = (0.01, 0.001, 0.001)
    """Random walk of each channel's mean: heave (m/sqrt(s)), roll and pitch (rad/sqrt(s))."""
    replay_window_s: float = 1.0
    """Messages up to this much older than the filter's time are inserted and the later ones re-fused."""
    horizontal: PlatformEkfConfig = field(default_factory=_horizontal_default)
    """The horizontal filter's settings."""

    def __post_init__(self) -> None:
        if self.order not in (2, 4):
            raise ValueError(f"order must be 2 or 4, got {self.order}")
        for name in ("fit_dt_s", "fit_window_s", "fit_min_s", "refit_every_s", "prior_period_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")
        if not self.fit_min_s <= self.fit_window_s:
            raise ValueError("fit_min_s must be <= fit_window_s")
        if not (0.0 < self.min_damping < 1.0 and 0.0 < self.prior_damping < 1.0):
            raise ValueError("damping ratios must be in (0, 1)")
        for name in ("prior_std", "mean_noise"):
            v = getattr(self, name)
            if len(v) != 3 or not all(math.isfinite(x) and x > 0.0 for x in v):
                raise ValueError(f"{name} must be three finite numbers > 0, got {v}")
        if not (math.isfinite(self.replay_window_s) and self.replay_window_s >= 0.0):
            raise ValueError(f"replay_window_s must be finite and >= 0, got {self.replay_window_s}")


@dataclass(frozen=True)
class DeckPrediction:
    """The deck predicted at times t (k,): its physical state and covariance at each."""

    t: FloatArray
    """Times (s), (k,)."""
    state: FloatArray
    """(k, 6): [z, dz/dt, roll, roll rate, pitch, pitch rate] (m, m/s, rad, rad/s); z is the pad's height
    in W and dz/dt its vertical speed."""
    cov: FloatArray
    """(k, 6, 6) covariance of ``state``."""

    @property
    def heave(self) -> FloatArray:
        out: FloatArray = self.state[:, 0]
        return out

    @property
    def heave_rate(self) -> FloatArray:
        out: FloatArray = self.state[:, 1]
        return out

    @property
    def roll(self) -> FloatArray:
        out: FloatArray = self.state[:, 2]
        return out

    @property
    def pitch(self) -> FloatArray:
        out: FloatArray = self.state[:, 4]
        return out


def car_model_from_ar(ar: FloatArray, dt: float, min_damping: float) -> FloatArray:
    """The CAR polynomial ``[1, a_1, ..., a_p]`` (s^p + a_1 s^(p-1) + ...) whose poles are the discrete
    AR(p) model's ``y_n = sum_i ar[i] y_(n-1-i) + e_n`` poles mapped by s = ln(lambda) / dt, each kept at
    least ``min_damping`` damped (a negative real discrete pole, which has no continuous image, is taken at
    its modulus)."""
    lam = np.roots(np.concatenate([[1.0], -np.asarray(ar, dtype=np.float64)]))
    poles: list[complex] = []
    for z in lam:
        if abs(z.imag) < 1e-12 and z.real <= 0.0:
            z = complex(abs(z.real), 0.0)
        s = complex(np.log(max(abs(z), 1e-12)), float(np.angle(z))) / dt
        w = abs(s)
        if w > math.pi / dt:  # a pole beyond the record's Nyquist frequency is the fit's, not the sea's
            s *= math.pi / dt / w
            w = math.pi / dt
        if w < 1e-6:
            s = complex(-1e-3, 0.0)
        elif s.real > -min_damping * w:
            s = complex(-min_damping * w, math.copysign(w * math.sqrt(1.0 - min_damping**2), s.imag))
            if abs(z.imag) < 1e-12:
                s = complex(-w, 0.0)
        poles.append(s)
    out: FloatArray = np.real(np.poly(poles))
    return out


def _companion(poly: FloatArray) -> FloatArray:
    """State matrix of x^(p) + a_1 x^(p-1) + ... = w over [x, x', ..., x^(p-1)]."""
    p = poly.shape[0] - 1
    A = np.zeros((p, p))
    A[: p - 1, 1:] = np.eye(p - 1)
    A[p - 1, :] = -poly[1:][::-1]
    return A


def _unit_variance(A: FloatArray) -> float:
    """Stationary variance of x for w of unit density."""
    p = A.shape[0]
    BB = np.zeros((p, p))
    BB[p - 1, p - 1] = 1.0
    S = solve_continuous_lyapunov(A, -BB)
    return float(S[0, 0])


class _Channel:
    """One channel's model: [b, x, x', ...], with A, and the process noise densities."""

    def __init__(self, poly: FloatArray, variance: float, mean_noise: float) -> None:
        self.set_model(poly, variance)
        self.mean_noise = mean_noise

    def set_model(self, poly: FloatArray, variance: float) -> None:
        self.A_x = _companion(poly)
        self.q = variance / _unit_variance(self.A_x)
        self.poly = poly

    def stationary(self) -> FloatArray:
        p = self.A_x.shape[0]
        BB = np.zeros((p, p))
        BB[p - 1, p - 1] = self.q
        out: FloatArray = np.asarray(solve_continuous_lyapunov(self.A_x, -BB), dtype=np.float64)
        return out


@dataclass
class _Entry:
    t: float
    H: FloatArray
    z: FloatArray
    R: FloatArray
    x: FloatArray = field(default_factory=lambda: np.zeros(0))
    P: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    used: bool = True


class _Bins:
    """A channel's measurements averaged in bins of width dt (inverse-variance weights)."""

    def __init__(self, dt: float) -> None:
        self.dt = dt
        self.sum: dict[int, float] = {}
        self.weight: dict[int, float] = {}

    def add(self, t: float, y: float, var: float) -> None:
        k = math.floor(t / self.dt)
        w = 1.0 / max(var, 1e-12)
        self.sum[k] = self.sum.get(k, 0.0) + w * y
        self.weight[k] = self.weight.get(k, 0.0) + w

    def record(self, t_end: float, span: float) -> tuple[FloatArray, float] | None:
        """The bin means over (t_end - span, t_end] (gaps linearly filled) and the mean noise variance of a
        bin; None if under 80 % of the bins hold data."""
        k1 = math.floor(t_end / self.dt) - 1  # the last complete bin
        k0 = k1 - round(span / self.dt) + 1
        for k in [k for k in self.sum if k < k0 - 10]:
            del self.sum[k], self.weight[k]
        ks = np.array([k for k in range(k0, k1 + 1) if k in self.weight])
        if ks.shape[0] < 0.8 * (k1 - k0 + 1) or ks.shape[0] < 10:
            return None
        ys = np.array([self.sum[k] / self.weight[k] for k in ks])
        noise = float(np.mean([1.0 / self.weight[k] for k in ks]))
        full = np.interp(np.arange(k0, k1 + 1), ks, ys)
        return full, noise


def fit_ar(y: FloatArray, order: int) -> FloatArray | None:
    """Least-squares AR(order) coefficients of the mean-removed record y; None if it is degenerate."""
    y = y - y.mean()
    n = y.shape[0]
    if n <= 4 * order:
        return None
    X = np.column_stack([y[order - 1 - i : n - 1 - i] for i in range(order)])
    coef, *_ = np.linalg.lstsq(X, y[order:], rcond=None)
    out: FloatArray = np.asarray(coef, dtype=np.float64)
    return out if np.isfinite(out).all() else None


class DeckEstimator:
    """The deck's horizontal track (platform EKF) and its heave, roll and pitch (module docstring)."""

    def __init__(self, config: DeckEstimatorConfig | None = None) -> None:
        self.config = config if config is not None else DeckEstimatorConfig()
        c = self.config
        self.horizontal = PlatformEkf(c.horizontal)
        p = c.order
        self._p = p
        self._n = 3 * (p + 1)
        w = 2.0 * math.pi / c.prior_period_s
        one = np.array([1.0, 2.0 * c.prior_damping * w, w * w])
        prior = np.convolve(one, one) if p == 4 else one
        self._prior_poly = prior
        self._channels = [_Channel(prior, s**2, m) for s, m in zip(c.prior_std, c.mean_noise, strict=True)]
        self._bins = [_Bins(c.fit_dt_s) for _ in CHANNELS]
        self._cache: dict[float, tuple[FloatArray, FloatArray]] = {}
        self._t = math.nan
        self._t_now = math.nan
        self._x = np.zeros(self._n)
        self._P = np.zeros((self._n, self._n))
        self._hist: list[_Entry] = []
        self._base: tuple[float, FloatArray, FloatArray] | None = None
        self._next_fit = c.fit_min_s
        self._t_first = math.nan
        self.n_updates = 0
        self.n_too_late = 0
        self.n_future = 0
        self.n_gated = 0
        self.n_fits = 0
        self.n_replays = 0

    # ---- the model -------------------------------------------------------------------------------

    def _offset(self, ch: int) -> int:
        return ch * (self._p + 1)

    def _discrete(self, dt: float) -> tuple[FloatArray, FloatArray]:
        """Exact transition F and process noise Q over dt (Van Loan), cached per dt."""
        key = round(dt, 6)  # the grid's steps differ in rounding only
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        n, p = self._n, self._p
        F = np.zeros((n, n))
        Q = np.zeros((n, n))
        for ch, chan in enumerate(self._channels):
            o = self._offset(ch)
            A = np.zeros((p + 1, p + 1))
            A[1:, 1:] = chan.A_x
            Qc = np.zeros((p + 1, p + 1))
            Qc[0, 0] = chan.mean_noise**2
            Qc[p, p] = chan.q
            M = np.zeros((2 * (p + 1), 2 * (p + 1)))
            M[: p + 1, : p + 1] = -A
            M[: p + 1, p + 1 :] = Qc
            M[p + 1 :, p + 1 :] = A.T
            # Van Loan's block exp(-A h) grows as exp(|A| h): over a long horizon it overflows (and loses
            # Qd's precision well before). Take it over h = dt / 2^k with |A| h <= 4, then double k times
            # by the semigroup law F(2h) = F(h)^2, Q(2h) = F(h) Q(h) F(h)^T + Q(h) (exact, and bounded
            # work: k is at most ~20 for any horizon up to MAX_HORIZON_S)
            scale = float(np.abs(A).sum(axis=0).max()) * dt
            k = max(0, math.ceil(math.log2(scale / 4.0))) if scale > 4.0 else 0
            h = dt / 2.0**k
            E = expm(M * h)
            Fc = E[p + 1 :, p + 1 :].T
            Qd = Fc @ E[: p + 1, p + 1 :]
            Qd = 0.5 * (Qd + Qd.T)
            for _ in range(k):
                Qd = Fc @ Qd @ Fc.T + Qd
                Fc = Fc @ Fc
                # a transition decayed below 1e-100 adds nothing beside Q's order-one terms; kept, its
                # products underflow
                Fc[np.abs(Fc) < 1e-100] = 0.0
            F[o : o + p + 1, o : o + p + 1] = Fc
            Q[o : o + p + 1, o : o + p + 1] = 0.5 * (Qd + Qd.T)
        if len(self._cache) > 64:
            self._cache.clear()
        self._cache[key] = (F, Q)
        return F, Q

    def _physical(self) -> FloatArray:
        """T (6, n): the state's [z, z', roll, roll', pitch, pitch'] (value = mean + x; rate = x')."""
        T = np.zeros((6, self._n))
        for ch in range(3):
            o = self._offset(ch)
            T[2 * ch, o] = 1.0
            T[2 * ch, o + 1] = 1.0
            T[2 * ch + 1, o + 2] = 1.0
        return T

    def _initial(self, t: float, H: FloatArray, z: FloatArray, R: FloatArray) -> None:
        """Start at the first message: each mean at its first value (or 0), x from the model's prior."""
        self._x[:] = 0.0
        self._P[:, :] = 0.0
        for ch, chan in enumerate(self._channels):
            o = self._offset(ch)
            self._P[o + 1 : o + 1 + self._p, o + 1 : o + 1 + self._p] = chan.stationary()
            self._P[o, o] = (10.0 if ch == 0 else 0.2) ** 2  # a mean height / list not known yet
        for r in range(H.shape[0]):  # a measured channel's mean starts at its value
            for ch in range(3):
                if H[r, self._offset(ch)] == 1.0:
                    self._x[self._offset(ch)] = z[r]
                    self._P[self._offset(ch), self._offset(ch)] = R[r, r]
        self._t = t
        self._t_first = t
        self._next_fit = t + self.config.fit_min_s

    def _refit(self) -> None:
        c = self.config
        for ch, chan in enumerate(self._channels):
            rec = self._bins[ch].record(self._t, min(c.fit_window_s, self._t - self._t_first))
            if rec is None:
                continue
            y, noise = rec
            ar = fit_ar(y, self._p)
            if ar is None:
                continue
            var = float(np.var(y)) - noise
            floor = 0.05 * float(np.var(y))
            chan.set_model(car_model_from_ar(ar, c.fit_dt_s, c.min_damping), max(var, floor, 1e-12))
        self._cache.clear()
        self.n_fits += 1

    # ---- the filter steps ------------------------------------------------------------------------

    def set_clock(self, t: float) -> None:
        """The caller's clock (s): messages stamped more than ``FUTURE_TOLERANCE_S`` later are refused."""
        self._t_now = check_time(t, "DeckEstimator.set_clock")

    def _kalman(
        self, x: FloatArray, P: FloatArray, dt: float, e: _Entry
    ) -> tuple[FloatArray, FloatArray, bool]:
        if dt > 0.0:
            F, Q = self._discrete(dt)
            x = F @ x
            P = F @ P @ F.T + Q
        r = e.z - e.H @ x
        S = e.H @ P @ e.H.T + e.R
        try:
            L = np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            return x, P, False
        u = np.linalg.solve(L, r)
        if float(u @ u) > GATE_SIGMA**2:
            return x, P, False
        K = np.linalg.solve(S, e.H @ P).T
        x = x + K @ r
        IKH = np.eye(self._n) - K @ e.H
        P = IKH @ P @ IKH.T + K @ e.R @ K.T
        return x, 0.5 * (P + P.T), True

    def _fuse(self, e: _Entry) -> bool:
        c = self.config
        if math.isnan(self._t):
            self._initial(e.t, e.H, e.z, e.R)
            self._base = (e.t, self._x.copy(), self._P.copy())
        if e.t >= self._t:
            self._x, self._P, e.used = self._kalman(self._x, self._P, e.t - self._t, e)
            self._t = e.t
            e.x, e.P = self._x.copy(), self._P.copy()
            self._hist.append(e)
        else:
            if self._base is None or e.t < self._base[0]:
                self.n_too_late += 1
                return False
            self._replay(e)
        while self._hist and self._hist[0].t < self._t - c.replay_window_s:
            old = self._hist.pop(0)
            self._base = (old.t, old.x, old.P)
        if not e.used:
            self.n_gated += 1
            return False
        self.n_updates += 1
        if self._t >= self._next_fit:
            self._refit()
            self._next_fit = self._t + c.refit_every_s
        return True

    def _replay(self, e: _Entry) -> None:
        assert self._base is not None
        i = next((k for k, h in enumerate(self._hist) if h.t > e.t), len(self._hist))
        t, x, P = (self._hist[i - 1].t, self._hist[i - 1].x, self._hist[i - 1].P) if i > 0 else self._base
        self._hist.insert(i, e)
        for h in self._hist[i:]:
            x, P, h.used = self._kalman(x, P, h.t - t, h)
            t = h.t
            h.x, h.P = x.copy(), P.copy()
        self._x, self._P, self._t = x, P, t
        self.n_replays += 1

    def _future(self, t: float) -> bool:
        if t > self._t_now + FUTURE_TOLERANCE_S:  # False while there is no clock (NaN)
            self.n_future += 1
            return True
        return False

    def update_pose(
        self,
        t: float,
        p_WP: FloatArray,
        cov_p_WP: FloatArray,
        roll_pitch: FloatArray | None,
        cov_roll_pitch: FloatArray | None,
    ) -> bool:
        """Fuse a pad pose captured at ``t`` (s): position (3,) m in W with covariance (3, 3) m^2, deck
        (roll, pitch) (2,) rad with covariance (2, 2); ``roll_pitch`` None: a position without attitude
        (the height alone is fused). True when fused."""
        where = "DeckEstimator.update_pose"
        t = check_time(t, where)
        p = check_vector(p_WP, 3, MAX_POSITION_M, "p_WP", where)
        cp = check_covariance(cov_p_WP, 3, where, "cov_p_WP")
        if cp[2, 2] <= 0.0:
            raise MeasurementError(f"{where}: the height variance must be > 0")
        m = 1
        a = ca = None
        if roll_pitch is not None or cov_roll_pitch is not None:
            a = check_vector(roll_pitch, 2, MAX_ANGLE_RAD, "roll_pitch", where)
            ca = check_covariance(cov_roll_pitch, 2, where, "cov_roll_pitch")
            if float(np.linalg.eigvalsh(ca).min()) <= 0.0:
                raise MeasurementError(f"{where}: the attitude covariance must be positive definite")
            m = 3
        if self._future(t):
            return False
        H = np.zeros((m, self._n))
        for ch in range(m):
            o = self._offset(ch)
            H[ch, o] = H[ch, o + 1] = 1.0
        R = np.zeros((m, m))
        R[0, 0] = cp[2, 2]
        z = np.array([p[2]]) if a is None else np.array([p[2], a[0], a[1]])
        if ca is not None:
            R[1:, 1:] = ca
        if t >= self._t_first or math.isnan(self._t_first):
            for ch in range(m):
                self._bins[ch].add(t, z[ch], R[ch, ch])
        hz = np.array([p[0], p[1], 0.0])
        hc = cp.copy()
        hc[2, :] = hc[:, 2] = 0.0
        hc[2, 2] = 1.0  # the horizontal filter's height is not used (module docstring)
        self.horizontal.predict(t if math.isnan(self._t_now) else self._t_now)
        rejected = self.horizontal.n_rejected
        self.horizontal.update(PlatformMeasurement(t=t, p_WP=hz, cov_p_WP=hc))
        if self.horizontal.n_rejected > rejected:
            self.n_gated += 1  # the track's gate refused the pad's position (an outlier): its height too
            return False
        return self._fuse(_Entry(t, H, z, R))

    def update_mru(self, t: float, roll_pitch: FloatArray, heave_rate: float, cov: FloatArray) -> bool:
        """Fuse a motion reference unit's sample at ``t`` (s): deck (roll, pitch) (2,) rad and the pad's
        vertical speed (m/s), with covariance (3, 3) over (roll, pitch, heave rate). True when fused."""
        where = "DeckEstimator.update_mru"
        t = check_time(t, where)
        a = check_vector(roll_pitch, 2, MAX_ANGLE_RAD, "roll_pitch", where)
        v = check_vector([heave_rate], 1, MAX_SPEED_MPS, "heave_rate", where)
        c = check_covariance(cov, 3, where, "cov")
        if float(np.linalg.eigvalsh(c).min()) <= 0.0:
            raise MeasurementError(f"{where}: cov must be positive definite")
        if self._future(t):
            return False
        H = np.zeros((3, self._n))
        H[0, self._offset(1)] = H[0, self._offset(1) + 1] = 1.0
        H[1, self._offset(2)] = H[1, self._offset(2) + 1] = 1.0
        H[2, 2] = 1.0  # the heave channel's x'
        self._bins[1].add(t, a[0], c[0, 0])
        self._bins[2].add(t, a[1], c[1, 1])
        z = np.array([a[0], a[1], v[0]])
        return self._fuse(_Entry(t, H, z, c))

    # ---- outputs ---------------------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        """True once a message was fused."""
        return not math.isnan(self._t)

    @property
    def t_filter(self) -> float:
        """Stamp of the latest message fused (s); NaN before any."""
        return self._t

    @property
    def fitted(self) -> bool:
        """True once the wave model was fitted to the record (before: the prior model)."""
        return self.n_fits > 0

    def models(self) -> dict[str, dict[str, Any]]:
        """Each channel's fitted model: its poles' periods (s) and damping ratios, and its std."""
        out: dict[str, dict[str, Any]] = {}
        for name, chan in zip(CHANNELS, self._channels, strict=True):
            poles = np.roots(chan.poly)
            osc = [s for s in poles if s.imag > 0.0]
            out[name] = {
                "periods_s": [2.0 * math.pi / s.imag for s in osc],
                "damping": [-s.real / abs(s) for s in osc],
                "std": math.sqrt(chan.q * _unit_variance(chan.A_x)),
            }
        return out

    def predict(self, times: FloatArray) -> DeckPrediction:
        """The deck at the absolute ``times`` (k,) (s), each at or after the filter's time (earlier ones
        are taken at the filter's time), at most ``MAX_HORIZON_S`` ahead (further ones are taken there)."""
        if not self.initialized:
            raise EstimationError("DeckEstimator.predict: no measurement yet")
        ts = np.asarray(times, dtype=np.float64)
        if ts.ndim != 1 or not np.isfinite(ts).all():
            raise EstimationError("DeckEstimator.predict: times must be a finite 1-D array")
        T = self._physical()
        k = ts.shape[0]
        state = np.empty((k, 6))
        cov = np.empty((k, 6, 6))
        # the model is linear and time-invariant: step from one time to the next in increasing order (a
        # uniform grid then needs one discretisation)
        dts = np.clip(ts - self._t, 0.0, MAX_HORIZON_S)
        x, P, t_prev = self._x, self._P, 0.0
        for i in np.argsort(dts, kind="stable"):
            step = float(dts[i]) - t_prev
            if step > 0.0:
                F, Q = self._discrete(step)
                x = F @ x
                P = F @ P @ F.T + Q
                t_prev = float(dts[i])
            state[i] = T @ x
            cov[i] = T @ P @ T.T
        return DeckPrediction(ts.copy(), state, 0.5 * (cov + cov.transpose(0, 2, 1)))

    def horizontal_state(self, t: float) -> PlatformEstimate:
        """The pad's horizontal track at ``t`` (its height and vertical covariance are not the deck's:
        use :meth:`predict`)."""
        return self.horizontal.state(t)

    def diagnostics(self) -> dict[str, Any]:
        """Counters for logs."""
        return {
            "n_updates": self.n_updates,
            "n_too_late": self.n_too_late,
            "n_future": self.n_future,
            "n_gated": self.n_gated,
            "n_fits": self.n_fits,
            "n_replays": self.n_replays,
        }
