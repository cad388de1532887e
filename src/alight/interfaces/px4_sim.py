"""alight's world as PX4's simulator: the ``simulator_mavlink`` interface that jMAVSim and Gazebo-classic use.

PX4 SITL connects as a TCP client to port ``4560 + instance``; this module listens there and is PX4's
whole world: the quadrotor, the moving platform with its deck contact, the wind and the camera of a
scenario (:class:`alight.sim.world.World`). Facts from PX4 v1.16.0, as the fact sheet
``../shared/references/px4_simulator_interface.md`` records them (nothing of PX4's code is used):

- **Lockstep.** Each HIL_SENSOR sets PX4's clock to its ``time_usec`` (sim time, µs); PX4 runs one full
  cycle and answers with one HIL_ACTUATOR_CONTROLS stamped with the same time. Once the first answer has
  arrived, the simulator waits for the answer to each step before the next: PX4's clock advances only
  with the simulator's. Before the first answer (PX4 still starting its modules) the steps are paced at
  wall-clock rate. The world ticks at 200 Hz (``TICK_DT``), so PX4 gets its IMU at 200 Hz.
- **The mission starts when PX4 is armed.** PX4 boots, aligns its estimator and is armed by the
  companion while the world stands still: the vehicle at rest at its start (its accelerometer feels the
  ground's contact force, with the IMU's noise from a child of the seed of its own), the platform at its
  position of t = 0, PX4's clock advancing from the first step. The first HIL_ACTUATOR_CONTROLS that says
  armed starts the world: the scenario's t = 0 is PX4's time then (:attr:`Px4Simulator.t0_us`), so
  neither PX4's start-up nor the companion's wait for "ready to arm" counts against ``duration_s``, and
  the platform does not drive off while PX4 boots. Every stamp the simulator sends (sensors, camera
  frames, the ground-truth log) is PX4's time; the verdict's times are the mission's.
- **Sensors out.** HIL_SENSOR every tick: accelerometer (specific force, FRD, m/s^2: the IMU model's,
  which feels the feet's contact force as a real accelerometer does), gyroscope (FRD, rad/s), the Earth's
  magnetic field at PX4's default home in the body frame (gauss), barometric pressure (hPa, ISA) and
  temperature; HIL_GPS at 10 Hz (degE7, mm AMSL, cm/s NED); DISTANCE_SENSOR at 50 Hz (cm, facing down)
  from the scenario's range finder; HIL_STATE_QUATERNION at 50 Hz (PX4's ground-truth topics only).
- **Motors in.** HIL_ACTUATOR_CONTROLS' first four outputs drive alight's rotors through the airframe
  mapping of :mod:`alight.interfaces.px4_airframe`; disarmed, PX4 sends zeros and the rotors stop.
- **The companion.** The pipeline flies through the bridge (``alight bridge``) connected to PX4's
  offboard link; it gets the scenario, the camera frames (stamped with sim time = PX4's clock), and at
  the end the verdict and the ground-truth log on the camera stream, as from ``alight sitl``.

A PX4 that does not connect, stops answering (a crash, a hang) or closes the link ends the mission as
``error`` with the reason, after a bounded wait; nothing here waits for ever.
"""

from __future__ import annotations

import json
import math
import os
import select
import socket
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

os.environ.setdefault("MAVLINK20", "1")  # HIL_SENSOR's ``id`` and HIL_GPS's ``id`` are MAVLink 2 fields

from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

import alight  # noqa: E402
from alight.airframe import Airframe  # noqa: E402
from alight.energy import flight_energy_J  # noqa: E402
from alight.errors import ConfigError, InputError  # noqa: E402
from alight.evaluation.runner import world_for_scenario  # noqa: E402
from alight.interfaces import frames  # noqa: E402
from alight.interfaces.camera_source import KIND_SCENARIO, FrameServer, encode_message  # noqa: E402
from alight.interfaces.px4_airframe import (  # noqa: E402
    motor_commands_N,
    px4_spins_alight_order,
    px4_to_alight_rotor,
)
from alight.interfaces.sitl import distance_sensor_fields  # noqa: E402
from alight.interfaces.sitl_protocol import Geodetic  # noqa: E402
from alight.scenario import Scenario  # noqa: E402
from alight.sim.physics import IN_DECK, IN_F_EXT, IN_V_WIND  # noqa: E402
from alight.sim.quadrotor import (  # noqa: E402
    IX_F,
    IX_Q,
    IX_V,
    IX_W,
    N_DK,
    PAR_SPIN,
    SL_P,
    SL_Q,
    SL_V,
    SL_W,
    contact_wrench,
    deck_at,
    step_contact,
)
from alight.sim.sensors import imu_sample_kernel  # noqa: E402
from alight.sim.world import PHYSICS_DT, TICK_DT, Shot, World  # noqa: E402
from alight.types import FloatArray, Outcome, quat_to_rotmat  # noqa: E402

SIM_PORT_BASE = 4560
"""PX4 connects to TCP ``SIM_PORT_BASE + instance``."""
# The Earth's field at PX4 SITL's default home (47.397742 N, 8.545594 E), from PX4's world magnetic model
# table as the fact sheet gives it: declination 3.41 deg, inclination 63.16 deg, 0.4824 gauss.
MAG_DECLINATION_DEG, MAG_INCLINATION_DEG, MAG_STRENGTH_GAUSS = 3.41, 63.16, 0.4824
HIL_SENSOR_FIELDS = 0x1BFF
"""HIL_SENSOR ``fields_updated``: accelerometer, gyroscope, magnetometer and barometer every tick."""
GPS_EVERY, RANGE_EVERY, TRUTH_EVERY = 20, 4, 4  # ticks of 5 ms: 10 Hz, 50 Hz, 50 Hz
MAG_NOISE_GAUSS, BARO_NOISE_HPA, GPS_NOISE_M, GPS_VEL_NOISE_MPS = 0.001, 0.005, 0.02, 0.02
SEED_PX4 = 11
"""The child of the scenario's seed (after the world's :data:`~alight.sim.world.SEED_CHILDREN`) that
this simulator's own sensors (magnetometer, barometer, GNSS) draw from; the next child is the IMU's noise
while the world waits for PX4 to be armed."""
TICK_US = int(round(TICK_DT * 1e6))
"""One world tick in PX4's microseconds (5,000)."""


def magnetic_field_ned_gauss() -> FloatArray:
    """The Earth's magnetic field at PX4's default home in NED (gauss)."""
    d, i = math.radians(MAG_DECLINATION_DEG), math.radians(MAG_INCLINATION_DEG)
    h = MAG_STRENGTH_GAUSS * math.cos(i)
    return np.array([h * math.cos(d), h * math.sin(d), MAG_STRENGTH_GAUSS * math.sin(i)])


def pressure_hPa(altitude_amsl_m: float) -> float:
    """Static pressure of the ISA troposphere at an altitude above mean sea level (hPa)."""
    return float(1013.25 * (1.0 - 0.0065 * altitude_amsl_m / 288.15) ** 5.25588)


@njit(cache=True)
def motor_tick(
    x: FloatArray,
    motor_cmd_N: FloatArray,
    inputs: FloatArray,
    sim_params: FloatArray,
    imu_bias: FloatArray,
    imu_noise: FloatArray,
    imu_scale: FloatArray,
    dt: float,
    n: int,
    contact_params: FloatArray,
    counts: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """One IMU period with the rotors commanded directly (PX4's outputs; no alight rate loop): ``n``
    contact-dynamics steps of ``dt``, then the IMU sample (the mean acceleration over the period, so the
    feet's contact force shows in it) and the feet on the deck and the ground into ``counts`` (2,).
    ``inputs``: the world's input vector (wind force and air velocity, the deck at the period's start)."""
    deck = inputs[IN_DECK : IN_DECK + N_DK]
    f_ext = inputs[IN_F_EXT : IN_F_EXT + 3]
    v_wind = inputs[IN_V_WIND : IN_V_WIND + 3]
    y = x.copy()
    for i in range(n):
        y = step_contact(y, motor_cmd_N, f_ext, v_wind, sim_params, dt, deck, i * dt, contact_params)
    a = np.empty(3)
    span = dt * n
    for k in range(3):
        a[k] = (y[IX_V + k] - x[IX_V + k]) / span
    imu = imu_sample_kernel(a, y[IX_Q : IX_Q + 4], y[IX_W : IX_W + 3], imu_bias, imu_noise, imu_scale)
    now = np.empty(N_DK)
    deck_at(deck, span, now)
    f = np.empty(3)
    tq = np.empty(3)
    contact_wrench(y, now, contact_params, f, tq, counts)
    return y, imu


class Px4World(World):
    """The scenario's world with its rotors driven by PX4's motor outputs (:attr:`motor_cmd_N`, alight's
    rotor order, N) instead of alight's rate loop, its propellers spinning as PX4 numbers them
    (:mod:`alight.interfaces.px4_airframe`). Everything else (platform, wind, contact and its judging,
    sensors, camera) is the World's."""

    def __init__(self, world: World) -> None:
        self.__dict__.update(world.__dict__)  # the world as built for the scenario, taken over whole
        self.sim_params = self.sim_params.copy()
        self.sim_params[PAR_SPIN : PAR_SPIN + 4] = px4_spins_alight_order(self.airframe)
        self.to_alight = px4_to_alight_rotor(self.airframe)
        self.motor_cmd_N: FloatArray = np.zeros(4)
        self._counts = np.zeros(2)

    def apply_controls(self, controls: FloatArray, armed: bool) -> None:
        """PX4's HIL_ACTUATOR_CONTROLS outputs from the next tick on (zeros unless ``armed``)."""
        self.motor_cmd_N = motor_commands_N(controls, self.airframe, self.to_alight) if armed else np.zeros(4)
        if armed != self.motors_on:
            self.set_command(0.0, np.zeros(3), armed)  # the World's record of when the motors stopped

    def _physics_batch(self) -> None:
        x, inputs, k = self.x, self.inputs, self.k
        if not self.windless:
            self.f_wind = self.wind.force_W(self.t, x[SL_P], x[SL_V])
            inputs[IN_F_EXT : IN_F_EXT + 3] = self.f_wind
            inputs[IN_V_WIND : IN_V_WIND + 3] = self.wind.air_velocity_W(self.t)
        inputs[IN_DECK : IN_DECK + N_DK] = self._deck_rows[k]
        self.faults.before_imu_batch(k + 1, 1, self.imu)
        bias, noise, scale = self.imu.kernel_inputs_many(1)
        y, imu = motor_tick(
            x, self.motor_cmd_N, inputs, self.sim_params, bias, noise[0], scale, PHYSICS_DT, self.n_sub,
            self.contact_params, self._counts,
        )  # fmt: skip
        self.imu.used(1)
        self._batch_xs, self._batch_imu = y[None, :], imu[None, :]
        self._batch_touch = [[float(self._counts[0]), float(self._counts[1])]]
        self._batch_i, self._batch_n = 0, 1

    def warm_up(self) -> None:
        super().warm_up()
        bias, noise, scale = self.imu.kernel_inputs_many(1)
        motor_tick(
            self.x.copy(), np.zeros(4), self.inputs.copy(), self.sim_params, bias.copy(), noise[0].copy(),
            scale.copy(), PHYSICS_DT, self.n_sub, self.contact_params, np.zeros(2),
        )  # fmt: skip


@dataclass(frozen=True)
class Px4SimConfig:
    """How the simulator meets PX4 and the companion."""

    instance: int = 0
    """PX4's instance number (``px4 -i``): PX4 connects to TCP 4560 + instance."""
    host: str = "127.0.0.1"
    camera_port: int = 0
    """The camera stream's TCP port for the companion (0: any free one, :attr:`Px4Simulator.camera_port`)."""
    speed: float = 1.0
    """Simulated seconds per wall second to hold at most (0: as fast as PX4 and the world compute)."""
    connect_timeout_s: float = 60.0
    """PX4 must connect within this (wall s)."""
    companion_timeout_s: float = 300.0
    """The companion must open the camera stream within this (wall s; it warms its kernels up first)."""
    boot_timeout_s: float = 60.0
    """PX4's first HIL_ACTUATOR_CONTROLS must come within this much simulated time (s)."""
    arm_timeout_s: float = 180.0
    """PX4 must be armed (by the companion) within this much of PX4's time (s): the world waits for it
    (module docstring, "The mission starts when PX4 is armed")."""
    lockstep_timeout_s: float = 10.0
    """PX4 must answer each step within this (wall s): beyond it PX4 has crashed or hung."""


@dataclass
class LockstepStats:
    """What the lockstep did: steps sent, answers received, answers waited for too long."""

    steps: int = 0
    actuator_messages: int = 0
    first_actuator_t_s: float | None = None
    wall_s: float = 0.0
    sim_s: float = 0.0
    wait_wall_s: float = 0.0
    events: list[dict[str, Any]] = field(default_factory=list)

    def record(self) -> dict[str, Any]:
        speed = self.sim_s / self.wall_s if self.wall_s > 0 else None
        return {
            "kind": "px4_lockstep", "steps": self.steps, "actuator_messages": self.actuator_messages,
            "first_actuator_t_s": self.first_actuator_t_s, "wall_s": round(self.wall_s, 3),
            "sim_s": round(self.sim_s, 3), "sim_s_per_wall_s": None if speed is None else round(speed, 3),
            "px4_wait_wall_s": round(self.wait_wall_s, 3),
        }  # fmt: skip


class Px4Link:
    """The TCP link PX4 connects to: MAVLink 2 out (pymavlink's encoder), HIL_ACTUATOR_CONTROLS in."""

    def __init__(self, host: str, port: int) -> None:
        self._listen = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listen.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._listen.bind((host, port))
        except OSError as err:
            self._listen.close()
            raise InputError(f"px4 simulator: cannot listen on tcp {host}:{port} ({err.strerror})") from None
        self._listen.listen(1)
        self.port: int = self._listen.getsockname()[1]
        self._sock: socket.socket | None = None
        self._out = bytearray()
        self.mav = mavlink.MAVLink(self, srcSystem=1, srcComponent=mavlink.MAV_COMP_ID_USER1)
        self.mav.robust_parsing = True
        self.closed = False

    def write(self, data: bytes) -> None:
        """pymavlink's output: buffered, sent by :meth:`flush`."""
        self._out += data

    def accept(self, timeout_s: float) -> bool:
        readable, _, _ = select.select([self._listen], [], [], timeout_s)
        if not readable:
            return False
        self._sock, _ = self._listen.accept()
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock.setblocking(False)
        return True

    def flush(self) -> None:
        if self._sock is None or not self._out:
            return
        try:
            self._sock.setblocking(True)
            self._sock.sendall(self._out)
            self._sock.setblocking(False)
        except OSError:
            self.closed = True
        self._out.clear()

    def receive(self, timeout_s: float) -> list[Any]:
        """The messages that arrive within ``timeout_s`` (at least those already queued)."""
        if self._sock is None or self.closed:
            return []
        readable, _, _ = select.select([self._sock], [], [], timeout_s)
        if not readable:
            return []
        try:
            data = self._sock.recv(1 << 16)
        except (BlockingIOError, InterruptedError):
            return []
        except OSError:
            data = b""
        if not data:
            self.closed = True
            return []
        msgs = self.mav.parse_buffer(data) or []
        return [m for m in msgs if m.get_type() != "BAD_DATA"]

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
        self._listen.close()


class Px4Sensors:
    """The messages PX4 reads as its sensors, from the world's truth and its IMU sample (module
    docstring); the magnetometer, barometer and GNSS noise draw from their own child of the seed."""

    def __init__(self, world: World, seed: int) -> None:
        self.world = world
        self.geo = Geodetic()
        self.m_NED = magnetic_field_ned_gauss()
        self.rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(SEED_PX4 + 1)[SEED_PX4])

    def hil_sensor(self, mav: Any, t_us: int, imu_FLU: FloatArray) -> None:
        """HIL_SENSOR: specific force and body rate FRD, magnetic field FRD (gauss), pressure (hPa)."""
        x, rng = self.world.x, self.rng
        f, w = frames.flu_to_frd(imu_FLU[0:3]), frames.flu_to_frd(imu_FLU[3:6])
        R_NED_FRD = frames.rotmat_enu_flu_to_ned_frd(quat_to_rotmat(x[SL_Q]))
        m = R_NED_FRD.T @ self.m_NED + rng.normal(0.0, MAG_NOISE_GAUSS, 3)
        alt = self.geo.alt0_m + float(x[2])
        p = pressure_hPa(alt) + float(rng.normal(0.0, BARO_NOISE_HPA))
        mav.hil_sensor_send(t_us, *f, *w, *m, p, 0.0, alt, 20.0, HIL_SENSOR_FIELDS, 0)

    def hil_gps(self, mav: Any, t_us: int) -> None:
        """HIL_GPS: a 3D fix at the true position and velocity with centimetre noise."""
        x, rng = self.world.x, self.rng
        p = x[SL_P] + rng.normal(0.0, GPS_NOISE_M, 3)
        v = x[SL_V] + rng.normal(0.0, GPS_VEL_NOISE_MPS, 3)
        lat, lon = self.geo.e7(float(p[0]), float(p[1]))
        v_ned = frames.enu_to_ned(v)
        ground = math.hypot(v_ned[0], v_ned[1])
        cog = int(round(math.degrees(math.atan2(v_ned[1], v_ned[0])) % 360.0 * 100.0)) % 36000
        mav.hil_gps_send(
            t_us, 3, lat, lon, int(round((self.geo.alt0_m + p[2]) * 1000.0)), 30, 40,
            int(round(ground * 100.0)), *(int(round(c * 100.0)) for c in v_ned),
            cog if ground > 0.05 else 65535, 12, 0, 0,
        )  # fmt: skip

    def distance_sensor(self, mav: Any, t_ms: int) -> None:
        """DISTANCE_SENSOR facing down: the scenario's range finder as it reports (cm)."""
        w = self.world
        lo, hi, cm, quality = distance_sensor_fields(w.range_m(), w.rangefinder.config)
        covariance_cm2 = min(int(round((w.rangefinder.config.noise_std_m * 100.0) ** 2)), 254)
        mav.distance_sensor_send(t_ms, lo, hi, cm, mavlink.MAV_DISTANCE_SENSOR_LASER, 0,
                                 mavlink.MAV_SENSOR_ROTATION_PITCH_270, covariance_cm2, 0.0, 0.0, [0.0] * 4,
                                 quality)  # fmt: skip

    def ground_truth(self, mav: Any, t_us: int) -> None:
        """HIL_STATE_QUATERNION: PX4 logs it as ground truth (its estimator does not read it)."""
        x = self.world.x
        q = frames.q_WB_to_mavlink(x[SL_Q])
        w = frames.flu_to_frd(x[SL_W])
        lat, lon = self.geo.e7(float(x[0]), float(x[1]))
        v = frames.enu_to_ned(x[SL_V])
        mav.hil_state_quaternion_send(
            t_us, q, *w, lat, lon, int(round((self.geo.alt0_m + x[2]) * 1000.0)),
            *(int(round(c * 100.0)) for c in v), 0, 0, 0, 0, 0,
        )  # fmt: skip


def actuator_reply(msg: Any) -> tuple[int, FloatArray, bool] | None:
    """``(time_usec, controls (16,), armed)`` of a HIL_ACTUATOR_CONTROLS, or None for another message
    or one with no finite controls."""
    if msg.get_type() != "HIL_ACTUATOR_CONTROLS":
        return None
    controls = np.asarray(msg.controls, dtype=np.float64)
    if controls.shape != (16,):
        return None
    return int(msg.time_usec), controls, bool(int(msg.mode) & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


FRAME_HOLD_S = 0.03
"""A frame goes to the companion no sooner than this after its capture (sim s): the companion stamps
time with PX4's telemetry, which reaches it a stream period behind the world, and the bridge refuses a
frame stamped after its clock. Measured with real PX4 on 2 shared cores: the bridge still refused 28 %
of the frames at 0.03 s and 22 % at 0.3 s, so the companion's lag is not the whole cause (docs/px4.md,
open)."""
_TRUTH_KEYS = ("t", "p_WB", "v_WB", "p_WP", "v_WP", "w_WB_B", "f_wind_W", "motor_N")


def check_px4_scenario(scenario: Scenario) -> None:
    """Refuse, in one line, what the world cannot give PX4 and the companion through this interface."""
    if scenario.optical_flow is not None:
        # the world sends no HIL_OPTICAL_FLOW, so the module would fly without reaching anyone
        raise ConfigError("optical_flow: not available with PX4 SITL (no HIL_OPTICAL_FLOW stream yet)")


class Px4Simulator:
    """One mission of ``scenario`` with PX4 SITL as its autopilot (module docstring). Create it (it
    listens at once), start PX4, then :meth:`run`."""

    def __init__(self, scenario: Scenario, config: Px4SimConfig, airframe: Airframe | None = None) -> None:
        self.scenario, self.config = scenario, config
        check_px4_scenario(scenario)
        self.world = Px4World(world_for_scenario(scenario, airframe))
        self.sensors = Px4Sensors(self.world, scenario.seed)
        self.link = Px4Link(config.host, SIM_PORT_BASE + config.instance)
        try:
            self.frames = FrameServer(config.host, config.camera_port)
        except InputError:
            self.link.close()
            raise
        self.frames.hello = encode_message(
            KIND_SCENARIO, json.dumps(scenario.model_dump(mode="json")).encode()
        )
        self.stats = LockstepStats()
        self.armed = False
        self.t0_us: int | None = None
        """PX4's time (µs) at the mission's t = 0: when PX4 was first armed (None before)."""
        self._rest_rng = np.random.default_rng(np.random.SeedSequence(scenario.seed).spawn(SEED_PX4 + 2)[-1])
        self.ack_us = -1
        self._controls: FloatArray = np.zeros(16)
        self._held: list[tuple[float, np.ndarray]] = []
        self.log: dict[str, list[Any]] = {k: [] for k in _TRUTH_KEYS}

    @property
    def camera_port(self) -> int:
        return self.frames.port

    def _event(self, kind: str, **info: Any) -> None:
        self.stats.events.append(
            {"t": round(self.world.t, 3), "t_px4": round(self._px4_s(), 3), "kind": kind, **info}
        )

    @property
    def t_us(self) -> int:
        """PX4's time now (µs): the boot's last step, then the mission's start plus the world's time."""
        if self.t0_us is None:
            return self.stats.steps * TICK_US
        return self.t0_us + int(round(self.world.t * 1e6))

    def _px4_s(self) -> float:
        return self.t_us / 1e6

    def run(self) -> dict[str, Any]:
        """Wait for PX4 and the companion, wait for PX4 to be armed on a world at rest, fly until the
        world decides the end; returns the verdict."""
        w = self.world
        w.warm_up()
        failure = self._wait_for_px4() or self._wait_for_companion()
        wall0 = time.monotonic()
        if failure is None:
            failure = self._boot(wall0)
        while failure is None and not w.done:
            failure = self._step(wall0)
        self.stats.wall_s, self.stats.sim_s = time.monotonic() - wall0, self._px4_s()
        if failure is not None:
            self._event("px4_failure", reason=failure)
            w.end(Outcome.ERROR, failure)
        return self._finish()

    def _wait_for_px4(self) -> str | None:
        port = SIM_PORT_BASE + self.config.instance
        if self.link.accept(self.config.connect_timeout_s):
            self._event("px4_connected", port=port)
            return None
        return (
            f"px4 did not connect to the simulator on tcp {port} within {self.config.connect_timeout_s:g} s"
        )

    def _wait_for_companion(self) -> str | None:
        deadline = time.monotonic() + self.config.companion_timeout_s
        while not self.frames.connected:
            if time.monotonic() > deadline:
                return f"no companion opened the camera stream within {self.config.companion_timeout_s:g} s"
            self.link.receive(0.05)  # PX4's HEARTBEAT and interval request; it waits for sensor data
        self._event("companion_connected")
        return None

    def _boot(self, wall0: float) -> str | None:
        """PX4's start-up on a world at rest, until PX4 is armed (module docstring): the sensors of the
        vehicle standing at its start, PX4's clock advancing a tick at a time, the world's not."""
        w = self.world
        while self.t0_us is None:
            imu = self._imu_at_rest()
            self.stats.steps += 1
            failure = self._send_sensors(self.stats.steps, self.t_us, imu)
            if failure is not None:
                return failure
            self._pace(wall0)
            if self.armed:
                self.t0_us = self.t_us
                self._event("mission_start", boot_s=round(self.t0_us / 1e6, 3))
            elif self._px4_s() > self.config.arm_timeout_s:
                return (
                    f"px4 was not armed within {self.config.arm_timeout_s:g} s of its clock (the companion "
                    "did not arm it, or PX4 refused: see px4.log)"
                )
        w.apply_controls(self._controls, True)
        return None

    def _imu_at_rest(self) -> FloatArray:
        """An IMU sample of the vehicle at rest at its start, with the feet's contact force (the world's
        state is not advanced; the noise is this simulator's own)."""
        w = self.world
        bias, _, scale = w.imu.kernel_inputs_many(1)
        inputs = w.inputs.copy()
        inputs[IN_DECK : IN_DECK + N_DK] = w._deck_rows[0]  # the deck where it is at t = 0
        _, imu = motor_tick(
            w.x.copy(), np.zeros(4), inputs, w.sim_params, bias.copy(),
            self._rest_rng.standard_normal(12), scale.copy(), PHYSICS_DT, w.n_sub, w.contact_params,
            np.zeros(2),
        )  # fmt: skip
        return imu

    def _step(self, wall0: float) -> str | None:
        """One world tick: physics with PX4's last outputs, the sensors to PX4, PX4's answer."""
        w = self.world
        imu = w.step()
        if w.k % TRUTH_EVERY == 0:
            self._log()
        for fix in w.telemetry_arrivals():  # by the platform's own radio, on the camera's stream
            self.frames.send_platform_fix(fix.t_stamp + self._t0_s(), fix.p_WP, fix.v_WP, fix.cov_p_WP)
        self._camera()
        self.stats.steps += 1
        failure = self._send_sensors(w.k, self.t_us, imu)
        if failure is None:
            self._pace(wall0)
        return failure

    def _send_sensors(self, k: int, t_us: int, imu: FloatArray) -> str | None:
        """Tick ``k``'s sensor messages at PX4 time ``t_us``, and PX4's answer (lockstep)."""
        mav = self.link.mav
        self.sensors.hil_sensor(mav, t_us, imu)
        if k % GPS_EVERY == 0:
            self.sensors.hil_gps(mav, t_us)
        if k % RANGE_EVERY == 0:
            self.sensors.distance_sensor(mav, t_us // 1000)
        if k % TRUTH_EVERY == 0:
            self.sensors.ground_truth(mav, t_us)
        self.link.flush()
        return self._lockstep(t_us)

    def _pace(self, wall0: float) -> None:
        """Hold PX4's clock to ``speed`` times the wall clock (real time until PX4 first answers)."""
        speed = self.config.speed if self.stats.first_actuator_t_s is not None else 1.0
        if speed > 0:
            ahead = self._px4_s() / speed - (time.monotonic() - wall0)
            if ahead > 0:
                time.sleep(ahead)

    def _lockstep(self, t_us: int) -> str | None:
        """Take PX4's answers; once it has answered once, wait for the answer to ``t_us``."""
        cfg, link = self.config, self.link
        waiting = self.stats.first_actuator_t_s is not None
        t0 = time.monotonic()
        while True:
            for msg in link.receive(0.0 if not waiting else min(0.05, cfg.lockstep_timeout_s)):
                self._on_message(msg)
            if link.closed:
                return "px4 closed the simulator link (it exited or crashed)"
            if not waiting:
                if self.stats.first_actuator_t_s is None and t_us * 1e-6 > cfg.boot_timeout_s:
                    return f"px4 sent no actuator output within {cfg.boot_timeout_s:g} s of simulated time"
                return None
            if self.ack_us >= t_us:
                self.stats.wait_wall_s += time.monotonic() - t0
                return None
            if time.monotonic() - t0 > cfg.lockstep_timeout_s:
                return f"px4 stopped answering (no actuator output for {cfg.lockstep_timeout_s:g} s)"

    def _on_message(self, msg: Any) -> None:
        reply = actuator_reply(msg)
        if reply is None:
            return
        t_us, controls, armed = reply
        if t_us <= self.ack_us:
            return  # stale or repeated
        self.ack_us = t_us
        self.stats.actuator_messages += 1
        if self.stats.first_actuator_t_s is None:
            self.stats.first_actuator_t_s = t_us * 1e-6
            self._event("px4_first_actuator_output")
        if armed != self.armed:
            self._event("armed" if armed else "disarmed")
            self.armed = armed
        self._controls = controls
        if self.t0_us is not None:  # while the world waits for the arming, its rotors stay still
            self.world.apply_controls(controls, armed)

    def _t0_s(self) -> float:
        return 0.0 if self.t0_us is None else self.t0_us / 1e6

    def _camera(self) -> None:
        w = self.world
        if w.renderer is not None:
            w.capture()
            for t_cap, shot in w.deliveries():
                assert isinstance(shot, Shot)
                self._held.append((t_cap, w.develop(shot, t_cap, used=True)))
        while self._held and w.t - self._held[0][0] >= FRAME_HOLD_S - 1e-9:
            t_cap, image = self._held.pop(0)
            self.frames.send_frame(t_cap + self._t0_s(), image)  # stamped with PX4's clock

    def _log(self) -> None:
        w, x = self.world, self.world.x
        lg = self.log
        lg["t"].append(w.t + self._t0_s())  # PX4's clock, as the companion's log
        lg["p_WB"].append(x[SL_P].copy())
        lg["v_WB"].append(x[SL_V].copy())
        lg["p_WP"].append(w.truths.p_WP[w.k].copy())
        lg["v_WP"].append(w.truths.v_WP[w.k].copy())
        lg["w_WB_B"].append(x[SL_W].copy())
        lg["f_wind_W"].append(np.array(w.f_wind, dtype=float))
        lg["motor_N"].append(x[IX_F : IX_F + 4].copy())

    def _finish(self) -> dict[str, Any]:
        w, s = self.world, self.scenario
        motor_t, motor_N = np.array(self.log["t"]), np.array(self.log["motor_N"])
        return {
            "scenario": s.model_dump(mode="json"),
            "seed": s.seed,
            "preset": s.preset,
            **w.verdict(),
            "energy_flight_J": flight_energy_J(motor_t, motor_N) if motor_t.size > 1 else None,
            "simulated_time_s": w.t,
            "px4_boot_s": None if self.t0_us is None else self.t0_us / 1e6,
            "sitl_wall_time_s": self.stats.wall_s,
            "sitl_flavour": "px4-sitl",
            "sitl_events": [*self.stats.events, self.stats.record()],
            "alight_version": alight.__version__,
        }

    def truth_arrays(self) -> dict[str, np.ndarray]:
        return {k: np.array(v, dtype=float) for k, v in self.log.items()}

    def send_outcome(self, result: dict[str, Any]) -> None:
        """The verdict and the ground-truth log to the companion, on the camera stream."""
        self.frames.send_result(json.loads(json.dumps(result, default=float)))
        self.frames.send_truth_log(self.truth_arrays())

    def close(self) -> None:
        self.frames.close()
        self.link.close()
