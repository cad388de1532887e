"""Fake mission functions for the campaign engine's tests: module-level (a sandbox imports them by
``module:function``), instant, and with the failure modes a real mission can have.

Each takes ``(scenario, out_dir)`` like ``alight.campaign.engines.fly_mission`` and returns a result dict
whose numbers are functions of the scenario's seed, so two runs of the same campaign must agree.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

SLEEP_ENV = "ALIGHT_FAKE_SLEEP_S"
PID_DIR_ENV = "ALIGHT_FAKE_PID_DIR"


def fake_result(scenario: Any) -> dict[str, Any]:
    """A result dict from the seed alone: landed for even seeds, crashed for odd ones."""
    seed = scenario.seed
    landed = seed % 2 == 0
    return {
        "preset": scenario.preset,
        "seed": seed,
        "outcome": "landed" if landed else "crashed",
        "success": landed,
        "touchdown_error_m": (seed % 1000) / 1e4,
        "touchdown_rel_speed_mps": 0.5,
        "touchdown_rel_vertical_speed_mps": 0.4,
        "time_to_land_s": 20.0 + seed % 7 if landed else None,
        "time_first_detection_s": 5.0,
        "energy_flight_J": 1000.0 + seed % 100,
        "energy_compute_J": None,
        "detections": seed % 50,
        "go_arounds": 0,
        "platform_estimate_rmse_m": 0.1,
        "simulated_time_s": scenario.duration_s,
        "wall_time_s": 0.01,
    }


def instant(scenario: Any, out_dir: Path) -> dict[str, Any]:
    result = fake_result(scenario)
    if result["outcome"] != "landed":
        (out_dir / "report.html").write_text(f"<p>{scenario.name}</p>", encoding="utf-8")
    return result


def sleepy(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """Sleeps ``ALIGHT_FAKE_SLEEP_S`` (default 0.3 s); writes its pid into ``ALIGHT_FAKE_PID_DIR``."""
    pid_dir = os.environ.get(PID_DIR_ENV)
    if pid_dir:
        (Path(pid_dir) / str(os.getpid())).touch()
    time.sleep(float(os.environ.get(SLEEP_ENV, "0.3")))
    return fake_result(scenario)


def by_speed(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """The platform speed picks the behaviour: 1 flies, 2 raises, 3 hangs, 4 kills its own process."""
    speed = scenario.platform.speed_mps
    if speed == 2.0:
        raise RuntimeError(f"fake failure of {scenario.name}")
    if speed == 3.0:
        time.sleep(3600.0)
    if speed == 4.0:
        os._exit(3)
    return instant(scenario, out_dir)


def not_a_result(scenario: Any, out_dir: Path) -> Any:
    return 42


FLIGHT_LOG_ENV = "ALIGHT_FAKE_FLIGHT_LOG"


def logged(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """Like ``sleepy``, and leaves one file per flight in ``ALIGHT_FAKE_FLIGHT_LOG``
    (``<mission name>.<pid>.<time>``): a test counts how many times each mission was flown."""
    log = os.environ.get(FLIGHT_LOG_ENV)
    if log:
        name = scenario.name.split()[-1]
        (Path(log) / f"{name}.{os.getpid()}.{time.monotonic_ns()}").touch()
    time.sleep(float(os.environ.get(SLEEP_ENV, "0.3")))
    return fake_result(scenario)


def killed(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """Writes a file into its scratch directory, then SIGKILLs its own process (nothing can clean up)."""
    import signal

    (out_dir / "partial.txt").write_text("half a mission", encoding="utf-8")
    os.kill(os.getpid(), signal.SIGKILL)
    return fake_result(scenario)  # never reached


def with_log(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """As the default mission does: a failure writes its log (here a stand-in) and no views."""
    result = fake_result(scenario)
    if result["outcome"] != "landed":
        (out_dir / "log.npz").write_bytes(f"log {scenario.seed}".encode())
    return result


def views(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """As the views mission does: the same flight, and a failure's views beside its log and result."""
    result = fake_result(scenario)
    if result["outcome"] != "landed":
        # another log than the sweep's (the campaign must keep the sweep's: it is the record)
        (out_dir / "log.npz").write_bytes(f"log of the views flight {scenario.seed}".encode())
        (out_dir / "replay.gif").write_bytes(b"GIF89a")
        (out_dir / "result.json").write_text('{"written": "by the views flight"}', encoding="utf-8")
        (out_dir / "report.html").write_text(f"<p>views {scenario.seed}</p>", encoding="utf-8")
    return result


def views_of_another_flight(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """A views flight that did not fly the recorded flight (a determinism bug): another touchdown error."""
    result = views(scenario, out_dir)
    return {**result, "touchdown_error_m": result["touchdown_error_m"] + 1.0}


def views_that_raise(scenario: Any, out_dir: Path) -> dict[str, Any]:
    raise RuntimeError(f"no views for seed {scenario.seed}")
