"""Electrical energy of flight from the rotor thrusts (momentum theory).

The ideal induced power of a rotor of disc area A giving thrust T in hover is T^1.5 / sqrt(2 rho A)
(Leishman, "Principles of Helicopter Aerodynamics", 2nd ed., eq. 2.19). Dividing by a figure of merit
(profile losses) and by the motor + ESC efficiency gives the electrical power drawn from the battery.
The defaults are for the 8-inch propellers of paper 000's vehicle (Sec. III-C): disc radius 0.1016 m,
figure of merit 0.6 and motor+ESC efficiency 0.75, typical of small brushless propulsion. A 1 kg
vehicle then draws about 120 W in hover, in line with measured values for F450-class quadrotors.
The model ignores the forward-flight reduction of induced power, so it is slightly conservative at speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True, kw_only=True)
class RotorPowerModel:
    rotor_radius_m: float = 0.1016
    air_density: float = 1.2
    figure_of_merit: float = 0.6
    drive_efficiency: float = 0.75

    def electrical_power_W(self, thrust_N: NDArray[np.float64]) -> NDArray[np.float64]:
        """Electrical power (W) of each rotor for the thrusts given (N), any shape."""
        area = math.pi * self.rotor_radius_m**2
        t = np.clip(np.asarray(thrust_N, dtype=np.float64), 0.0, None)
        ideal = t**1.5 / math.sqrt(2.0 * self.air_density * area)
        return ideal / (self.figure_of_merit * self.drive_efficiency)


def flight_energy_J(
    t: NDArray[np.float64], motor_thrust_N: NDArray[np.float64], model: RotorPowerModel | None = None
) -> float:
    """Energy (J) drawn by all rotors over the samples ``t`` (n,) of the thrusts ``motor_thrust_N`` (n, 4)."""
    if len(t) < 2:
        return 0.0
    power = (model or RotorPowerModel()).electrical_power_W(motor_thrust_N).sum(axis=1)
    return float(np.trapezoid(power, t))
