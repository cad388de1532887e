"""Vehicle parameters shared by the simulator and the controller.

The default airframe is the one of paper 000 (Falanga et al. 2017, Sec. III-C): a DJI F450 frame,
1.0 kg all up, thrust-to-weight ratio 1.85. The paper gives no inertia or motor constants, so:

- geometry: F450 motor-to-motor diagonal 450 mm, hence arm length 0.225 m, X configuration;
- inertia: T. Luukkonen, "Modelling and control of quadcopter", Aalto University 2011, Table 1, identified
  on an F450-class frame of 0.468 kg (Ixx = Iyy = 4.856e-3, Izz = 8.801e-3 kg m^2), scaled by the mass ratio
  1.0 / 0.468 (same geometry, mass distributed alike): Ixx = Iyy = 0.01038, Izz = 0.01881 kg m^2;
- motors: the RotorS simulator's multirotor motor model (Furrer et al., "RotorS - A modular Gazebo MAV
  simulator framework", 2016): first-order thrust response with time constants 0.0125 s spinning up and
  0.025 s spinning down, drag torque = 0.016 m x thrust;
- rotor drag: linear in the body-frame airspeed, mass-normalised coefficients d_x = d_y = 0.3, d_z = 0.05
  (1/s), of the order that Faessler, Franchi, Scaramuzza identified ("Differential flatness of quadrotor
  dynamics subject to rotor drag", RA-L 2018) for a vehicle of this class;
- body drag area: 0.09 m^2, the area paper 004 (Sec. IV-C) lets the wind push on.

The same numbers, each with its unit and source, are the packaged airframe ``f450``
(``alight/airframes/f450.yaml``); ``alight.airframes.load_airframe`` reads those files.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from alight.errors import ConfigError
from alight.types import GRAVITY_MPS2, FloatArray


@dataclass(frozen=True, kw_only=True)
class Airframe:
    """A quadrotor in X configuration. Rotor order: front-left, rear-left, rear-right, front-right
    (counter-clockwise seen from above, starting front-left); rotors 0 and 2 spin counter-clockwise."""

    mass: float = 1.0
    """Mass (kg)."""
    inertia_diag: tuple[float, float, float] = (0.01038, 0.01038, 0.01881)
    """Principal moments of inertia about the FLU body axes (kg m^2)."""
    arm_length: float = 0.225
    """Distance from the centre to each rotor (m)."""
    thrust_to_weight: float = 1.85
    """Maximum total thrust over weight."""
    motor_thrust_min_N: float = 0.0
    """Lowest thrust a spinning rotor gives (N)."""
    motor_tau_up: float = 0.0125
    """First-order time constant when the thrust rises (s)."""
    motor_tau_down: float = 0.025
    """First-order time constant when the thrust falls (s)."""
    torque_coefficient: float = 0.016
    """Rotor drag torque per unit thrust (m)."""
    rotor_drag: tuple[float, float, float] = (0.3, 0.3, 0.05)
    """Mass-normalised linear rotor-drag coefficients along the body axes (1/s)."""
    gear_height: float = 0.10
    """Height of the body origin above the landing-gear feet (m)."""
    gear_half_width: float = 0.20
    """Half the footprint width of the landing gear (m)."""
    max_body_rate: float = 6.0
    """Largest body rate the planner may ask for (rad/s)."""
    max_tilt_rad: float = math.radians(45.0)
    """Largest tilt of the thrust from the vertical that the controller commands (rad), in (0, pi/2);
    ``HighLevelGains.max_tilt`` overrides it."""
    body_drag_area_m2: float = 0.09
    """Area the air pushes on, for the bluff-body drag ``1/2 rho A |v_rel| v_rel`` of the wind models
    (m^2)."""

    # Derived from the fields above: left out of ==, which would otherwise compare arrays elementwise.
    rotor_positions_B: FloatArray = field(init=False, repr=False, compare=False)
    """Rotor positions in B (m), shape (4, 3)."""
    rotor_spin: FloatArray = field(init=False, repr=False, compare=False)
    """+1 for counter-clockwise rotors (their drag torque pushes the body clockwise, -z), shape (4,)."""

    def __post_init__(self) -> None:
        if self.mass <= 0 or min(self.inertia_diag) <= 0 or self.arm_length <= 0:
            raise ValueError("mass, inertia and arm length must be positive")
        if self.thrust_to_weight <= 1.0:
            raise ValueError(f"thrust_to_weight must exceed 1 to fly, got {self.thrust_to_weight}")
        if not 0.0 < self.max_tilt_rad < math.pi / 2:
            raise ValueError(f"max_tilt_rad must be in (0, pi/2), got {self.max_tilt_rad}")
        if not self.body_drag_area_m2 >= 0.0:
            raise ValueError(f"body_drag_area_m2 must be >= 0, got {self.body_drag_area_m2}")
        d = self.arm_length / math.sqrt(2.0)
        pos = np.array([[d, d, 0.0], [-d, d, 0.0], [-d, -d, 0.0], [d, -d, 0.0]])
        pos.setflags(write=False)
        spin = np.array([1.0, -1.0, 1.0, -1.0])
        spin.setflags(write=False)
        object.__setattr__(self, "rotor_positions_B", pos)
        object.__setattr__(self, "rotor_spin", spin)

    @property
    def weight_N(self) -> float:
        return self.mass * GRAVITY_MPS2

    @property
    def motor_thrust_max_N(self) -> float:
        """Largest thrust of one rotor (N)."""
        return self.thrust_to_weight * self.weight_N / 4.0

    @property
    def feet_B(self) -> tuple[float, float, float]:
        """Where the downward sensors sit, in B (m): at the landing-gear feet under the body origin (the
        range finder and an optical-flow module measure from there)."""
        return (0.0, 0.0, -self.gear_height)

    def downward_sensor_B(
        self, position_B_m: tuple[float, float, float] | None, key: str
    ) -> tuple[float, float, float]:
        """Where a downward sensor sits in B (m): ``position_B_m`` as configured, or :attr:`feet_B` when
        None. A position below the feet is refused (``key`` names the setting): the sensor would meet the
        deck before the landing gear does."""
        if position_B_m is None:
            return self.feet_B
        x, y, z = (float(c) for c in position_B_m)
        if z < -self.gear_height - 1e-9:
            raise ConfigError(
                f"{key}: z = {z:g} m puts the sensor {-self.gear_height - z:.3g} m below the landing-gear "
                f"feet (gear height {self.gear_height:g} m)"
            )
        return (x, y, z)

    @property
    def inertia(self) -> FloatArray:
        return np.diag(self.inertia_diag)

    @property
    def allocation(self) -> FloatArray:
        """Matrix A with [T, tau_x, tau_y, tau_z] = A @ f for the rotor thrusts f (N), shape (4, 4).

        Roll torque is y_i f_i, pitch torque -x_i f_i, yaw torque -spin_i * torque_coefficient * f_i
        (a counter-clockwise rotor's drag turns the body clockwise).
        """
        p = self.rotor_positions_B
        return np.vstack(
            [
                np.ones(4),
                p[:, 1],
                -p[:, 0],
                -self.rotor_spin * self.torque_coefficient,
            ]
        )

    @property
    def collective_accel_limits(self) -> tuple[float, float]:
        """Mass-normalised collective thrust limits (m/s^2) that leave margin for attitude control.

        The planner keeps 20 % of the range for the feedback and the attitude loop, so a feasible
        trajectory stays trackable with saturated-motor margins.
        """
        f_max = 4 * self.motor_thrust_max_N / self.mass
        f_min = 4 * self.motor_thrust_min_N / self.mass
        margin = 0.2 * (f_max - f_min)
        return f_min + 0.5 * margin + 1.0, f_max - 0.5 * margin


DEFAULT_AIRFRAME = Airframe()
