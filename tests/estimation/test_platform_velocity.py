"""The platform velocity estimator of paper 004 Sec. IV-B: differencing, low-pass filters on speed and
heading, and U-turns (the tractor path)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import EstimationError
from alight.estimation.platform_velocity import (
    PlatformVelocityConfig,
    PlatformVelocityEstimator,
    lowpass_alpha,
)
from alight.sim.platform import Platform, PlatformConfig

DT = 1.0 / 30.0
BASELINE = 0.19  # min_baseline_s; with 30 Hz samples the baseline used is 6 samples = 0.2 s
M = 6


def tractor(speed: float = 1.5) -> Platform:
    return Platform(PlatformConfig(path="tractor", speed_mps=speed, start_xy_m=(0.0, 0.0), start_heading=0.3))


def run(plat: Platform, T: float, est: PlatformVelocityEstimator, rng=None, sigma: float = 0.0):  # type: ignore[no-untyped-def]
    ts = np.arange(0.0, T, DT)
    st = plat.states(ts)
    out = np.full((ts.size, 2), np.nan)
    psi = np.full(ts.size, np.nan)
    cov = np.eye(3) * sigma**2 if sigma > 0 else None
    for k, t in enumerate(ts):
        p = st.p_WP[k] + (rng.normal(0, sigma, 3) if sigma > 0 else 0.0)
        est.update(float(t), p, cov)
        if est.initialized:
            out[k] = est.velocity[:2]
            psi[k] = est.heading
    return ts, st, out, psi


def test_straight_line_is_exact_from_the_first_difference() -> None:
    plat = Platform(PlatformConfig(path="straight", speed_mps=2.3, start_heading=-2.5))
    est = PlatformVelocityEstimator(PlatformVelocityConfig(min_baseline_s=BASELINE))
    ts, st, v, psi = run(plat, 3.0, est)
    k = np.flatnonzero(~np.isnan(psi))
    assert k[0] == M  # the first time a position BASELINE older exists
    assert np.abs(v[k] - st.v_WP[k, :2]).max() < 1e-9
    assert est.speed == pytest.approx(2.3, abs=1e-9) and est.heading == pytest.approx(-2.5, abs=1e-9)


@pytest.mark.parametrize("turn_left", [True, False])
def test_steady_turn_lags_by_the_closed_form(turn_left: bool) -> None:
    """In a steady turn the heading trails by omega (B/2 + dt (1 - alpha) / alpha) and the speed is the
    chord's, 2 R sin(omega B / 2) / B."""
    R, v = 6.0, 1.5
    plat = Platform(
        PlatformConfig(path="circle", speed_mps=v, circle_radius_m=R, turn_left=turn_left, start_heading=1.0)
    )
    cfg = PlatformVelocityConfig(min_baseline_s=BASELINE, cutoff_hz=0.5)
    ts, st, _, psi = run(plat, 12.0, PlatformVelocityEstimator(cfg))
    omega = v / R * (1 if turn_left else -1)
    a = lowpass_alpha(0.5, DT)
    B = M * DT
    lag = omega * (B / 2 + DT * (1 - a) / a)
    k = ts > 8.0  # transients decay as (1 - alpha)^k: ~1e-6 rad after 8 s
    err = np.array([math.remainder(p - y, 2 * math.pi) for p, y in zip(psi[k], st.yaw[k], strict=True)])
    assert np.abs(err + lag).max() < 1e-5
    est = PlatformVelocityEstimator(cfg)
    run(plat, 12.0, est)
    assert est.speed == pytest.approx(2 * R * abs(math.sin(omega * B / 2)) / B, abs=1e-9)


def _noise_gain(alpha: float, m: int, n: int = 4000) -> float:
    """sqrt(sum c_i^2) of the filtered difference: y = sum_i c_i e_{k-i} (per unit position noise / B)."""
    i = np.arange(n)
    c = alpha * (1 - alpha) ** i
    c[m:] -= alpha * (1 - alpha) ** (i[m:] - m)
    return float(np.sqrt(np.sum(c**2)))


def test_u_turns_heading_follows_through_180_deg_and_error_stays_bounded() -> None:
    plat = tractor()
    sigma = 0.05
    cfg = PlatformVelocityConfig(min_baseline_s=BASELINE)
    ts, st, v, psi = run(plat, 60.0, PlatformVelocityEstimator(cfg), np.random.default_rng(11), sigma)
    ok = ~np.isnan(psi)
    # two U-turns (left then right) in 60 s: rows of 30 m, turns of pi * 4 m at 1.5 m/s
    assert np.ptp(np.unwrap(st.yaw)) == pytest.approx(math.pi, abs=1e-6)
    un = np.unwrap(psi[ok])
    true_un = np.unwrap(st.yaw[ok])
    # the estimate turns by the same 180 deg and back (no wrap-around jumps)
    assert np.abs(np.diff(un)).max() < 0.2
    first_turn_end = np.searchsorted(ts[ok], (30 + 4 * math.pi) / 1.5 + 3.0)
    assert un[first_turn_end] - un[0] == pytest.approx(true_un[first_turn_end] - true_un[0], abs=0.1)
    # the velocity error: the steady-turn lag plus 5 sigma of the filtered noise (both closed form)
    a = lowpass_alpha(cfg.cutoff_hz, DT)
    omega = 1.5 / 4.0
    lag_speed = 1.5 * omega * (M * DT / 2 + DT * (1 - a) / a)
    sigma_v = sigma / (M * DT) * _noise_gain(a, M)
    err = np.linalg.norm(v[ok] - st.v_WP[ok, :2], axis=1)
    assert err.max() < lag_speed + 5 * sigma_v
    # on the straight rows (away from the turns) only the noise remains
    straight = ok & (np.abs(st.yaw_rate) < 1e-12)
    straight &= np.convolve(straight, np.ones(90), "same") > 89.5  # 1.5 s clear of a turn
    err_s = np.linalg.norm(v[straight] - st.v_WP[straight, :2], axis=1)
    assert np.sqrt(np.mean(err_s**2)) < 2.0 * sigma_v


def test_a_vector_lowpass_would_shrink_the_speed_in_the_u_turn() -> None:
    """Why speed and heading are filtered apart: the vector filter's steady-turn gain is below one."""
    plat = tractor()
    cfg = PlatformVelocityConfig(min_baseline_s=BASELINE, cutoff_hz=0.1)
    ts, st, v, _ = run(plat, 28.0, PlatformVelocityEstimator(cfg))
    a = lowpass_alpha(0.1, DT)
    mid = np.searchsorted(ts, (30 + 2 * math.pi) / 1.5)  # middle of the first U-turn
    speed = float(np.linalg.norm(v[mid]))
    chord = 2 * 4.0 * math.sin(1.5 / 4.0 * M * DT / 2) / (M * DT)
    assert speed == pytest.approx(chord, abs=2e-3)  # speed kept (after 4 s of a 1.6 s filter)
    # the vector filter of the same raw velocities, in closed form: |H(e^{i omega dt})| < 1
    w = 1.5 / 4.0 * DT
    gain = a / abs(1 - (1 - a) * np.exp(-1j * w))
    assert gain < 0.9


def test_debias_removes_the_noise_share_of_the_speed() -> None:
    plat = Platform(PlatformConfig(path="straight", speed_mps=0.5))
    sigma = 0.05
    rng = np.random.default_rng(3)
    speeds = {}
    for debias in (True, False):
        est = PlatformVelocityEstimator(PlatformVelocityConfig(min_baseline_s=BASELINE, debias=debias))
        ts = np.arange(0.0, 200.0, DT)
        st = plat.states(ts)
        s2 = []
        for k, t in enumerate(ts):
            est.update(float(t), st.p_WP[k] + rng.normal(0, sigma, 3), np.eye(3) * sigma**2)
            if t > 5.0:
                s2.append(est.speed**2)
        speeds[debias] = float(np.mean(s2))
    B = M * DT
    assert speeds[True] == pytest.approx(0.25, abs=0.02)
    # without it |v|^2 carries tr(Sigma_v) = 2 * 2 sigma^2 / B^2 on average
    assert speeds[False] == pytest.approx(0.25 + 4 * sigma**2 / B**2, abs=0.02)


def test_measured_yaw_with_fold_and_gaps_and_bad_input() -> None:
    est = PlatformVelocityEstimator(
        PlatformVelocityConfig(use_measured_yaw=True, yaw_fold=4, min_baseline_s=0.0)
    )
    est.update(0.0, np.array([0.0, 0.0]), yaw=0.1)
    assert est.heading == pytest.approx(0.1)
    # 0.1 + pi/2 is the same 4-fold yaw: resolved to the candidate nearest the heading
    est.update(0.1, np.array([0.1, 0.0]), yaw=0.1 + math.pi / 2)
    assert est.heading == pytest.approx(0.1, abs=1e-12)
    assert est.initialized and est.speed == pytest.approx(1.0)
    # a gap longer than max_baseline_s: no difference across it
    assert not est.update(5.0, np.array([3.0, 0.0]))
    assert est.update(5.5, np.array([3.5, 0.0]))
    # older than the last: ignored
    assert not est.update(5.2, np.array([0.0, 0.0]))
    with pytest.raises(EstimationError):
        est.update(6.0, np.array([np.nan, 0.0]))
    with pytest.raises(ValueError):
        PlatformVelocityConfig(min_baseline_s=2.0, max_baseline_s=1.0)
    est.reset()
    assert not est.initialized and est.speed == 0.0 and np.all(est.velocity == 0.0)


def test_a_parked_platform_is_initialised_with_zero_velocity() -> None:
    est = PlatformVelocityEstimator(PlatformVelocityConfig(min_baseline_s=BASELINE))
    rng = np.random.default_rng(5)
    for k in range(30):
        est.update(k * DT, np.array([2.0, 1.0, 0.0]) + rng.normal(0, 0.01, 3), np.eye(3) * 1e-4)
    assert est.initialized and est.speed < 0.1 and np.all(est.velocity == 0.0)


def _run_with_marker_yaw(  # type: ignore[no-untyped-def]
    plat: Platform, T: float, est: PlatformVelocityEstimator, offset: float, drop_every: int = 0
):
    """Like ``run``, noiseless, with the pad yaw as a 4-fold marker gives it: modulo pi/2, mounted
    ``offset`` off the vehicle's axis; every ``drop_every``-th measurement has no yaw."""
    ts = np.arange(0.0, T, DT)
    st = plat.states(ts)
    psi = np.full(ts.size, np.nan)
    for k, t in enumerate(ts):
        yaw = None if drop_every and k % drop_every == 0 else float(np.mod(st.yaw[k] + offset, 0.5 * math.pi))
        est.update(float(t), st.p_WP[k], yaw=yaw)
        if est.initialized:
            psi[k] = est.heading
    return ts, st, psi


@pytest.mark.parametrize("turn_left", [True, False])
def test_measured_yaw_increments_remove_the_steady_turn_lag(turn_left: bool) -> None:
    """With the marker's yaw changes turning the heading, a steady turn has no heading lag at all (the
    chord's middle brought to the newest time by the measured turn), whatever the fold and mount offset;
    the travel direction alone trails by the closed form of ``test_steady_turn_lags_by_the_closed_form``."""
    R, v = 6.0, 1.5
    plat = Platform(
        PlatformConfig(path="circle", speed_mps=v, circle_radius_m=R, turn_left=turn_left, start_heading=1.0)
    )
    cfg = PlatformVelocityConfig(min_baseline_s=BASELINE, measured_yaw_increments=True, yaw_fold=4)
    ts, st, psi = _run_with_marker_yaw(plat, 12.0, PlatformVelocityEstimator(cfg), offset=0.7)
    k = ts > 8.0
    err = np.array([math.remainder(p - y, 2 * math.pi) for p, y in zip(psi[k], st.yaw[k], strict=True)])
    assert np.abs(err).max() < 1e-5
    with pytest.raises(ValueError, match="exclusive"):
        PlatformVelocityConfig(use_measured_yaw=True, measured_yaw_increments=True)


def test_measured_yaw_increments_follow_a_u_turn_without_lag() -> None:
    """Through the tractor's U-turns (180 deg at 0.375 rad/s) the heading with the marker's yaw changes
    stays within 0.03 rad, where the travel direction alone trails by ~0.15 rad at
    the turn's entry; a gap in the yaw (a frame without the marker) only skips an increment."""
    plat = tractor()
    base = PlatformVelocityConfig(min_baseline_s=BASELINE)
    inc = PlatformVelocityConfig(min_baseline_s=BASELINE, measured_yaw_increments=True, yaw_fold=4)
    ts, st, psi_inc = _run_with_marker_yaw(plat, 60.0, PlatformVelocityEstimator(inc), -0.4, drop_every=7)
    _, _, _, psi_base = run(plat, 60.0, PlatformVelocityEstimator(base))
    ok = ~np.isnan(psi_inc) & ~np.isnan(psi_base) & (ts > 2.0)

    def heading_error(psi: np.ndarray) -> np.ndarray:
        return np.abs([math.remainder(p - y, 2 * math.pi) for p, y in zip(psi[ok], st.yaw[ok], strict=True)])

    e_inc, e_base = heading_error(psi_inc), heading_error(psi_base)
    assert e_base.max() > 0.12
    assert e_inc.max() < 0.03
