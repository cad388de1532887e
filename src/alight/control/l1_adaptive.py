"""L1 adaptive augmentation of the translational loop, on top of the high-level controller.

Paper 003 (Kim, Jung, Lee, Shim) Sec. V-B: "we use L1 adaptive augmentation loop based on an output
feedback method to improve the accurate path tracking. The adaptive manner supplements the linear
controller [...] in the presence of the uncertainties [9]". The paper gives no equations; its source [9]
(Jung & Shim, J. Intell. Robot. Syst. 2012) augments a baseline controller with the L1 adaptive
output-feedback controller of Cao & Hovakimyan ("L1 adaptive output feedback controller for systems of
unknown dimension", IEEE TAC 53(3), 2008; Hovakimyan & Cao, "L1 Adaptive Control Theory", SIAM 2010,
Ch. 4). That structure is implemented here, per world axis, around the Faessler-style baseline:

* Plant (W, ENU z-up), with the measured output ``y = v`` (the ego estimate ``v_WB``)::

      dv/dt = u(t) + sigma(t),     u = (T_cmd / m) z_B + g - R D R^T v

  ``u`` is the known part: the commanded collective thrust ``T_cmd`` (N) along the measured body z axis,
  gravity ``g = (0, 0, -9.81)`` and the rotor drag ``R D R^T v`` that the baseline already feeds forward
  (D = the baseline's drag coefficients; zero when it has drag compensation off). ``sigma`` (m/s^2) lumps
  what is unknown: wind force / mass, a wrong mass or thrust constant, the air-relative part of the rotor
  drag, the motors' lag. Only the output ``v`` and the input ``u`` are used, never the attitude or rotor
  states of the loop in between (the "output feedback" of the paper: those dynamics stay in the unknown
  ``A(s)`` of Cao & Hovakimyan).

* Output predictor (Cao & Hovakimyan's state predictor with the Hurwitz pole ``A_s = -a_s I``)::

      dv_hat/dt = u(t) + sigma_hat(t) + A_s (v_hat - v),    y_tilde = v_hat - v

* Piecewise-constant adaptation law, sample time ``T_s``::

      sigma_hat(t) = sigma_hat(i T_s)  for t in [i T_s, (i+1) T_s)
      sigma_hat(i T_s) = -Phi(T_s)^-1 mu(i T_s),    mu(i T_s) = e^{A_s T_s} y_tilde(i T_s)
      Phi(T_s) = A_s^-1 (e^{A_s T_s} - I) = (1 - e^{-a_s T_s}) / a_s I

  i.e. the constant that, applied over the next interval, would bring the prediction error back to zero.

* Low-pass filter and augmentation (the "augmentation loop" of [9]: L1 adds to the baseline's input)::

      u_ad(s) = -C(s) sigma_hat(s),   C(s) = omega_c / (s + omega_c)        (C(0) = 1)
      a_ref' = a_ref + u_ad

  The baseline then builds thrust and attitude from ``a_ref'`` (its feed-forward and its feedback
  ``K_p e_p + K_v e_v``), so within C(s)'s bandwidth the vehicle feels ``(1 - C(s)) sigma`` instead of
  ``sigma``: a constant disturbance is cancelled instead of being balanced by a position offset
  ``sigma / K_p``.

* Jerk: the baseline's body-rate feed-forward differentiates its thrust vector ``a - g + R D R^T v`` as
  if ``a_ref'`` were the reference's acceleration, i.e. includes ``R D R^T a_ref'`` (Faessler 2018). The
  compensation is a force, not an acceleration of the reference, so its share is removed::

      j_ref' = j_ref + R D R^T C(s) sigma_hat          (R measured)

  Without it the drag model turns a steady compensation into a steady body-rate feed-forward, i.e. a
  steady tilt error (measured under 3.7 N of steady force: an offset of (-1.4, 1.0, -1.1) cm instead of
  the closed-form (0.7, -0.5, -0.25) cm below). ``dC(s)sigma_hat/dt`` is
  NOT fed forward: it is ``omega_c (sigma_hat - C sigma_hat)`` and ``sigma_hat`` carries the velocity
  noise amplified by ~1/T_s.

Discretisation. The controller runs at the rate it is called (``ego.t``). Between calls the thrust
command is held (zero-order hold) while ``z_B`` and ``v`` are measured at both ends; ``u`` is averaged by the
trapezoidal rule. The predictor error obeys ``dy_tilde/dt = A_s y_tilde + sigma_hat - sigma`` (``u`` cancels),
which is integrated exactly with ``sigma`` constant over the interval, whose integral is known from the
measurements: ``int sigma = v_k - v_{k-1} - dt u_bar``. So ``y_tilde_k = e^{-a_s dt} y_tilde_{k-1} +
Phi(dt) (sigma_hat - sigma_bar)``, ``sigma_bar = (v_k - v_{k-1}) / dt - u_bar``. C(s) is discretised
exactly (sigma_hat held). Two consequences, both tested:

* called every ``T_s``, the law reduces to ``sigma_hat_k = e^{-a_s T_s} sigma_bar_{k-1}``: a one-interval
  finite difference of the measured velocity minus the known input, scaled by ``e^{-a_s T_s}``; all
  smoothing is C(s)'s. (This is the known equivalence of the piecewise-constant L1 law with a disturbance
  observer.)
* for a constant ``sigma`` the fixed point is ``sigma_hat = e^{-a_s T_s} sigma``: the predictor pole
  biases the estimate, which is why ``a_s T_s`` is kept small (1 rad/s x 10 ms: 0.99 sigma); the
  remaining 1 % is left to the baseline's feedback.

The law is evaluated at the first call at least ``T_s`` after the previous adaptation, with the interval
``T = max(T_s, t - t_adapt)`` in ``Phi(T)`` and ``e^{A_s T}`` (the next interval is assumed as long as the
last one): a ``T_s`` shorter than the call period would otherwise over-correct every interval and
oscillate.

Design rule of the defaults (with the default gains: position loop 2 rad/s, tilt loop 1/0.12 s = 8.3
rad/s, roll/pitch rate loop 25 rad/s): ``T_s`` = the control period (10 ms at 100 Hz);
``omega_c`` = 4 rad/s, about half the tilt loop (the compensation reaches the vehicle through the attitude,
so a wider filter only passes the velocity noise, amplified by ~1/T_s in ``sigma_hat``) and 6x below the
rate loop, yet 2x above the position loop so that it, not the baseline, absorbs the disturbance.

Robustness: ``|sigma_hat|`` is projected onto a ball (``sigma_limit``), so the compensation is bounded; a
gap longer than ``max_gap`` restarts the predictor (keeping the estimate), time going backwards resets
the adaptive state; non-finite inputs or state make the controller fall back to the baseline command and
reset the adaptive state.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numba import njit, types

from alight.airframe import Airframe
from alight.control.high_level import HL_DRAG, HL_MASS, HighLevelController, HighLevelGains
from alight.control.rate import tilt_time_constant_s
from alight.numerics.rotation import quat_to_R
from alight.types import GRAVITY_MPS2, Command, EgoState, FloatArray, Reference

__all__ = [
    "L1AugmentedController",
    "L1Config",
    "faessler2017_l1",
    "l1_kernel",
    "new_l1_state",
    "pack_l1_params",
]

# --------------------------------------------------------------------------------------------------
# Layouts of the packed parameter and state vectors (float64)
# --------------------------------------------------------------------------------------------------
L1_MASS = 0  # 1: mass the thrust is divided by (kg)
L1_DRAG = 1  # 3: rotor-drag coefficients d_x, d_y, d_z of the known model (1/s)
L1_TS = 4  # 1: adaptation sample time T_s (s)
L1_AS = 5  # 1: predictor pole a_s, A_s = -a_s I (rad/s)
L1_WC = 6  # 1: bandwidth omega_c of C(s) (rad/s)
L1_SIG_LIM = 7  # 1: radius of the ball sigma_hat is projected onto (m/s^2)
L1_GAP = 8  # 1: longest interval the predictor integrates over (s)
L1_N_PARAMS = 9

S_VHAT = 0  # 3: predictor state v_hat (m/s)
S_SIG = 3  # 3: piecewise-constant estimate sigma_hat (m/s^2)
S_SIGF = 6  # 3: filtered estimate C(s) sigma_hat (m/s^2); the compensation is minus this
S_VPREV = 9  # 3: measured velocity at the previous call (m/s)
S_ZPREV = 12  # 3: measured body z axis at the previous call
S_DPREV = 15  # 3: R D R^T v at the previous call (m/s^2)
S_TPREV = 18  # 1: time of the previous call (s), NaN before the first
S_TADAPT = 19  # 1: time of the last adaptation (s)
S_THRUST = 20  # 1: collective thrust commanded at the previous call (N), NaN when none
L1_N_STATE = 21

_new = object.__new__
_setattr = object.__setattr__  # the frozen messages' own way to set their fields
_G = GRAVITY_MPS2
_TS_TOL = 1e-6  # relative slack on "at least T_s since the last adaptation" (clock round-off)


# --------------------------------------------------------------------------------------------------
# Kernel
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _init_state(state: FloatArray) -> None:
    for k in range(L1_N_STATE):
        state[k] = 0.0
    state[S_TPREV] = math.nan
    state[S_THRUST] = math.nan


def new_l1_state() -> FloatArray:
    """A fresh state vector for ``l1_kernel`` (no call yet, no estimate), shape (L1_N_STATE,)."""
    state = np.empty(L1_N_STATE)
    _init_state(state)
    return state


@njit(cache=True)
def l1_kernel(
    t: float,
    v: FloatArray,
    q: FloatArray,
    a_ref: FloatArray,
    j_ref: FloatArray,
    params: FloatArray,
    state: FloatArray,
    out: FloatArray,
) -> bool:
    """One call of the L1 augmentation (module docstring): predictor, adaptation law, C(s).

    Args:
        t: time of the measurement (s).
        v: measured velocity v_WB (m/s, W), shape (3,).
        q: measured attitude q_WB (x, y, z, w), shape (4,).
        a_ref, j_ref: reference acceleration (m/s^2) and jerk (m/s^3) in W, shape (3,).
        params: ``pack_l1_params``, shape (L1_N_PARAMS,).
        state: shape (L1_N_STATE,), updated in place; ``state[S_THRUST]`` must hold the thrust (N)
            commanded at the previous call (the caller writes it after the baseline has run).
        out: shape (6,), written with the reference the baseline gets: ``a_ref - C(s) sigma_hat``
            (m/s^2) and ``j_ref + R D R^T C(s) sigma_hat`` (m/s^3) (module docstring, "jerk").

    Returns:
        False (state untouched) when an input is not finite, or (state updated) when the new state or
        output is not finite; the caller then falls back to the baseline and resets the state.

    One kernel: the predictor, the adaptation law and C(s) read and write the one packed ``state`` in the
    order the module docstring derives them (the drag term R D R^T v feeds the predictor's input and is stored
    for the next call; the output needs the filtered estimate just updated). Split, the stages would only hand
    slices of ``state`` and ``R`` to each other, once per control tick.
    """
    if not math.isfinite(t):
        return False
    for k in range(3):
        if not (math.isfinite(v[k]) and math.isfinite(q[k])):
            return False
        if not (math.isfinite(a_ref[k]) and math.isfinite(j_ref[k])):
            return False
    if not math.isfinite(q[3]):
        return False

    R = np.empty((3, 3))
    # q copied to a writable array: the messages' q is read-only, the ego filter's is not, and numba would
    # compile quat_to_R once for each
    qw = np.empty(4)
    for k in range(4):
        qw[k] = q[k]
    quat_to_R(qw, R)
    # R D R^T v: the rotor drag of the known model (subtracted in u)
    dr0 = 0.0
    dr1 = 0.0
    dr2 = 0.0
    for c in range(3):
        s = params[L1_DRAG + c] * (R[0, c] * v[0] + R[1, c] * v[1] + R[2, c] * v[2])
        dr0 += s * R[0, c]
        dr1 += s * R[1, c]
        dr2 += s * R[2, c]

    t_prev = state[S_TPREV]
    dt = t - t_prev
    thrust = state[S_THRUST]
    if math.isnan(t_prev) or dt < 0.0:
        # first call, or the clock went back (a new run): start from nothing
        _init_state(state)
        for k in range(3):
            state[S_VHAT + k] = v[k]
        state[S_TADAPT] = t
    elif dt > params[L1_GAP] or math.isnan(thrust):
        # a gap: the velocity change says nothing about sigma any more; restart the predictor, keep
        # the estimate (a slowly varying disturbance is still there)
        for k in range(3):
            state[S_VHAT + k] = v[k]
        state[S_TADAPT] = t
    elif dt > 0.0:
        a_s = params[L1_AS]
        e_as = math.exp(-a_s * dt)
        phi = -math.expm1(-a_s * dt) / a_s  # Phi(dt) = int_0^dt e^{-a_s tau} d tau
        ec = math.exp(-params[L1_WC] * dt)
        t_m = 0.5 * thrust / params[L1_MASS]
        dr = (dr0, dr1, dr2)
        for k in range(3):
            # trapezoidal mean of u over the interval (thrust held, z_B and v measured at both ends)
            u_bar = t_m * (state[S_ZPREV + k] + R[k, 2]) - 0.5 * (state[S_DPREV + k] + dr[k])
            if k == 2:
                u_bar -= _G
            sig = state[S_SIG + k]
            yt = state[S_VHAT + k] - state[S_VPREV + k]
            # Phi(dt) sigma_bar = (Phi(dt) / dt) (v_k - v_{k-1} - dt u_bar): no division by a tiny dt
            yt = e_as * yt + phi * sig - (phi / dt) * (v[k] - state[S_VPREV + k] - dt * u_bar)
            state[S_VHAT + k] = v[k] + yt
            # C(s) = omega_c / (s + omega_c), exact with sigma_hat held over the interval
            state[S_SIGF + k] = sig + (state[S_SIGF + k] - sig) * ec
        elapsed = t - state[S_TADAPT]
        ts = params[L1_TS]
        if elapsed >= ts * (1.0 - _TS_TOL):
            T = max(ts, elapsed)
            e_T = math.exp(-a_s * T)
            gain = a_s * e_T / -math.expm1(-a_s * T)  # Phi(T)^-1 e^{-a_s T}
            n2 = 0.0
            for k in range(3):
                sk = -gain * (state[S_VHAT + k] - v[k])
                state[S_SIG + k] = sk
                n2 += sk * sk
            lim = params[L1_SIG_LIM]
            if n2 > lim * lim:  # projection onto the ball |sigma_hat| <= lim
                scale = lim / math.sqrt(n2)
                for k in range(3):
                    state[S_SIG + k] *= scale
            state[S_TADAPT] = t

    state[S_TPREV] = t
    state[S_DPREV] = dr0
    state[S_DPREV + 1] = dr1
    state[S_DPREV + 2] = dr2
    # The baseline reads a_ref' as a kinematic acceleration and feeds forward the rate of change of the
    # drag it would cause, R D R^T a_ref' (Faessler 2018's thrust derivative). The compensation is a force,
    # not an acceleration of the reference: take its share R D R^T (a_ref' - a_ref) back out of the
    # jerk, with the measured R (the compensated reference attitude up to the feedback's small tilt).
    sf = np.empty(3)
    for k in range(3):
        sf[k] = state[S_SIGF + k]
    ok = True
    for k in range(3):
        dj = 0.0
        for c in range(3):
            dj += R[k, c] * params[L1_DRAG + c] * (R[0, c] * sf[0] + R[1, c] * sf[1] + R[2, c] * sf[2])
        state[S_VPREV + k] = v[k]
        state[S_ZPREV + k] = R[k, 2]
        out[k] = a_ref[k] - sf[k]
        out[3 + k] = j_ref[k] + dj
        ok = ok and math.isfinite(out[k]) and math.isfinite(out[3 + k])
        ok = ok and math.isfinite(state[S_VHAT + k]) and math.isfinite(state[S_SIG + k])
    return ok


# --------------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class L1Config:
    """Parameters of ``L1AugmentedController`` (symbols of the module docstring). Defaults: the design
    rule there, for the default gains at 100 Hz."""

    sample_time: float = 0.01
    """Adaptation sample time T_s (s): the control period."""
    filter_bandwidth: float = 4.0
    """Bandwidth omega_c of the low-pass filter C(s) = omega_c / (s + omega_c) (rad/s)."""
    predictor_pole: float = 1.0
    """a_s > 0 with A_s = -a_s I (rad/s); a constant sigma is estimated as e^{-a_s T_s} sigma."""
    sigma_limit: float = 10.0
    """Radius of the ball the estimate is projected onto (m/s^2); bounds the compensation. About 1 g by
    default: the baseline's tilt limit (45 deg, i.e. 1 g sideways at hover) binds first in normal flight,
    this only catches an estimate gone wild."""
    max_gap: float = 0.1
    """Longest interval between calls the predictor integrates (s); after a longer one it restarts."""
    enabled: bool = True
    """Apply the compensation; when False the estimator still runs (for logging) and the command is
    exactly the baseline's."""

    def __post_init__(self) -> None:
        for name in ("sample_time", "filter_bandwidth", "predictor_pole", "sigma_limit", "max_gap"):
            val = float(getattr(self, name))
            if not (math.isfinite(val) and val > 0.0):
                raise ValueError(f"{name} must be positive and finite, got {getattr(self, name)}")
            object.__setattr__(self, name, val)
        if self.max_gap <= self.sample_time:
            raise ValueError(f"max_gap {self.max_gap} must exceed sample_time {self.sample_time}")
        if not isinstance(self.enabled, bool):
            raise ValueError(f"enabled must be a bool, got {self.enabled!r}")


def pack_l1_params(config: L1Config, mass: float, rotor_drag: tuple[float, float, float]) -> FloatArray:
    """Parameter vector of ``l1_kernel``, shape (L1_N_PARAMS,).

    ``mass`` (kg) and ``rotor_drag`` (1/s) are the known model the predictor uses: the baseline's.
    """
    if not (math.isfinite(mass) and mass > 0.0):
        raise ValueError(f"mass must be positive, got {mass}")
    p = np.zeros(L1_N_PARAMS)
    p[L1_MASS] = mass
    p[L1_DRAG : L1_DRAG + 3] = rotor_drag
    p[L1_TS] = config.sample_time
    p[L1_AS] = config.predictor_pole
    p[L1_WC] = config.filter_bandwidth
    p[L1_SIG_LIM] = config.sigma_limit
    p[L1_GAP] = config.max_gap
    if not np.isfinite(p).all():
        raise ValueError(f"rotor_drag must be finite, got {rotor_drag}")
    return p


_RO = types.Array(types.float64, 1, "C", readonly=True)
_RW = types.Array(types.float64, 1, "C")
_MESSAGE_SIG = (types.float64, _RO, _RO, _RO, _RO, _RW, _RW, _RW)
"""``l1_kernel``'s argument types when fed ``EgoState`` / ``Reference`` arrays (read-only C float64)."""


def _message_entry_point() -> Callable[..., bool]:
    """The compiled kernel for ``_MESSAGE_SIG``: calling it skips the dispatcher's per-argument type
    resolution (as ``high_level._message_entry_point``)."""
    try:
        return l1_kernel.compile(_MESSAGE_SIG)
    except Exception:  # pragma: no cover - a numba without Dispatcher.compile returning the entry point
        return l1_kernel


# --------------------------------------------------------------------------------------------------
# The controller
# --------------------------------------------------------------------------------------------------


class L1AugmentedController:
    """``base`` (the Faessler-style high-level controller) + the L1 augmentation of the module docstring.

    ``command(ego, ref)`` runs the L1 step on ``ego.v_WB``, ``ego.q_WB`` and the thrust it commanded at
    the previous call, then asks ``base`` for the command with the reference acceleration
    ``ref.a - C(s) sigma_hat`` and jerk ``ref.j + R D R^T C(s) sigma_hat``. Satisfies the ``Controller``
    protocol. The baseline's own integrator (if its ``ki`` is set) keeps working; both then act on the
    same disturbance (L1 first, being faster).
    """

    def __init__(self, base: HighLevelController, config: L1Config | None = None) -> None:
        self.base = base
        self.config = config if config is not None else L1Config()
        d = base.params[HL_DRAG : HL_DRAG + 3]  # zeros when the baseline does not compensate drag
        self.params = pack_l1_params(self.config, float(base.params[HL_MASS]), (d[0], d[1], d[2]))
        self.enabled = self.config.enabled
        """Apply the compensation (switchable in flight; the estimator runs either way)."""
        self._state = np.empty(L1_N_STATE)
        _init_state(self._state)
        self._out = np.zeros(6)
        self._kernel = _message_entry_point()

    def reset(self) -> None:
        """Forget the adaptive state and the baseline's (e.g. at a mode change)."""
        _init_state(self._state)
        self.base.reset()

    def set_tilt_limit(self, max_tilt_rad: float | None) -> None:
        """The baseline's tilt limit (:class:`~alight.control.TiltLimited`)."""
        self.base.set_tilt_limit(max_tilt_rad)

    def reset_adaptive(self) -> None:
        """Forget the adaptive state only (predictor, estimate, filter); the baseline keeps its own."""
        _init_state(self._state)

    @property
    def sigma_hat(self) -> FloatArray:
        """Piecewise-constant estimate of the lumped disturbance acceleration (m/s^2, W), shape (3,)."""
        return self._state[S_SIG : S_SIG + 3].copy()

    @property
    def sigma_filtered(self) -> FloatArray:
        """C(s) sigma_hat (m/s^2, W), shape (3,): the estimate the compensation uses."""
        return self._state[S_SIGF : S_SIGF + 3].copy()

    @property
    def compensation(self) -> FloatArray:
        """Acceleration offset u_ad = -C(s) sigma_hat added to the reference (m/s^2, W), shape (3,);
        zeros while disabled."""
        if not self.enabled:
            return np.zeros(3)
        return -self._state[S_SIGF : S_SIGF + 3]

    @property
    def v_hat(self) -> FloatArray:
        """Predictor state (m/s, W), shape (3,)."""
        return self._state[S_VHAT : S_VHAT + 3].copy()

    def command(self, ego: EgoState, ref: Reference) -> Command:
        """Collective thrust (N) and body rates (rad/s, B) at ``ego.t``; see the class docstring.

        Raises ValueError (from the baseline) when no finite command can be made from ``ego``/``ref``.
        """
        ok = self._kernel(ego.t, ego.v_WB, ego.q_WB, ref.a, ref.j, self.params, self._state, self._out)
        if not ok:
            _init_state(self._state)
            return self.base.command(ego, ref)
        if self.enabled:
            aj = self._out.copy()
            aj.flags.writeable = False  # its views a, j are read-only and nobody holds a writable handle
            r = _new(Reference)  # Reference.trusted without its checks and copies
            _setattr(r, "t", ref.t)
            _setattr(r, "p", ref.p)
            _setattr(r, "v", ref.v)
            _setattr(r, "a", aj[0:3])
            _setattr(r, "j", aj[3:6])
            _setattr(r, "yaw", ref.yaw)
            _setattr(r, "yaw_rate", ref.yaw_rate)
            ref = r
        try:
            cmd = self.base.command(ego, ref)
        except ValueError:
            _init_state(self._state)  # the thrust of this call is unknown: the predictor cannot go on
            raise
        self._state[S_THRUST] = cmd.thrust_N
        return cmd


def faessler2017_l1(airframe: Airframe, **options: Any) -> L1AugmentedController:
    """Registry factory: ``HighLevelController`` + L1. Options named like ``L1Config`` fields go to the
    L1 configuration, the others to ``HighLevelGains``."""
    l1_names = {f.name for f in fields(L1Config)}
    l1_opts = {k: v for k, v in options.items() if k in l1_names}
    gain_opts = {k: v for k, v in options.items() if k not in l1_names}
    gain_opts.setdefault("tau_tilt", tilt_time_constant_s(airframe))
    base = HighLevelController(airframe, HighLevelGains(**gain_opts))
    return L1AugmentedController(base, L1Config(**l1_opts))
