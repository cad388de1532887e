"""Which PX4 airframe flies a scenario's airframe, and how PX4's motor outputs drive alight's rotors.

PX4 SITL with an external simulator (``simulator_mavlink``) starts the airframe ``10016_none_iris``
(``PX4_SIM_MODEL=none_iris``): a quadrotor X in PX4's standard numbering (facts from PX4 v1.16.0's
airframe file and control-allocation parameters, ``../shared/references/px4_simulator_interface.md``
section 5)::

    output  PX4 motor   where (x forward, y right)   spin seen from above
      0     Motor 1     front right                  counter-clockwise
      1     Motor 2     rear left                    counter-clockwise
      2     Motor 3     front left                   clockwise
      3     Motor 4     rear right                   clockwise

alight's rotor order is front-left, rear-left, rear-right, front-right (FLU), and its ``f450`` has the
front-left rotor spinning counter-clockwise: the mirror image of PX4's propeller directions. A real F450
flown with PX4 is built the way PX4's numbering says, so the simulated vehicle takes PX4's spins; its
mass, inertia, arm length, motors and drag stay the scenario's airframe's. PX4 is told the airframe's
geometry and hover thrust through parameters set at boot (``PX4_PARAM_<NAME>`` environment variables),
so its control allocation matches the vehicle it flies:

- ``CA_ROTORi_PX`` / ``CA_ROTORi_PY``: the rotor positions in FRD (m), from the airframe's arm length;
- ``CA_ROTORi_KM``: +-the airframe's torque coefficient (m; + for a counter-clockwise rotor);
- ``MPC_THR_HOVER``: 1 / thrust-to-weight (the command that holds the weight with linear thrust);
- ``IMU_INTEG_RATE`` 200 and ``IMU_GYRO_RATEMAX`` 200: alight's IMU ticks at 200 Hz (PX4's default
  expects 250 Hz, the rate PX4's clock would advance at otherwise).

A PX4 output ``u`` in [0, 1] commands ``u`` times the rotor's largest thrust (PX4's default
``THR_MDL_FAC`` 0: thrust linear in the command). Only airframes listed in :data:`PX4_AIRFRAMES` fly
with PX4; any other is refused in one line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from alight.airframe import Airframe
from alight.errors import ConfigError
from alight.types import FloatArray

PX4_ROTOR_QUADRANTS_FRD = ((1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0))
"""The sign of (x, y) in FRD of PX4's Motor 1..4 on a quadrotor X (front right, rear left, front left,
rear right)."""
PX4_ROTOR_SPIN = (1.0, 1.0, -1.0, -1.0)
"""PX4's Motor 1..4 spin, +1 counter-clockwise seen from above (``CA_ROTORi_KM`` > 0)."""


@dataclass(frozen=True)
class Px4Airframe:
    """The PX4 airframe a scenario's airframe flies as: the model name PX4 SITL starts
    (``PX4_SIM_MODEL``) and its ``SYS_AUTOSTART`` number."""

    model: str
    sys_autostart: int


PX4_AIRFRAMES: dict[str, Px4Airframe] = {"f450": Px4Airframe("none_iris", 10016)}
"""Scenario airframe -> PX4 SITL airframe. The F450 is a quadrotor X like the Iris; the Iris's geometry
and hover thrust are replaced by the F450's through :func:`px4_parameters`."""


def px4_airframe_for(name: str) -> Px4Airframe:
    """The PX4 airframe for the scenario's ``airframe:`` ``name``; ConfigError in one line otherwise."""
    found = PX4_AIRFRAMES.get(name)
    if found is None:
        known = ", ".join(f"{k} (PX4 {v.model}, {v.sys_autostart})" for k, v in PX4_AIRFRAMES.items())
        raise ConfigError(f"px4: airframe {name!r} has no PX4 airframe to fly it; known: {known}")
    return found


def px4_to_alight_rotor(airframe: Airframe) -> np.ndarray:
    """For each PX4 output 0..3, the index of alight's rotor at the same place (by its quadrant in FRD),
    shape (4,). A rotor layout that is not a quadrotor X with one rotor per quadrant is refused."""
    p = airframe.rotor_positions_B
    x_frd, y_frd = p[:, 0], -p[:, 1]  # FLU -> FRD
    out = np.empty(4, dtype=np.int64)
    for i, (sx, sy) in enumerate(PX4_ROTOR_QUADRANTS_FRD):
        hits = np.flatnonzero((np.sign(x_frd) == sx) & (np.sign(y_frd) == sy))
        if hits.size != 1:
            raise ConfigError("px4: the airframe is not a quadrotor X with one rotor in each quadrant")
        out[i] = hits[0]
    return out


def px4_spins_alight_order(airframe: Airframe) -> FloatArray:
    """The spin of each of alight's rotors (+1 counter-clockwise) when built as PX4 numbers them, (4,)."""
    spin = np.empty(4)
    spin[px4_to_alight_rotor(airframe)] = PX4_ROTOR_SPIN
    return spin


def motor_commands_N(controls: FloatArray, airframe: Airframe, to_alight: np.ndarray) -> FloatArray:
    """alight's rotor thrust commands (N, alight's order) from HIL_ACTUATOR_CONTROLS ``controls`` (its
    first four entries, PX4's motor outputs in [0, 1]; NaN or out of range clipped to [0, 1])."""
    u = np.nan_to_num(np.asarray(controls[:4], dtype=np.float64), nan=0.0, posinf=1.0, neginf=0.0)
    f = np.empty(4)
    f[to_alight] = np.clip(u, 0.0, 1.0) * airframe.motor_thrust_max_N
    return f


def px4_parameters(airframe: Airframe, *, takeoff_altitude_m: float | None = None) -> dict[str, float]:
    """The PX4 parameters that tell PX4's allocation and hover thrust what ``airframe`` is (module
    docstring), by name; with ``takeoff_altitude_m``, PX4's own take-off climbs to it (``MIS_TAKEOFF_ALT``,
    m above home; PX4's default is 2.5)."""
    to_alight = px4_to_alight_rotor(airframe)
    p = airframe.rotor_positions_B
    params: dict[str, float] = {}
    for i in range(4):
        j = to_alight[i]
        params[f"CA_ROTOR{i}_PX"] = round(float(p[j, 0]), 4)
        params[f"CA_ROTOR{i}_PY"] = round(float(-p[j, 1]), 4)
        params[f"CA_ROTOR{i}_KM"] = PX4_ROTOR_SPIN[i] * airframe.torque_coefficient
    params["MPC_THR_HOVER"] = round(1.0 / airframe.thrust_to_weight, 3)
    params["IMU_INTEG_RATE"] = 200
    params["IMU_GYRO_RATEMAX"] = 200
    if takeoff_altitude_m is not None:
        params["MIS_TAKEOFF_ALT"] = round(float(takeoff_altitude_m), 2)
    return params


def px4_environment(airframe: Airframe, *, takeoff_altitude_m: float | None = None) -> dict[str, str]:
    """The environment variables that start PX4 SITL as ``airframe`` with an external simulator."""
    px4 = PX4_AIRFRAMES[airframe_name_checked(airframe)]
    env = {"PX4_SIM_MODEL": px4.model}
    for name, value in px4_parameters(airframe, takeoff_altitude_m=takeoff_altitude_m).items():
        env[f"PX4_PARAM_{name}"] = f"{value:g}" if isinstance(value, float) else str(value)
    return env


def airframe_name_checked(airframe: Airframe) -> str:
    """The name under which ``airframe`` is in :data:`PX4_AIRFRAMES`: the packaged airframe whose
    numbers it has (a scenario names its airframe; the Airframe object itself carries no name)."""
    from alight.airframes import load_airframe

    for name in PX4_AIRFRAMES:
        if load_airframe(name) == airframe:
            return name
    raise ConfigError(
        f"px4: this airframe (mass {airframe.mass:g} kg, arm {airframe.arm_length:g} m) is not one PX4 flies;"
        f" known: {', '.join(PX4_AIRFRAMES)}"
    )


def hover_command(airframe: Airframe) -> float:
    """The PX4 output that holds the airframe's weight on four rotors (linear thrust)."""
    return airframe.weight_N / (4.0 * airframe.motor_thrust_max_N) if airframe.weight_N > 0 else math.nan
