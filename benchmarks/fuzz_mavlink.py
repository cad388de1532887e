"""Fuzz the MAVLink bridge's receive path.

    python benchmarks/fuzz_mavlink.py [--n 100000] [--seed 0]

Feeds a bridge (the falanga2017 pipeline, offboard, arming allowed) a stream of buffers drawn from seven
kinds: a valid 5 ms tick of a scripted PX4 (so time advances and the pipeline runs), random bytes (half
of them starting with the MAVLink 2 magic 0xFD), valid messages with mutated fields (NaN, inf, +-1e38,
extreme integers; the CRC recomputed by packing, so they pass the parser), truncated frames, a few ticks
with their messages shuffled, messages with timestamps going backwards, and valid frames with flipped
bits. Counts: exceptions that escape ``MavlinkBridge.feed_bytes`` (must be 0), non-finite numbers that
reach the pipeline's ``on_imu`` / ``on_odometry`` / ``on_range`` (must be 0; a range may be +-inf, the
sensor's out-of-range readings, but never NaN), and the longest time one buffer took (a hang shows
there). Prints one JSON line.

    python benchmarks/fuzz_mavlink.py --target emulator [--n 100000] [--seed 0]

Fuzzes the emulated autopilot's receive path (``EmulatedAutopilot.receive``, what ``alight sitl`` does with
each datagram) the same way, with two emulators of the same scenario and seed flying side by side: both
get the peer's datagrams (a scripted companion that takes off and holds, plus its own random bytes,
mutated and truncated messages and flipped bits), and the first also gets datagrams from senders that
are not the peer (random bytes, valid commands, heartbeats, setpoints and lockstep acknowledgements with
NaN / inf / absurd fields, and spoofs that carry the peer's system and component ids from another
address). The simulated clock advances one control period every 20 datagrams. Counts: exceptions that
escape ``receive`` or the control step (must be 0), and the state differences between the two emulators
at each checkpoint (``outcome_changes``: what a sender that is not the peer changed; must be 0).
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import time
from typing import Any

import numpy as np

from alight.airframe import DEFAULT_AIRFRAME
from alight.interfaces.fake_autopilot import Capture, FakeAutopilot
from alight.interfaces.mavlink_bridge import BridgeConfig, MavlinkBridge, mavlink
from alight.mission.presets import build_preset
from alight.scenario import Scenario

_FLOATS = (math.nan, math.inf, -math.inf, 1e38, -1e38, 0.0, -0.0, 1e-30)
_INT_RANGE = {
    "uint8_t": (0, 255),
    "int8_t": (-128, 127),
    "uint16_t": (0, 65535),
    "int16_t": (-32768, 32767),
    "uint32_t": (0, 2**32 - 1),
    "int32_t": (-(2**31), 2**31 - 1),
    "uint64_t": (0, 2**64 - 1),
    "int64_t": (-(2**63), 2**63 - 1),
}


def _random_value(rng: np.random.Generator, ftype: str) -> Any:
    if ftype in ("float", "double"):
        return (
            _FLOATS[rng.integers(len(_FLOATS))]
            if rng.random() < 0.6
            else float(rng.normal() * 10 ** rng.integers(0, 6))
        )
    if ftype == "char":
        return bytes(rng.integers(0, 256, size=rng.integers(0, 10), dtype=np.uint8)).decode("latin-1")
    lo, hi = _INT_RANGE.get(ftype, (0, 255))
    if rng.random() < 0.5:
        return int(lo if rng.random() < 0.5 else hi)
    return int(rng.integers(lo, hi, endpoint=True, dtype=np.uint64 if lo == 0 else np.int64))


def _mutate(msg: Any, rng: np.random.Generator) -> Any:
    m = copy.copy(msg)
    for name, ftype in zip(m.fieldnames, m.fieldtypes, strict=True):
        if rng.random() > 0.3:
            continue
        value = getattr(m, name)
        if isinstance(value, list):
            value = list(value)
            for i in range(len(value)):
                if rng.random() < 0.5:
                    value[i] = _random_value(rng, ftype)
            setattr(m, name, value)
        else:
            setattr(m, name, _random_value(rng, ftype))
    return m


class _Spy:
    """Wraps the pipeline's sensor inputs and counts non-finite numbers in them."""

    def __init__(self, pipeline: Any) -> None:
        self.non_finite = 0
        self.calls = 0
        for name in ("on_imu", "on_odometry", "on_range"):
            setattr(pipeline, name, self._wrap(getattr(pipeline, name)))

    def _wrap(self, fn: Any) -> Any:
        # A range reading may be +-inf (out of range, ROS REP 117, as the sensor reports it); NaN never.
        is_range = getattr(fn, "__name__", "") == "on_range"

        def spy(*args: Any) -> Any:
            self.calls += 1
            for a in args:
                if a is None:
                    continue
                v = np.asarray(a, dtype=float)
                if np.any(np.isnan(v)) if is_range else not np.all(np.isfinite(v)):
                    self.non_finite += 1
            return fn(*args)

        return spy


def _templates(ap: FakeAutopilot) -> list[Any]:
    m, t_us, t_ms = ap.mav, 1_000_000, 1000
    nan21 = [math.nan] * 21
    return [
        m.heartbeat_encode(2, 12, 129, 6 << 16, 4),
        m.highres_imu_encode(t_us, 0, 0, -9.81, 0, 0, 0, 0, 0, 0, 1013, 0, 0, 20, 63),
        m.scaled_imu_encode(t_ms, 0, 0, -1000, 0, 0, 0, 0, 0, 0),
        m.attitude_encode(t_ms, 0.1, 0.1, 0.5, 0, 0, 0),
        m.attitude_quaternion_encode(t_ms, 1, 0, 0, 0, 0, 0, 0),
        m.local_position_ned_encode(t_ms, 1, 2, -3, 0, 0, 0),
        m.odometry_encode(t_us, 1, 12, 1, 2, -3, [1, 0, 0, 0], 0, 0, 0, 0, 0, 0, nan21, nan21, 0, 0, 100),
        m.distance_sensor_encode(t_ms, 0, 1400, 300, 0, 0, 25, 0),
        m.extended_sys_state_encode(0, 2),
        m.timesync_encode(0, 123),
        m.named_value_int_encode(t_ms, b"FRAMESEQ", 5),
        m.named_value_int_encode(t_ms, b"LOCKSTEP", 1),
        m.command_ack_encode(176, 0),
        m.statustext_encode(4, b"hello"),
    ]


def run(n: int = 100_000, seed: int = 0) -> dict[str, Any]:
    """Fuzz ``n`` buffers; returns the counts (see the module docstring)."""
    rng = np.random.default_rng(seed)
    scenario = Scenario.model_validate({"preset": "falanga2017", "seed": seed})
    preset = build_preset(scenario, DEFAULT_AIRFRAME, np.random.default_rng(seed))
    bridge = MavlinkBridge(preset.pipeline, BridgeConfig(arm=True), link=Capture())
    spy = _Spy(preset.pipeline)
    ap = FakeAutopilot()
    ap.offboard(armed=True)  # so the bridge engages and the pipeline runs under the fuzz
    templates = _templates(ap)
    uncaught: dict[str, int] = {}
    max_s = 0.0
    kinds = np.zeros(7, dtype=int)
    t0 = time.perf_counter()
    for _ in range(n):
        kind = int(rng.integers(7))
        kinds[kind] += 1
        if kind == 0:
            data = ap.tick()
        elif kind == 1:
            data = bytes(rng.integers(0, 256, size=int(rng.integers(1, 300)), dtype=np.uint8))
            if rng.random() < 0.5:
                data = b"\xfd" + data
        elif kind == 2:
            try:
                data = ap.encode(_mutate(templates[rng.integers(len(templates))], rng))
            except Exception:  # noqa: BLE001 - a mutation pymavlink itself cannot pack: not a bridge input
                continue
        elif kind == 3:
            full = ap.encode(templates[rng.integers(len(templates))])
            data = full[: int(rng.integers(1, len(full)))]
        elif kind == 4:
            parts = [ap.tick() for _ in range(int(rng.integers(2, 6)))]
            msgs = [bytes(x.get_msgbuf()) for p in parts for x in (Capture.decode(p))]
            rng.shuffle(msgs)
            data = b"".join(msgs)
        elif kind == 5:
            back = ap.t - float(rng.uniform(0.0, 10.0))
            m = ap.mav
            if rng.random() < 0.5:
                msg = m.highres_imu_encode(
                    max(int(back * 1e6), 0), 0, 0, -9.81, 0, 0, 0, 0, 0, 0, 1013, 0, 0, 20, 63
                )
            else:
                nan21 = [math.nan] * 21
                t_us = max(int(back * 1e6), 0)
                msg = m.odometry_encode(
                    t_us, 1, 1, 0, 0, -2, [1, 0, 0, 0], 0, 0, 0, 0, 0, 0, nan21, nan21, 0, 0, 100
                )
            data = ap.encode(msg)
        else:
            buf = bytearray(ap.encode(templates[rng.integers(len(templates))]))
            for _ in range(int(rng.integers(1, 4))):
                buf[int(rng.integers(len(buf)))] ^= 1 << int(rng.integers(8))
            data = bytes(buf)
        start = time.perf_counter()
        try:
            bridge.feed_bytes(data)
        except Exception as err:  # noqa: BLE001 - what the fuzzer exists to count
            key = f"{type(err).__name__}: {str(err)[:80]}"
            uncaught[key] = uncaught.get(key, 0) + 1
        max_s = max(max_s, time.perf_counter() - start)
    wall = time.perf_counter() - t0
    return {
        "buffers": n,
        "seed": seed,
        "kinds": {
            k: int(c)
            for k, c in zip(
                ("tick", "random", "mutated", "truncated", "reordered", "backwards", "bitflip"),
                kinds,
                strict=True,
            )
        },  # fmt: skip
        "uncaught_exceptions": sum(uncaught.values()),
        "uncaught_by_type": uncaught,
        "non_finite_inputs": spy.non_finite,
        "pipeline_inputs": spy.calls,
        "accepted_messages": sum(bridge.stats.accepted.values()),
        "rejected_messages": sum(bridge.stats.rejected.values()),
        "parse_errors": bridge.stats.parse_errors,
        "foreign_messages": bridge.stats.foreign,
        "autopilot_time_s": round(bridge.t_ap, 3) if math.isfinite(bridge.t_ap) else None,
        "final_phase": bridge.phase.value,
        "max_buffer_s": round(max_s, 4),
        "wall_time_s": round(wall, 2),
        "mavlink_wire_version": mavlink.WIRE_PROTOCOL_VERSION,
    }


# -- the emulated autopilot ------------------------------------------------------------------------------
PEER_ADDR, OTHER_ADDRS = ("127.0.0.1", 40000), [("127.0.0.1", 40001 + i) for i in range(8)]


def _emulator_templates(mav: Any) -> list[Any]:
    """Valid messages a companion or a ground station sends (before mutation)."""
    nan = math.nan
    return [
        mav.heartbeat_encode(18, 8, 0, 0, 0),
        mav.command_long_encode(1, 1, 400, 0, 0, 21196, nan, nan, nan, nan, nan),  # forced disarm
        mav.command_long_encode(1, 1, 400, 0, 1, nan, nan, nan, nan, nan, nan),
        mav.command_long_encode(1, 1, 176, 0, 1, 4, 6, nan, nan, nan, nan),  # AUTO.LAND
        mav.command_long_encode(1, 1, 22, 0, nan, nan, nan, nan, nan, nan, 495.0),
        mav.command_long_encode(1, 1, 21, 0, nan, nan, nan, nan, nan, nan, nan),
        mav.command_long_encode(1, 1, 512, 0, 148, nan, nan, nan, nan, nan, nan),
        mav.command_long_encode(1, 1, 511, 0, 105, 5000, nan, nan, nan, nan, nan),
        mav.command_int_encode(1, 1, 6, 192, 0, 0, -1, 1, 0, nan, 473977420, 85455940, 3.0),
        mav.command_int_encode(1, 1, 0, 20, 0, 0, nan, nan, nan, nan, 0, 0, nan),
        mav.set_position_target_local_ned_encode(0, 1, 1, 1, 2552, 1.0, 2.0, -3.0, 0, 0, 0, 0, 0, 0, 0.5, 0),
        mav.set_attitude_target_encode(0, 1, 1, 7, [1, 0, 0, 0], 0.1, 0.0, 0.0, 0.6),
        mav.landing_target_encode(0, 0, 1, 0, 0, 0, 0, 0, 1.0, 2.0, 0.0, [1, 0, 0, 0], 2, 1),
        mav.named_value_int_encode(10_000_000, b"LSACK", 0),
        mav.param_set_encode(1, 1, b"COM_OF_LOSS_T", 0.2, 9),
        mav.param_request_read_encode(1, 1, b"MIS_TAKEOFF_ALT", -1),
        mav.param_request_list_encode(1, 1),
        mav.mission_request_list_encode(1, 1, 0),
        mav.mission_count_encode(1, 1, 5, 0),
        mav.file_transfer_protocol_encode(0, 1, 1, [0, 0, 0, 4] + [0] * 247),
        mav.timesync_encode(0, 123),
    ]


def _emulator_state(ap: Any) -> tuple[Any, ...]:
    w = ap.world
    params = tuple(sorted((k, v.value) for k, v in ap.params.items()))
    return (round(w.t, 6), tuple(np.round(w.x, 9)), ap.mode.value, ap.custom_mode, ap.armed, ap.ack_t,
            ap.peer_lockstep, w.outcome, params, len(ap.events))  # fmt: skip


def _fuzz_datagram(rng: np.random.Generator, mav: Any, templates: list[Any]) -> bytes | None:
    kind = int(rng.integers(4))
    if kind == 0:  # random bytes, half with the MAVLink 2 start byte
        data = bytes(rng.integers(0, 256, size=int(rng.integers(1, 300)), dtype=np.uint8))
        return b"\xfd" + data if rng.random() < 0.5 else data
    msg = templates[int(rng.integers(len(templates)))]
    if kind == 1:  # NaN, inf, absurd values in any field, the CRC valid
        try:
            return bytes(_mutate(msg, rng).pack(mav))
        except Exception:  # noqa: BLE001 - a mutation pymavlink cannot pack: not an input
            return None
    full = bytes(msg.pack(mav))
    if kind == 2:  # truncated
        return full[: int(rng.integers(1, len(full)))]
    buf = bytearray(full)  # flipped bits
    for _ in range(int(rng.integers(1, 4))):
        buf[int(rng.integers(len(buf)))] ^= 1 << int(rng.integers(8))
    return bytes(buf)


def _emulator_pair(seed: int) -> tuple[Any, Any]:
    from alight.interfaces.sitl import EmulatedAutopilot, SitlConfig

    scenario = Scenario.model_validate({"preset": "groundtruth", "seed": seed, "duration_s": 3600.0})
    config = SitlConfig(port=0, camera_port=0, lockstep=True)
    return EmulatedAutopilot(scenario, config), EmulatedAutopilot(scenario, config)


def run_emulator(n: int = 100_000, seed: int = 0) -> dict[str, Any]:
    """Fuzz ``n`` datagrams into the emulator's receive path; returns the counts (module docstring)."""
    from pymavlink.dialects.v20 import common as mav2

    rng = np.random.default_rng(seed)
    fuzzed, reference = _emulator_pair(seed)
    peer = mav2.MAVLink(None, 1, 191)  # the companion's ids (and the spoofers')
    stranger = mav2.MAVLink(None, 7, 190)
    templates = _emulator_templates(peer)
    # The peer's own fuzz leaves out its commands (a mutated forced disarm would end the flight early and
    # leave little to fuzz); strangers and spoofers send everything.
    peer_templates = [m for m in templates if m.get_type() not in ("COMMAND_LONG", "COMMAND_INT")]
    script = [
        peer.heartbeat_encode(18, 8, 0, 0, 0),
        peer.command_long_encode(1, 1, 176, 0, 1, 4, 2, 0, 0, 0, 0),
        peer.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0),
    ]
    for msg in script:  # the peer shows itself, asks for AUTO.TAKEOFF and arms: the world flies
        for ap in (fuzzed, reference):
            ap.receive(bytes(msg.pack(peer)), PEER_ADDR)
    exits: dict[str, int] = {}
    changes = checkpoints = foreign_sent = 0
    counts = {"peer": 0, "foreign": 0, "spoofed": 0}
    max_s = 0.0
    t0 = time.perf_counter()
    for i in range(n):
        who = rng.random()
        if who < 0.4:
            sender, addr, targets = peer, PEER_ADDR, (fuzzed, reference)
            counts["peer"] += 1
        else:  # not the peer: another system, or the peer's own ids from another address
            spoofed = who < 0.7
            sender = peer if spoofed else stranger
            addr, targets = OTHER_ADDRS[int(rng.integers(len(OTHER_ADDRS)))], (fuzzed,)
            counts["spoofed" if spoofed else "foreign"] += 1
            foreign_sent += 1
        data = _fuzz_datagram(rng, sender, peer_templates if targets[-1] is reference else templates)
        start = time.perf_counter()
        for ap in targets if data is not None else ():
            try:
                ap.receive(data, addr)
            except Exception as err:  # noqa: BLE001 - what the fuzzer exists to count
                key = f"receive {type(err).__name__}: {str(err)[:80]}"
                exits[key] = exits.get(key, 0) + 1
        max_s = max(max_s, time.perf_counter() - start)
        if i % 20 == 19:  # one control period of simulated time
            for ap in (fuzzed, reference):
                try:
                    _emulator_period(ap)
                except Exception as err:  # noqa: BLE001
                    key = f"control {type(err).__name__}: {str(err)[:80]}"
                    exits[key] = exits.get(key, 0) + 1
            if i % 2000 == 1999:
                checkpoints += 1
                changes += _emulator_state(fuzzed) != _emulator_state(reference)
    wall = time.perf_counter() - t0
    result = {
        "target": "emulator",
        "datagrams": n,
        "seed": seed,
        "senders": counts,
        "exits": sum(exits.values()),
        "exits_by_type": exits,
        "checkpoints": checkpoints,
        "outcome_changes": changes,
        "final_state_equal": _emulator_state(fuzzed) == _emulator_state(reference),
        "refused_from_non_peers": fuzzed.foreign - reference.foreign,
        "parse_errors": fuzzed.parse_errors,
        "simulated_s": round(fuzzed.world.t, 2),
        "final_mode": fuzzed.mode.value,
        "armed": fuzzed.armed,
        "max_datagram_s": round(max_s, 4),
        "wall_time_s": round(wall, 2),
    }
    for ap in (fuzzed, reference):
        ap.close()
    return result


def _emulator_period(ap: Any) -> None:
    """One control period of the emulator without its socket loop: control, then the physics ticks."""
    from alight.interfaces.sitl import CONTROL_DT, TICK_DT

    w = ap.world
    if w.done:
        return
    ap._control()
    for _ in range(round(CONTROL_DT / TICK_DT)):
        imu = w.step()
        ap._send_sensors(imu)
        if w.done:
            break
    ap.outbox.buf.clear()  # nobody listens


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=100_000, help="number of buffers")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--target", choices=("bridge", "emulator"), default="bridge")
    args = parser.parse_args()
    fuzz = run_emulator if args.target == "emulator" else run
    print(json.dumps(fuzz(args.n, args.seed)))


if __name__ == "__main__":
    main()
