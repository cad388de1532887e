"""``alight fly --autopilot px4``: finding the build, choosing the instance, and a PX4 that does not start or
crashes ending the mission with a clear outcome (stand-in ``bin/px4`` scripts, no PX4 needed). The
flight with a real PX4 SITL build runs where ``ALIGHT_PX4_DIR`` points at one (docs/px4.md) and is
skipped otherwise."""

from __future__ import annotations

import json
import os
import socket
import stat
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from alight.airframes import load_airframe
from alight.errors import ConfigError
from alight.interfaces.autopilot_missions import fly_through_command
from alight.interfaces.px4_airframe import px4_environment
from alight.interfaces.px4_run import (
    PX4_DIR_ENV,
    PX4_UDP_PORTS,
    Px4FlyConfig,
    _takeoff_altitude_m,
    claim_instance,
    find_px4_build,
    fly_px4,
    free_instance,
)
from alight.interfaces.px4_sim import SIM_PORT_BASE
from alight.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[2]

# A stand-in for PX4: connects to the world, answers HIL_SENSOR with HIL_ACTUATOR_CONTROLS (disarmed)
# ANSWERS times, then exits with status 3 (a crash). ANSWERS 0: exits at once (a PX4 that cannot start).
FAKE_PX4 = """#!{python}
import socket, sys, time
from pymavlink.dialects.v20 import common as mavlink
ANSWERS = {answers}
if ANSWERS == 0:
    print("ERROR: no such airframe"); sys.exit(1)
instance = int(sys.argv[sys.argv.index("-i") + 1])
deadline = time.monotonic() + 120
while True:
    try:
        sock = socket.create_connection(("127.0.0.1", 4560 + instance), timeout=1.0); break
    except OSError:
        if time.monotonic() > deadline: sys.exit(2)
        time.sleep(0.05)
sock.settimeout(120)
tx, rx, n = mavlink.MAVLink(None), mavlink.MAVLink(None), 0
while n < ANSWERS:
    data = sock.recv(65536)
    if not data: break
    for msg in rx.parse_buffer(data) or []:
        if msg.get_type() == "HIL_SENSOR":
            n += 1
            sock.sendall(tx.hil_actuator_controls_encode(msg.time_usec, [0.0] * 16, 1, 1).pack(tx))
print("segmentation fault (stand-in)"); sys.exit(3)
"""


def _fake_build(tmp: Path, answers: int) -> Path:
    root = tmp / "build" / "px4_sitl_default"
    (root / "bin").mkdir(parents=True)
    (root / "etc" / "init.d-posix").mkdir(parents=True)
    exe = root / "bin" / "px4"
    exe.write_text(FAKE_PX4.format(python=sys.executable, answers=answers))
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return tmp


def test_find_build_refuses_in_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(PX4_DIR_ENV, raising=False)
    with pytest.raises(ConfigError, match="--px4 DIR") as err:
        find_px4_build(None)
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match="no PX4 SITL build"):
        find_px4_build(str(tmp_path))
    _fake_build(tmp_path, 1)
    assert find_px4_build(str(tmp_path)).root == tmp_path / "build" / "px4_sitl_default"  # a checkout
    monkeypatch.setenv(PX4_DIR_ENV, str(tmp_path / "build" / "px4_sitl_default"))
    assert find_px4_build(None).binary.is_file()  # the environment variable


def test_free_instance_skips_one_whose_port_is_taken() -> None:
    i = free_instance()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("0.0.0.0", PX4_UDP_PORTS[0] + i))
        assert free_instance(i) > i
    assert SIM_PORT_BASE + free_instance(i) >= SIM_PORT_BASE + i


def test_two_missions_never_claim_the_same_instance() -> None:
    # the ports of an instance are free until PX4 binds them, seconds after the check: the claim is a lock
    first, lock1 = claim_instance()
    second, lock2 = claim_instance()
    try:
        assert second != first
        with pytest.raises(ConfigError, match=f"instance {first} is in use"):
            claim_instance(wanted=first)
    finally:
        lock1.close()
        lock2.close()
    again, lock3 = claim_instance(wanted=first)  # released by closing (or by the process's death)
    lock3.close()
    assert again == first


def test_px4_takes_off_to_the_search_height_in_landing_target_mode() -> None:
    s = _scenario()
    assert _takeoff_altitude_m(s, Px4FlyConfig(mode="landing-target")) == 12.0  # explore_altitude_m
    assert _takeoff_altitude_m(s, Px4FlyConfig(mode="offboard")) is None
    low = Scenario.model_validate(
        {**s.model_dump(mode="json", exclude_none=True), "mission": {"takeoff_altitude_m": 7.5}}
    )
    assert _takeoff_altitude_m(low, Px4FlyConfig(mode="landing-target")) == 7.5
    env = px4_environment(load_airframe(s.airframe), takeoff_altitude_m=12.0)
    assert env["PX4_PARAM_MIS_TAKEOFF_ALT"] == "12"


def _scenario() -> Scenario:
    return load_scenario(ROOT / "examples" / "alight_circle.yaml").model_copy(update={"duration_s": 30.0})


def test_a_px4_that_does_not_start_ends_the_mission_as_error(tmp_path: Path) -> None:
    build = _fake_build(tmp_path / "px4", 0)
    t0 = time.monotonic()
    r = fly_px4(_scenario(), tmp_path / "out", str(build), Px4FlyConfig(connect_timeout_s=3.0))
    assert r["outcome"] == "error" and "did not connect" in r["outcome_reason"]
    assert r["px4"]["exit_code"] == 1
    assert time.monotonic() - t0 < 900  # bounded: the companion loads its kernels first (minutes here)
    saved = json.loads((tmp_path / "out" / "result.json").read_text())
    assert saved["outcome"] == "error" and saved["px4"]["airframe"]["model"] == "none_iris"
    assert "no such airframe" in (tmp_path / "out" / "px4" / "px4.log").read_text()


def test_a_px4_that_crashes_ends_the_mission_as_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    build = _fake_build(tmp_path / "px4", 300)
    args = SimpleNamespace(
        autopilot="px4", px4=str(build), px4_mode="offboard", px4_speed=0.0, setpoint="position",
        replay=False, mcap=False, bag=None,
    )  # fmt: skip
    assert fly_through_command(_scenario(), tmp_path / "out", args) == 0
    r = json.loads((tmp_path / "out" / "result.json").read_text())
    assert r["outcome"] == "error" and "closed the simulator link" in r["outcome_reason"]
    # the stand-in is never armed: it dies 1.5 s into its clock, before the mission's clock has started
    lockstep = next(e for e in r["sitl"]["events"] if e.get("kind") == "px4_lockstep")
    assert r["px4"]["exit_code"] == 3 and lockstep["sim_s"] == pytest.approx(1.5, abs=0.02)
    assert r["simulated_time_s"] == 0.0 and r["sitl"]["px4_boot_s"] is None
    assert "px4 alight seed 1 (offboard): error" in capsys.readouterr().out
    with pytest.raises(ConfigError, match="--autopilot sim only"):
        fly_through_command(_scenario(), tmp_path / "out2", SimpleNamespace(**{**vars(args), "replay": True}))


@pytest.mark.skipif(
    not os.environ.get(PX4_DIR_ENV), reason=f"no PX4 SITL build: set {PX4_DIR_ENV} (docs/px4.md)"
)
def test_real_px4_flies_the_circle_offboard(tmp_path: Path) -> None:
    scenario = load_scenario(ROOT / "examples" / "alight_circle.yaml")
    r = fly_px4(scenario, tmp_path, None, Px4FlyConfig(speed=1.0))
    assert r["outcome"] == "landed", (r["outcome"], r["outcome_reason"])
    assert (tmp_path / "report.html").is_file()
