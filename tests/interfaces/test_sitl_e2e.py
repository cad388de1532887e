"""End to end through the command line: ``alight sitl`` + ``alight bridge`` over loopback MAVLink.

Offboard (body rates + thrust) lands the falanga2017 straight-line mission (1.2 m/s) on three seeds, and in
landing-target mode the emulated precision landing, fed only by alight's LANDING_TARGET messages, lands on
a slow platform. All four pairs of processes run at once (lockstep: each pair keeps about one core busy;
about 20-40 s of wall time on a shared 2-core machine with a warm numba cache)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from tests_interfaces_ports import free_port_pair

ROOT = Path(__file__).resolve().parents[2]
STRAIGHT = ROOT / "examples" / "falanga2017_straight.yaml"
PRECLAND = Path(__file__).parent / "data" / "precland_slow.yaml"


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT / "src") + os.pathsep + env.get("PYTHONPATH", "")
    return env


@pytest.mark.slow
def test_sitl_and_bridge_land(tmp_path: Path) -> None:
    cases = [(STRAIGHT, seed, ["--mode", "offboard"]) for seed in (1, 2, 3)]
    cases.append((PRECLAND, 3, ["--mode", "landing-target"]))
    procs: list[tuple[Path, subprocess.Popen[str], subprocess.Popen[str]]] = []
    outputs: list[tuple[Path, subprocess.Popen[str], str, subprocess.Popen[str], str]] = []
    try:
        for scenario, seed, mode in cases:
            port = free_port_pair()
            out = tmp_path / f"{scenario.stem}_{seed}"
            cli = [sys.executable, "-m", "alight.cli"]
            sitl = subprocess.Popen(
                [*cli, "sitl", str(scenario), "--port", str(port), "--seed", str(seed)],
                env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            )  # fmt: skip
            bridge = subprocess.Popen(
                [*cli, "bridge", "--connect", f"udp:127.0.0.1:{port}", "--out", str(out), "--arm", *mode],
                env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            )  # fmt: skip
            procs.append((out, sitl, bridge))
        for out, sitl, bridge in procs:
            _, b_err = bridge.communicate(timeout=900)
            _, s_err = sitl.communicate(timeout=60)
            outputs.append((out, bridge, b_err, sitl, s_err))
    finally:
        # A failure must not leave processes running, nor pipes for the garbage collector to report as
        # unclosed in whichever test runs next.
        for _, sitl, bridge in procs:
            for proc in (bridge, sitl):
                if proc.poll() is None:
                    proc.kill()
                if proc.stdout is not None and not proc.stdout.closed:
                    proc.communicate()
    for out, bridge, b_err, sitl, s_err in outputs:
        assert bridge.returncode == 0, f"bridge: {b_err}\nsitl: {s_err}"
        assert sitl.returncode == 0, f"sitl: {s_err}\nbridge: {b_err}"
        result = json.loads((out / "result.json").read_text())
        assert (out / "report.html").is_file() and (out / "log.npz").is_file()
        assert result["outcome"] == "landed", (out.name, result["outcome"], result["bridge"]["events"][-5:])
        assert result["touchdown_error_m"] < 0.55
        assert result["detections"] > 10 and result["bridge"]["lockstep"]
        assert result["bridge"]["rejected"] == {}  # nothing the emulator sent was refused
        # judged as alight fly judges it: first contact, then still on the pad settle_s after the motors
        # stopped; the motors stop only when the emulated autopilot disarms
        assert result["outcome_reason"] == "" and result["bounces"] == 0
        assert result["time_first_contact_s"] < result["time_motors_off_s"] < result["simulated_time_s"]
        disarms = [e for e in result["sitl"]["events"] if e["event"] == "disarmed"]
        assert len(disarms) == 1 and disarms[0]["t"] == pytest.approx(result["time_motors_off_s"], abs=0.011)
        if result["bridge"]["mode"] == "landing-target":
            assert result["bridge"]["landing_targets_sent"] > 10 and result["bridge"]["setpoints_sent"] == 0
            assert disarms[0]["reason"] == "land detector"  # the emulator's own, in AUTO.PRECLAND
        else:
            assert result["bridge"]["setpoints_sent"] > 500
            # the pipeline's land detector said landed; the bridge forced the disarm at that tick
            assert disarms[0]["reason"] == "forced"
            assert result["time_touchdown_onboard_s"] == pytest.approx(result["time_motors_off_s"], abs=0.011)
