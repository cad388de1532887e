"""The vessel's linear response to each regular wave: a complex amplitude per axis and component.

Every axis j is ``x_j(t) = Re{ sum_i C_ji e^{j w_e,i t} }`` with ``C_ji = A_i X_j(w_i, mu) H_j(j w_e,i)``,
``A_i = a_i e^{j eps_i}`` the wave at the centre of motion, ``X_j`` an excitation that depends on the
wave and the hull's footprint, and ``H_j`` a resonance at the encounter frequency. The model is the
reference sheet's (sec. 3.2, [MODEL]): a cheap stand-in for hull RAOs, with the same interface.

Body axes FLU; roll positive lifts the port (left, +y) side, pitch positive is bow down, yaw positive
turns the bow to port. With the wave's body-axis wave numbers ``kx = k cos mu``, ``ky = k sin mu``, hull
length L, beam B, draft d, ``sinc(u) = sin(u)/u`` and ``S3(u) = 3 (sin u - u cos u) / u^3`` (the
least-squares slope of ``e^{-j k x}`` over ``[-h, h]`` divided by ``-j k``, u = k h):

- heave: ``X = fL fB sm`` with ``fL = sinc(kx L/2)``, ``fB = sinc(ky B/2)`` (the elevation averaged over
  the footprint) and ``sm = exp(-k d)`` (the pressure's decay to the draft);
- roll: ``X = -j ky S3(ky B/2) fL sm`` (the surface's least-squares slope across the hull: the deck
  follows it, port up where the surface rises to port);
- pitch: ``X = +j kx S3(kx L/2) fB sm`` (minus the slope along the hull: bow down where it falls ahead);
- surge, sway: ``X = -j cos mu fL fB``, ``-j sin mu fL fB`` (the surface's orbital displacement along
  the body axes, in quadrature with the elevation; no resonance);
- yaw: ``X = yaw_fraction (-j kx S3(kx L/2)) (-j sin mu fB)`` (the least-squares slope of the sway
  displacement along the hull, the share the heading control leaves; no resonance).

Heave, roll and pitch pass a unit-gain second-order resonance ``H(j w) = wn^2 / (wn^2 - w^2 + 2 j z wn w)``
at ``wn = 2 pi / T_n``: gain 1 (heave) or the wave slope (roll, pitch) in long waves, ``1/(2 z)`` times
the excitation at resonance, falling as ``(wn / w_e)^2`` above it. ``H(-j w) = conj(H(j w))``, so a
negative encounter frequency (overtaking following seas) is handled by keeping its sign.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from alight.sim.sea.vessel import Vessel
from alight.sim.sea.waves import WaveComponents, encounter_frequency

__all__ = ["AXES", "ComplexArray", "resonance", "response_coefficients", "sinc", "slope_factor"]

ComplexArray = NDArray[np.complex128]

AXES: tuple[str, ...] = ("surge", "sway", "heave", "roll", "pitch", "yaw")
"""Order of the rows of :func:`response_coefficients` (m, m, m, rad, rad, rad)."""


def sinc(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sin(u) / u``, 1 at 0."""
    out: NDArray[np.float64] = np.sinc(np.asarray(u, dtype=np.float64) / math.pi)
    return out


def slope_factor(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """``3 (sin u - u cos u) / u^3``, 1 at 0 (its Taylor series below |u| = 1e-3, where the closed form
    loses its digits)."""
    u = np.asarray(u, dtype=np.float64)
    small = np.abs(u) < 1e-3
    us = np.where(small, 1.0, u)
    out: NDArray[np.float64] = np.where(
        small, 1.0 - u**2 / 10.0, 3.0 * (np.sin(us) - us * np.cos(us)) / us**3
    )
    return out


def resonance(w_e: NDArray[np.float64], period_s: float, damping: float) -> ComplexArray:
    """Unit-gain second-order resonance at ``s = j w_e`` (``w_e`` signed, rad/s)."""
    wn = 2.0 * math.pi / period_s
    den = (wn**2 - w_e**2) + 2j * damping * wn * w_e
    out: ComplexArray = np.asarray(wn**2 / den, dtype=np.complex128)
    return out


def response_coefficients(
    waves: WaveComponents, vessel: Vessel, speed_mps: float, mu_rad: float
) -> tuple[ComplexArray, NDArray[np.float64]]:
    """``(C, w_e)``: the complex amplitudes ``C``, shape (6, N), rows in :data:`AXES` order, and the
    encounter frequencies ``w_e`` (rad/s), shape (N,), of a vessel at ``speed_mps`` meeting the waves at
    ``mu_rad`` (the waves' direction of travel relative to the heading)."""
    k = waves.k
    w_e = encounter_frequency(waves.w, speed_mps, mu_rad)
    amp = waves.a * np.exp(1j * waves.eps)
    c, s = math.cos(mu_rad), math.sin(mu_rad)
    kx, ky = k * c, k * s
    f_l, f_b = sinc(kx * vessel.length_m / 2), sinc(ky * vessel.beam_m / 2)
    smith = np.exp(-k * vessel.draft_m)
    s3_l = slope_factor(kx * vessel.length_m / 2)
    out = np.empty((6, k.shape[0]), dtype=np.complex128)
    out[0] = -1j * c * f_l * f_b * amp
    out[1] = -1j * s * f_l * f_b * amp
    out[2] = f_l * f_b * smith * amp * resonance(w_e, vessel.heave_period_s, vessel.heave_damping)
    roll_x = -1j * ky * slope_factor(ky * vessel.beam_m / 2) * f_l * smith
    out[3] = roll_x * amp * resonance(w_e, vessel.roll_period_s, vessel.roll_damping)
    pitch_x = 1j * kx * s3_l * f_b * smith
    out[4] = pitch_x * amp * resonance(w_e, vessel.pitch_period_s, vessel.pitch_damping)
    out[5] = vessel.yaw_fraction * (-1j * kx * s3_l) * (-1j * s * f_b) * amp
    return out, w_e
