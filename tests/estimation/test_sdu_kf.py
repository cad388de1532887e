"""Paper 004's relative-position Kalman filter (Sec. IV-B, eq. 1-2): equality with a textbook KF, NEES,
the delay shift, the PlatformEstimator contract, and the latency acceptance test."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from alight.errors import EstimationError
from alight.estimation import PlatformEstimator
from alight.estimation.platform_velocity import PlatformVelocityConfig
from alight.estimation.sdu_kf import SduKalmanFilter, SduKfConfig
from alight.sim.platform import Platform, PlatformConfig
from alight.types import EgoState, PlatformEstimate, PlatformMeasurement

Q_ID = np.array([0.0, 0.0, 0.0, 1.0])
Z3 = np.zeros(3)


def ego(t: float, p: np.ndarray, v: np.ndarray, a: np.ndarray) -> EgoState:
    return EgoState.trusted(t, np.asarray(p, float), np.asarray(v, float), Q_ID, Z3, np.asarray(a, float))


def meas(t: float, p: np.ndarray, cov: np.ndarray) -> PlatformMeasurement:
    return PlatformMeasurement(t=t, p_WP=p, cov_p_WP=cov)


def assert_spd(P: np.ndarray) -> None:
    assert np.all(np.isfinite(P)) and np.allclose(P, P.T, atol=1e-15)
    assert np.linalg.eigvalsh(P).min() > 0


# ---- the filter is eq. (1)-(2) -------------------------------------------------------------------------


@pytest.mark.parametrize("use_cov", [False, True])
def test_equals_a_textbook_kalman_filter_without_delay(use_cov: bool) -> None:
    cfg = SduKfConfig(sigma_imu_mps=0.2, sigma_obs_m=0.15, use_measurement_covariance=use_cov)
    kf = SduKalmanFilter(cfg)
    rng = np.random.default_rng(0)
    t, p, v, a = 0.0, np.array([1.0, -2.0, 5.0]), rng.normal(0, 1, 3), rng.normal(0, 0.5, 3)
    x = P = None
    for k in range(400):
        dt = rng.uniform(0.02, 0.05)
        u_vm = kf.platform_velocity[:2]  # the platform velocity the next prediction uses
        if k > 0:
            t_new = t + dt
            p = p + v * dt + 0.5 * a * dt * dt
            if x is not None:
                G = np.hstack([dt * np.eye(2), 0.5 * dt * dt * np.eye(2), -dt * np.eye(2)])
                x = x + G @ np.concatenate([v[:2], a[:2], u_vm])  # eq. (1), F = I
                P = P + dt * cfg.sigma_imu_mps**2 * np.eye(2)
            v = v + a * dt
            a = rng.normal(0, 0.5, 3)
            t = t_new
        kf.set_ego(ego(t, p, v, a))
        if k % 3 == 0:  # a measurement captured now: no delay
            C = np.diag(rng.uniform(0.005, 0.03, 3))
            C[0, 1] = C[1, 0] = 0.003
            pm = np.array([0.3 * t, -0.2 * t, 0.4]) + rng.normal(0, 0.1, 3)
            assert kf.update(meas(t, pm, C))
            z = p[:2] - pm[:2]
            R = C[:2, :2] if use_cov else cfg.sigma_obs_m**2 * np.eye(2)
            if x is None:
                x, P = z.copy(), cfg.p0_m2 * np.eye(2)
            else:  # eq. (2)
                e = z - x
                S = P + R
                K = P @ np.linalg.inv(S)
                x = x + K @ e
                P = (np.eye(2) - K) @ P
        if x is not None:
            assert np.abs(kf.x - x).max() < 1e-12
            assert np.abs(kf.covariance - P).max() < 1e-12
    assert kf.initialized and kf.n_updates == 134


def test_delay_shift_is_the_predicted_relative_motion() -> None:
    """A measurement captured d seconds ago is moved by the integral of G u over those d seconds; a
    fixed delay_s gives the same shift; without compensation the raw relative observation is used."""
    v, a = np.array([1.2, -0.4, 0.0]), np.array([0.3, 0.1, 0.0])
    cov = np.eye(3) * 0.01
    results = {}
    for name, cfg in {
        "capture": SduKfConfig(),
        "fixed": SduKfConfig(delay_s=0.2),
        "off": SduKfConfig(compensate_delay=False),
        "uav": SduKfConfig(compensation_velocity="uav"),
    }.items():
        kf = SduKalmanFilter(cfg)
        t, p, vv = 0.0, np.array([0.0, 0.0, 4.0]), v.copy()
        for k in range(101):
            kf.set_ego(ego(t, p, vv, a))
            if k in (0, 40, 60):  # a still platform at the origin: its velocity estimate stays 0
                kf.update(meas(t, np.zeros(3), cov))
            dt = 0.01
            p = p + vv * dt + 0.5 * a * dt * dt
            vv = vv + a * dt
            t = round(t + dt, 12)
        # now t_f = 1.0; a measurement of the pad (still at the origin) captured at 0.8 s
        x_before = kf.x
        kf.update(meas(0.8, np.zeros(3), cov))
        # the measurement as the filter used it: innovation + prior
        results[name] = (kf.last_innovation + x_before, kf.last_delay_s)
    p_08 = (np.array([0.0, 0.0, 4.0]) + v * 0.8 + 0.5 * a * 0.64)[:2]  # x_obs: UAV - pad at 0.8 s
    x_now = (np.array([0.0, 0.0, 4.0]) + v * 1.0 + 0.5 * a * 1.0)[:2]  # the relative position at 1.0 s
    z, d = results["capture"]
    assert d == pytest.approx(0.2, abs=1e-12) and results["fixed"][1] == 0.2
    assert np.allclose(z, x_now, atol=1e-12)  # shifted by p(1.0) - p(0.8)
    assert np.allclose(results["fixed"][0], x_now, atol=1e-12)
    assert np.allclose(results["off"][0], p_08, atol=1e-12)
    # the platform is still, so the UAV's displacement alone is the whole relative motion
    assert np.allclose(results["uav"][0], x_now, atol=1e-12)


def test_delay_shift_counts_the_platform_motion() -> None:
    """Relative compensation subtracts the platform's (estimated) displacement; the paper's literal
    UAV-only shift does not."""
    rel, uav = SduKalmanFilter(), SduKalmanFilter(SduKfConfig(compensation_velocity="uav"))
    vp = np.array([1.5, 0.0, 0.0])
    for kf in (rel, uav):
        for k in range(61):  # a hovering UAV, the platform passing at 1.5 m/s, measured at 20 Hz
            t = k * 0.05
            kf.set_ego(ego(t, [0.0, 0.0, 5.0], Z3, Z3))
            if k >= 1:
                kf.update(meas(t - 0.05, vp * (t - 0.05), np.eye(3) * 1e-12))
    assert rel.platform_velocity[:2] == pytest.approx(vp[:2], abs=1e-9)
    assert rel.state(3.0).p_WP[:2] == pytest.approx((vp * 3.0)[:2], abs=1e-6)
    # the UAV-only shift leaves the pad where it was seen: one delay behind
    assert uav.state(3.0).p_WP[0] == pytest.approx(1.5 * 2.95, abs=0.02)


# ---- consistency ---------------------------------------------------------------------------------------


def _nees_run(rng: np.random.Generator, cfg: SduKfConfig, delay_steps: int, n: int) -> float:
    """The paper's model simulated exactly (with the filter's own platform velocity input): NEES of the
    relative position at the last step. Ego at 30 Hz, a measurement every second step."""
    kf = SduKalmanFilter(cfg)
    dt = 1.0 / 30.0
    p, v = np.array([0.0, 0.0, 6.0]), rng.normal(0, 1, 3)
    x_true = rng.normal(0, 2, 2)
    acc = rng.normal(0, 1, (n, 3))
    w = rng.normal(0, cfg.sigma_imu_mps * math.sqrt(dt), (n, 2))
    obs = rng.normal(0, cfg.sigma_obs_m, (n, 2))
    cov = np.eye(3) * cfg.sigma_obs_m**2
    pending: list[tuple[int, PlatformMeasurement]] = []
    for k in range(n):
        a = acc[k]
        kf.set_ego(ego(k * dt, p, v, a))
        if k % 2 == 0:
            pm = np.zeros(3)
            pm[:2] = p[:2] - x_true + obs[k]
            pending.append((k + delay_steps, meas(k * dt, pm, cov)))
        while pending and pending[0][0] <= k:
            kf.update(pending.pop(0)[1])
        if k == n - 1:
            e = kf.x - x_true
            return float(e @ np.linalg.solve(kf.covariance, e))
        vm = kf.platform_velocity[:2]  # what the filter's next prediction uses
        x_true = x_true + v[:2] * dt + 0.5 * a[:2] * dt * dt - vm * dt + w[k]
        p = p + v * dt + 0.5 * a * dt * dt
        v = v + a * dt
    raise AssertionError("unreachable")


@pytest.mark.parametrize(
    "delay_steps,capture_gain,consistent", [(0, True, True), (6, True, True), (6, False, False)]
)
def test_nees_is_chi_square_with_two_dof(delay_steps: int, capture_gain: bool, consistent: bool) -> None:
    """Without delay the filter is eq. (1)-(2) and consistent. With 200 ms of delay, compensated, it is
    consistent with the gain taken at the capture time, and over-confident with eq. (2)'s gain at the
    filter's time (the shifted measurement shares the delay window's process noise with the prior)."""
    cfg = SduKfConfig(sigma_imu_mps=0.15, sigma_obs_m=0.1, capture_time_gain=capture_gain)
    rng = np.random.default_rng(42 + delay_steps)
    runs = 80
    nees = np.array([_nees_run(rng, cfg, delay_steps, 60) for _ in range(runs)])
    lo, hi = chi2.ppf([0.0025, 0.9975], 2 * runs) / runs
    if consistent:
        assert lo < nees.mean() < hi, nees.mean()
    else:
        assert nees.mean() > hi, nees.mean()


# ---- the PlatformEstimator contract --------------------------------------------------------------------


def test_satisfies_the_platform_estimator_contract_without_an_ego_stream() -> None:
    """The registry's contract test, as it will run once the filter is registered: predict + update only
    (the UAV is then at rest at the origin)."""
    est = SduKalmanFilter()
    assert isinstance(est, PlatformEstimator)
    assert not est.initialized and not est.has_measurement
    with pytest.raises(EstimationError):
        est.state(0.0)
    rng = np.random.default_rng(0)
    times = np.linspace(0.0, 3.0, 61)
    for t in times:  # a gentle arc at 2 m/s, delivered 0.1 s late
        p = np.array([5 * math.sin(0.4 * t), 5 * (1 - math.cos(0.4 * t)), 0.4]) + rng.normal(0, 0.05, 3)
        est.predict(t + 0.1)
        assert est.update(meas(float(t), p, np.eye(3) * 0.05**2))
        s = est.state(t + 0.1)
        assert isinstance(s, PlatformEstimate)
        assert all(np.all(np.isfinite(x)) for x in (s.p_WP, s.v_WP, s.a_WP, s.cov_p_WP))
        assert_spd(s.cov_p_WP)
    assert est.initialized
    ahead = times[-1] + np.linspace(0.0, 2.0, 20)
    p, v, a, yaw = est.predict_ahead(ahead)
    assert p.shape == v.shape == a.shape == (20, 3) and yaw.shape == (20,)
    assert np.linalg.norm(v[0]) == pytest.approx(2.0, abs=0.3)
    s = est.state(ahead[5])
    assert np.allclose(s.p_WP, p[5], atol=1e-12) and np.allclose(s.v_WP, v[5]) and s.yaw == yaw[5]
    tr = 3.0
    truth = np.array([5 * math.sin(0.4 * tr), 5 * (1 - math.cos(0.4 * tr))])
    assert np.linalg.norm(est.state(tr).p_WP[:2] - truth) < 0.15
    est.reset()
    assert not est.initialized and not est.has_measurement


def test_covariance_grows_with_the_query_age_and_bad_inputs_raise() -> None:
    kf = SduKalmanFilter(SduKfConfig(history_s=1.0))
    kf.set_ego(ego(0.0, [0, 0, 5.0], Z3, Z3))
    kf.update(meas(0.0, np.zeros(3), np.eye(3) * 0.01))
    kf.set_ego(ego(2.0, [0, 0, 5.0], Z3, Z3))
    c0 = kf.state(2.0).cov_p_WP
    c1 = kf.state(4.0).cov_p_WP
    assert c1[0, 0] - c0[0, 0] == pytest.approx(2.0 * 0.1**2)
    assert not kf.update(meas(0.5, np.zeros(3), np.eye(3) * 0.01))  # older than history_s
    assert kf.n_too_old == 1
    with pytest.raises(EstimationError):
        kf.set_ego(ego(3.0, [0, np.nan, 5.0], Z3, Z3))
    with pytest.raises(ValueError):
        SduKfConfig(compensation_velocity="platform")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        SduKfConfig(sigma_obs_m=0.0)


# ---- acceptance: detection latency at 1.5 m/s ------------------------------------------------------------

SPEED = 1.5
LATENCY_SEEDS = range(6)
# the zamanakos_sdu preset's velocity estimator: the marker's yaw turns the heading (n-fold order 4)
PRESET_VELOCITY = PlatformVelocityConfig(measured_yaw_increments=True, yaw_fold=4)


def _latency_run(  # type: ignore[no-untyped-def]
    latency: float,
    compensate: bool,
    uav: str,
    seed: int = 7,
    velocity: PlatformVelocityConfig = PRESET_VELOCITY,
):
    """A tractor platform (20 m rows, 4 m U-turns) at 1.5 m/s for 24 s (a row, a U-turn, the next row);
    a UAV that either hovers or tracks it (PD, 1 rad/s, damping 0.8, at most 3 m/s^2) from 5 m off; ego
    velocity / acceleration with 0.03 m/s / 0.1 m/s^2 noise at 40 Hz; the pad measured at 20 Hz with 5 cm
    noise, and its yaw as the n-fold marker alone gives it (modulo pi/2, 0.05 rad noise, the pad mounted
    0.3 rad off the vehicle's axis), delivered ``latency`` late (a multiple of the 25 ms step). Returns
    the horizontal error of ``state(t)`` at every measurement time after 3 s, and its along-track part on
    the first row."""
    rng = np.random.default_rng(seed)
    plat = Platform(
        PlatformConfig(
            path="tractor",
            speed_mps=SPEED,
            start_xy_m=(0.0, 0.0),
            start_heading=0.0,
            tractor_row_length_m=20.0,
        )
    )
    dt = 1.0 / 40.0
    ts = np.arange(0.0, 24.0, dt)
    st = plat.states(ts)
    n = ts.size
    n_v, n_a = rng.normal(0, 0.03, (n, 3)), rng.normal(0, 0.1, (n, 3))
    n_m = np.zeros((n, 3))
    n_m[:, :2] = rng.normal(0, 0.05, (n, 2))
    yaw_meas = np.mod(st.yaw + 0.3 + rng.normal(0, 0.05, n), 0.5 * math.pi)
    cov = np.diag([0.05**2, 0.05**2, 0.01])
    kf = SduKalmanFilter(SduKfConfig(compensate_delay=compensate, velocity=velocity))
    p, v = np.array([-4.0, 3.0, 5.0]), np.zeros(3)
    lag = int(round(latency / dt))
    pending: list[tuple[int, PlatformMeasurement]] = []
    errs, along = [], []
    a = np.zeros(3)
    for k in range(n):
        t = float(ts[k])
        if uav == "track":
            a[:2] = (st.p_WP[k] - p)[:2] + 1.6 * (st.v_WP[k] - v)[:2]
            a *= min(1.0, 3.0 / max(float(np.linalg.norm(a)), 1e-12))
        kf.set_ego(ego(t, p, v + n_v[k], a + n_a[k]))
        if k % 2 == 0:
            m = PlatformMeasurement(t=t, p_WP=st.p_WP[k] + n_m[k], cov_p_WP=cov, yaw=float(yaw_meas[k]))
            pending.append((k + lag, m))
        while pending and pending[0][0] <= k:
            kf.update(pending.pop(0)[1])
        if t >= 3.0 and k % 2 == 0:
            d = kf.state(t).p_WP[:2] - st.p_WP[k, :2]
            errs.append(math.hypot(d[0], d[1]))
            if t < 20.0 / SPEED:
                along.append(d[0])  # first row: heading along +x
        p = p + v * dt + 0.5 * a * dt * dt
        v = v + a * dt
    return np.array(errs), np.array(along)


def rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2)))


def latency_table(latency: float) -> dict[str, float]:
    """Worst horizontal error and mean RMS over ``LATENCY_SEEDS`` for both filters and both UAVs; also
    checks that the compensated filter does not see the UAV's motion at all."""
    out: dict[str, float] = {}
    for compensate, tag in ((True, "comp"), (False, "uncomp")):
        for uav in ("hover", "track"):
            runs = [_latency_run(latency, compensate, uav, seed=s) for s in LATENCY_SEEDS]
            out[f"{tag}_{uav}_max"] = max(float(e.max()) for e, _ in runs)
            out[f"{tag}_{uav}_rms"] = float(np.mean([rms(e) for e, _ in runs]))
            out[f"{tag}_{uav}_along"] = float(np.mean([al.mean() for _, al in runs]))
    return out


@pytest.mark.parametrize("latency", [0.10, 0.15, 0.20, 0.25])
def test_latency_compensation_at_1_5_mps(latency: float, record_property) -> None:  # type: ignore[no-untyped-def]
    """The issue's claim, on the worst error of six seeded 24 s runs (a row, a U-turn, the next row).
    Compensated: under 0.2 m at every latency from 100 to 250 ms, hovering or tracking (the relative
    formulation cancels the UAV's motion exactly). Uncompensated: an along-track lag of exactly (relative
    speed) x latency - the platform's whole 1.5 m/s under a hovering UAV, over 0.2 m at its worst from
    100 ms on; a UAV that follows the platform carries most of the relative motion itself, and the
    uncompensated filter's worst case (the approach and the U-turn) passes 0.2 m from 150 ms on.
    The numbers are recorded as properties (``--junitxml``)."""
    numbers = latency_table(latency)
    for key, val in numbers.items():
        record_property(key, round(val, 4))
    assert numbers["comp_hover_max"] < 0.2 and numbers["comp_track_max"] < 0.2, numbers
    assert numbers["comp_hover_max"] == pytest.approx(numbers["comp_track_max"], abs=1e-9)
    # along-track on the straight row: no lag compensated, SPEED x latency uncompensated
    assert abs(numbers["comp_hover_along"]) < 0.02
    assert numbers["uncomp_hover_along"] == pytest.approx(-SPEED * latency, abs=0.02)
    assert numbers["uncomp_hover_max"] > 0.2, numbers
    assert numbers["uncomp_hover_rms"] > 2.0 * numbers["comp_hover_rms"], numbers
    if latency >= 0.15:
        assert numbers["uncomp_track_max"] > 0.2, numbers
    assert numbers["comp_track_max"] < numbers["uncomp_track_max"], numbers


def test_measured_yaw_increments_remove_the_turn_lag() -> None:
    """Through the U-turn the heading from the direction of travel alone trails the vehicle; the marker's
    yaw changes (fold 4, a mounting offset) turn it at once. The compensated filter's worst error is lower
    with them at the longest latency, where the platform velocity's error counts most."""

    def worst(velocity: PlatformVelocityConfig) -> float:
        return max(float(_latency_run(0.25, True, "hover", s, velocity)[0].max()) for s in LATENCY_SEEDS)

    with_yaw, travel_only = worst(PRESET_VELOCITY), worst(PlatformVelocityConfig())
    assert with_yaw < travel_only - 0.03, (with_yaw, travel_only)
