"""``alight bench``: run the benchmark functions of the source tree's ``benchmarks/`` folder.

Each ``benchmarks/bench_*.py`` module exposes a ``bench_*()`` function returning a flat dict of numbers
(and pytest-benchmark tests for ``pytest benchmarks/``). The benchmarks live beside the tests, not in the
installed package, because they measure the package; ``alight bench`` therefore needs a source checkout
(an editable install finds it on its own; otherwise pass ``--dir`` or set ``ALIGHT_BENCHMARKS``).
"""

from __future__ import annotations

import importlib.util
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import alight
from alight.errors import InputError


def benchmarks_dir() -> Path:
    env = os.environ.get("ALIGHT_BENCHMARKS")
    if env:
        d = Path(env)
    else:
        d = Path(alight.__file__).resolve().parents[2] / "benchmarks"
    if not d.is_dir():
        raise InputError(
            f"{d}: no benchmarks folder; alight bench needs a source checkout (or ALIGHT_BENCHMARKS=DIR)"
        )
    return d


def _load(path: Path) -> Any:
    spec = importlib.util.spec_from_file_location(f"alight_bench_{path.stem}", path)
    if spec is None or spec.loader is None:
        raise InputError(f"{path}: cannot load")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def machine() -> dict[str, Any]:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
    }


ANCHOR_ARUCO_MS = 13.0
"""Issue 3's anchor for "this kind of machine": OpenCV's ``ArucoDetector`` (DICT_APRILTAG_36h11) takes about
13 ms per frame of the detector benchmark's rendered 752x480 AprilTag-pad frames, on one core."""


def at_reference_speed(rtf: float, measured_aruco_ms: float) -> float:
    """A real-time factor measured here, stated at the anchor machine's speed: ``rtf * measured / anchor``,
    with ``measured_aruco_ms`` timed in the same run (``bench_detectors.aruco_reference_ms``).

    Why: the real-time-factor targets were set on a machine of this kind where the anchor took
    :data:`ANCHOR_ARUCO_MS`, and this VM's speed changes by 1.5-2x from one session (or half hour) to the
    next. It is an approximation (OpenCV's C++ and alight's Python-and-numba loop need not scale alike),
    reported beside the raw figure, never instead of it."""
    if not (measured_aruco_ms > 0 and math.isfinite(measured_aruco_ms)):
        raise ValueError(f"measured_aruco_ms must be positive and finite, got {measured_aruco_ms}")
    return rtf * measured_aruco_ms / ANCHOR_ARUCO_MS


def load_benchmark(name: str) -> Any:
    """A module of the benchmarks folder by its file stem (for benchmarks that reuse another's frames)."""
    return _load(benchmarks_dir() / f"{name}.py")


def run_benchmarks(*, quick: bool = False, only: list[str] | None = None) -> dict[str, Any]:
    """Run every ``bench_*`` function (or those whose group name is in ``only``) and merge their dicts."""
    d = benchmarks_dir()
    summary: dict[str, Any] = {"alight_version": alight.__version__, "machine": machine(), "quick": quick}
    for path in sorted(d.glob("bench_*.py")):
        group = path.stem.removeprefix("bench_")
        if only is not None and group not in only:
            continue
        module = _load(path)
        fn = getattr(module, path.stem, None)
        if fn is None:
            continue
        t0 = time.perf_counter()
        numbers = fn(quick=quick) if "quick" in fn.__code__.co_varnames else fn()
        summary.update(numbers)
        summary.setdefault("group_wall_s", {})[group] = round(time.perf_counter() - t0, 2)
    return summary
