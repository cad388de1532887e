"""The platform's GNSS telemetry (sim/telemetry.py) and its scenario key."""

from __future__ import annotations

import numpy as np
import pytest

from alight.errors import ConfigError
from alight.scenario import scenario_from_dict
from alight.sim.telemetry import PlatformTelemetry, TelemetryConfig


def _fixes(config: TelemetryConfig, seed: int, n: int = 200) -> tuple[PlatformTelemetry, list]:
    tel = PlatformTelemetry(config, np.random.default_rng(seed))
    out = []
    t = 0.0
    while len(out) < n and t < 1000.0:
        if t + 1e-9 >= tel.next_fix_s:
            out.append(tel.fix(t, np.array([8.0 * t, 0.0, 0.5]), np.array([8.0, 0.0, 0.0])))
        t = round(t + 0.01, 6)
    return tel, out


def test_fixes_carry_the_bias_noise_latency_and_rate() -> None:
    tel, fixes = _fixes(TelemetryConfig(rate_hz=10.0, noise_m=0.3, latency_s=0.2, bias_m=2.0), seed=3)
    got = [f for f in fixes if f is not None]
    assert len(got) == len(fixes)  # no dropouts by default
    np.testing.assert_allclose(np.diff([f.t_stamp for f in got]), 0.1, atol=1e-6)
    assert all(f.t_arrival == pytest.approx(f.t_stamp + 0.2) for f in got)
    err = np.array([f.p_WP - np.array([8.0 * f.t_stamp, 0.0, 0.5]) for f in got])
    # the mean error is the constant bias (to 3 sigma of the mean of 200 fixes), the spread the noise
    np.testing.assert_allclose(err.mean(axis=0), tel.bias_W, atol=3 * 0.3 / np.sqrt(len(got)))
    np.testing.assert_allclose(err.std(axis=0), 0.3, rtol=0.2)
    assert float(np.linalg.norm(tel.bias_W)) > 0.0


def test_fixes_are_deterministic_and_dropouts_do_not_shift_the_noise() -> None:
    c = TelemetryConfig(noise_m=0.3, dropout_prob=0.3)
    _, a = _fixes(c, seed=5)
    _, b = _fixes(c, seed=5)
    assert [f is None for f in a] == [f is None for f in b]
    assert 0.15 < np.mean([f is None for f in a]) < 0.45
    for fa, fb in zip(a, b, strict=True):
        if fa is not None and fb is not None:
            np.testing.assert_array_equal(fa.p_WP, fb.p_WP)


def test_bad_values_are_one_line_errors() -> None:
    with pytest.raises(ConfigError) as e:
        scenario_from_dict({"platform": {"telemetry": {"rate_hz": 0.0}}})
    assert "platform.telemetry.rate_hz" in str(e.value)
    with pytest.raises(ConfigError):
        scenario_from_dict({"platform": {"telemetry": {"dropout_prob": 1.5}}})
    with pytest.raises(ConfigError):
        scenario_from_dict({"platform": {"telemetry": {"latency_s": -0.1}}})
    with pytest.raises(ValueError):
        TelemetryConfig(noise_m=float("nan"))


def test_the_telemetry_child_leaves_the_other_seeds_alone() -> None:
    # the runner spawns ten children; the first nine are the ones spawn(9) gave before telemetry
    old = np.random.SeedSequence(7).spawn(9)
    new = np.random.SeedSequence(7).spawn(10)
    for a, b in zip(old, new[:9], strict=True):
        assert np.random.default_rng(a).integers(2**62) == np.random.default_rng(b).integers(2**62)
