"""``alight fly`` compiles the preset's kernels before the mission's clock starts (issue 18, item 3)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import alight.compile.warmup as warmup
import alight.evaluation.mission_io as mission_io
from alight.cli import main

ROOT = Path(__file__).parents[2]


def _record_order(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    calls: list[str] = []
    real_warm_up = warmup.warm_up
    real_fly = mission_io.fly_to_dir

    def warm_up(presets: Any) -> warmup.WarmupReport:
        calls.append("warm_up")
        return real_warm_up(presets)

    def fly_to_dir(*args: Any, **kwargs: Any) -> Any:
        calls.append("fly")
        return real_fly(*args, **kwargs)

    monkeypatch.setattr(warmup, "warm_up", warm_up)
    monkeypatch.setattr(mission_io, "fly_to_dir", fly_to_dir)
    return calls


def test_fly_warms_up_before_the_mission_clock_and_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    calls = _record_order(monkeypatch)
    assert main(["fly", str(ROOT / "examples" / "circle.yaml"), "--out", str(tmp_path)]) == 0
    assert calls == ["warm_up", "fly"]
    err = capsys.readouterr().err
    assert "warm-up (groundtruth, before the mission's clock)" in err
    assert "numba compiled" in err


def test_fly_no_warmup_skips_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _record_order(monkeypatch)
    assert main(["fly", str(ROOT / "examples" / "circle.yaml"), "--out", str(tmp_path), "--no-warmup"]) == 0
    assert calls == ["fly"]


def test_after_the_warm_up_a_mission_compiles_nothing() -> None:
    """What the warm-up leaves compiled is all the README's first mission needs: its clock holds no
    compile (the same process, so this holds on a cold cache as on a warm one)."""
    from alight.evaluation.runner import run_mission
    from alight.scenario import load_scenario

    warmup.warm_up(["groundtruth"])
    with warmup.compile_meter() as meter:
        run_mission(load_scenario(ROOT / "examples" / "circle.yaml"), record=True)
    assert meter.n_signatures == 0, meter.by_kernel


def test_the_compile_meter_takes_nested_compiles_out_of_each_functions_own_time() -> None:
    """A kernel compiles its callee inside its own compile: the callee's time is the kernel's inclusive
    time but not its exclusive time, the exclusive times add up to the outermost compiles' total, and only
    the kernel is an outermost compile."""
    import numba
    import numpy as np

    @numba.njit(cache=False)
    def callee(x: np.ndarray) -> float:
        s = 0.0
        for v in x:
            s += v * v
        return s

    @numba.njit(cache=False)
    def kernel(x: np.ndarray) -> float:
        return callee(x) + np.sum(np.empty(3))

    with warmup.compile_meter() as meter:
        kernel(np.ones(4))
    outer = f"{kernel.py_func.__module__}.{kernel.py_func.__qualname__}"
    inner = f"{callee.py_func.__module__}.{callee.py_func.__qualname__}"
    assert set(meter.by_kernel) == {outer}
    assert meter.by_kernel[outer] == pytest.approx(meter.compile_s)
    assert {outer, inner} <= set(meter.by_function)
    k, c = meter.by_function[outer], meter.by_function[inner]
    assert k.inclusive_s == pytest.approx(meter.compile_s)
    assert 0.0 < c.inclusive_s < k.inclusive_s
    assert k.exclusive_s <= k.inclusive_s - c.inclusive_s + 1e-9
    assert sum(f.exclusive_s for f in meter.by_function.values()) == pytest.approx(meter.compile_s)
    assert sum(f.signatures for f in meter.by_function.values()) == meter.n_signatures >= 2
    with warmup.compile_meter() as again:  # compiled now: a call compiles nothing
        kernel(np.ones(4))
    assert again.n_signatures == 0 and again.by_function == {}
