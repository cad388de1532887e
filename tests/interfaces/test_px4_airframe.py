"""The scenario airframe <-> PX4 airframe mapping: motor order by geometry, PX4's propeller directions,
the allocation parameters PX4 is told, and the one-line refusal of an airframe PX4 does not fly."""

from __future__ import annotations

import numpy as np
import pytest

from alight.airframes import load_airframe
from alight.errors import ConfigError
from alight.interfaces.px4_airframe import (
    PX4_ROTOR_SPIN,
    hover_command,
    motor_commands_N,
    px4_airframe_for,
    px4_environment,
    px4_parameters,
    px4_spins_alight_order,
    px4_to_alight_rotor,
)

F450 = load_airframe("f450")


def test_f450_flies_as_none_iris_and_others_are_refused_in_one_line() -> None:
    px4 = px4_airframe_for("f450")
    assert (px4.model, px4.sys_autostart) == ("none_iris", 10016)
    with pytest.raises(ConfigError) as err:
        px4_airframe_for("matrice100")
    assert "\n" not in str(err.value) and "matrice100" in str(err.value) and "f450" in str(err.value)
    with pytest.raises(ConfigError):
        px4_environment(load_airframe("matrice100"))


def test_px4_motor_order_maps_to_alight_rotors_by_position() -> None:
    # PX4: Motor 1 front right, 2 rear left, 3 front left, 4 rear right; alight: FL, RL, RR, FR
    to_alight = px4_to_alight_rotor(F450)
    assert to_alight.tolist() == [3, 1, 0, 2]
    p = F450.rotor_positions_B  # FLU
    x_frd, y_frd = p[to_alight, 0], -p[to_alight, 1]
    assert np.all(np.sign(x_frd) == [1, -1, 1, -1]) and np.all(np.sign(y_frd) == [1, -1, -1, 1])


def test_spins_are_px4s_and_torques_follow_px4s_convention() -> None:
    """Each PX4 output alone, through alight's allocation with the PX4 spins, gives the body torque PX4's
    allocation expects of that rotor (FRD): roll -y T, pitch x T, yaw KM T (KM > 0: counter-clockwise)."""
    spin = px4_spins_alight_order(F450)
    to_alight = px4_to_alight_rotor(F450)
    assert spin[to_alight].tolist() == list(PX4_ROTOR_SPIN)
    params = px4_parameters(F450)
    p, c = F450.rotor_positions_B, F450.torque_coefficient
    for i in range(4):
        controls = np.zeros(16)
        controls[i] = 0.5
        f = motor_commands_N(controls, F450, to_alight)
        assert np.count_nonzero(f) == 1 and f[to_alight[i]] == pytest.approx(0.5 * F450.motor_thrust_max_N)
        tau_flu = np.array([p[:, 1] @ f, -p[:, 0] @ f, -(spin * c) @ f])  # the simulator's torque, FLU
        tau_frd = tau_flu * [1, -1, -1]
        px, py, km = (params[f"CA_ROTOR{i}_{k}"] for k in ("PX", "PY", "KM"))
        t = f.sum()
        assert tau_frd == pytest.approx([-py * t, px * t, km * t], abs=1e-3)


def test_outputs_are_clipped_and_nan_is_no_thrust() -> None:
    controls = np.array([np.nan, 1.7, -0.3, np.inf] + [0.0] * 12)
    f = motor_commands_N(controls, F450, px4_to_alight_rotor(F450))
    f_max = F450.motor_thrust_max_N
    # PX4 outputs 0..3 are alight rotors 3, 1, 0, 2
    assert f.tolist() == pytest.approx([0.0, f_max, f_max, 0.0])


def test_parameters_and_environment() -> None:
    params = px4_parameters(F450)
    assert params["MPC_THR_HOVER"] == pytest.approx(1 / 1.85, abs=1e-3)
    assert hover_command(F450) == pytest.approx(params["MPC_THR_HOVER"], abs=1e-3)
    d = F450.arm_length / np.sqrt(2)
    assert abs(params["CA_ROTOR0_PX"]) == pytest.approx(d, abs=1e-4)
    env = px4_environment(F450)
    assert env["PX4_SIM_MODEL"] == "none_iris"
    assert env["PX4_PARAM_IMU_INTEG_RATE"] == "200"
    assert float(env["PX4_PARAM_CA_ROTOR2_KM"]) == pytest.approx(-F450.torque_coefficient)
