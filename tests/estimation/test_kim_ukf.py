"""Paper 003's UKF (eq. 10-27): the paper's root selection, the fisheye measurement
model, the process model, NEES/NIS consistency on simulated flights, re-acquisition after 2 s out of view,
the world-measurement path against a Kalman filter, and the PlatformEstimator contract."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from alight.cameras.omni import OmniCamera, project_exact_point, project_exact_work
from alight.cameras.pinhole import CameraMount, PinholeCamera
from alight.errors import ConfigError, EstimationError
from alight.estimation import PlatformEstimator
from alight.estimation.kim_ukf import (
    KimUkf,
    KimUkfConfig,
    euler_zyx,
    kim_camera_h,
    kim_fisheye_h,
    kim_process_noise,
    kim_transition,
    rotation_zyx,
)
from alight.types import PlatformEstimate, PlatformMeasurement, rotmat_to_quat

# calib_results_0.txt of testdata/real/fisheye_ocamcalib (MIT, matsuren/ocamcalib_undistort): the five
# data lines, so the tests run without the test data; test_embedded_calibration_matches_the_file checks it
CALIB_0 = """
5 -4.714441e+02 0.000000e+00 7.356108e-04 -3.773045e-07 5.800006e-10
10 772.405470 504.754051 7.034666 45.327180 54.651570 0.458049 -7.873745 15.588713 13.743404 2.968883
794.308657 798.175741
1.000305 -0.000277 -0.000925
1600 1600
"""


def parse_calib(text: str) -> OmniCamera:
    """The parts of an OCamCalib calib_results.txt the UKF needs: ss, centre, affine, size."""
    rows = [ln.split() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    ss = np.array([float(v) for v in rows[0][1:]])
    assert len(ss) == int(float(rows[0][0]))
    xc, yc = (float(v) for v in rows[2])
    c, d, e = (float(v) for v in rows[3])
    h, w = (int(float(v)) for v in rows[4])
    return OmniCamera(width=w, height=h, ss=ss, xc=xc, yc=yc, c=c, d=d, e=e, rho_max=800.0)


LENS = parse_calib(CALIB_0)
MOUNT = CameraMount.downward()


def calib_file() -> Path:
    root = Path(
        os.environ.get(
            "ALIGHT_TESTDATA", Path(__file__).resolve().parents[2] / ".." / "shared" / "testdata" / "real"
        )
    )
    return root / "fisheye_ocamcalib" / "calib_results_0.txt"


def test_embedded_calibration_matches_the_file() -> None:
    f = calib_file()
    if not f.is_file():
        pytest.skip(f"test data not found at {f}")
    lens = parse_calib(f.read_text())
    assert np.array_equal(lens.ss, LENS.ss) and (lens.xc, lens.yc, lens.c, lens.d, lens.e) == (
        LENS.xc, LENS.yc, LENS.c, LENS.d, LENS.e
    )  # fmt: skip


# --------------------------------------------------------------------------------------------------
# Roots and root selection (eq. 24)
# --------------------------------------------------------------------------------------------------


def test_paper_root_selection_picks_the_root_nearest_the_previous_measurement() -> None:
    """A lens whose eq. 24 has three positive roots for one direction: a4 (rho - 300)(rho - 900)
    (rho - 1400)(rho + 500) = f(rho) - K0 rho. The paper takes the root nearest rho_prev."""
    a4, K0 = 1e-9, 0.05
    ss = np.real(np.poly([300.0, 900.0, 1400.0, -500.0]))[::-1] * a4
    ss[1] += K0
    work = project_exact_work(ss.size)
    # a point in C with -Z / r = K0 and direction (1, 0) in the image plane: X = 1, Z = -K0
    for rho_prev, expected in ((880.0, 900.0), (1300.0, 1400.0), (10.0, 300.0), (math.nan, 300.0)):
        u, v = project_exact_point(
            1.0, 0.0, -K0, ss, 1500.0, 1500.0, 1.0, 0.0, 0.0, rho_prev, math.inf, *work
        )
        assert u - 1500.0 == pytest.approx(expected, rel=1e-9) and v == pytest.approx(1500.0)


def test_fisheye_projection_round_trip_and_agreement_with_omni_camera() -> None:
    rng = np.random.default_rng(0)
    ang = rng.uniform(0, math.radians(92), 500)
    phi = rng.uniform(-math.pi, math.pi, 500)
    rays = np.stack([np.sin(ang) * np.cos(phi), np.sin(ang) * np.sin(phi), np.cos(ang)], axis=1)
    px = LENS.project_exact(rays * rng.uniform(0.5, 20, (500, 1)))
    assert np.isfinite(px).all()
    back = LENS.unproject(px)
    assert np.allclose(back, rays, atol=1e-12)
    assert np.allclose(LENS.project_exact(back), px, atol=1e-9)
    # the invpol projection (Newton-polished) agrees with the exact root
    assert np.allclose(LENS.project(back), px, atol=1e-6)


def test_quartic_model_refuses_a_pinhole() -> None:
    with pytest.raises(ConfigError):
        KimUkf(KimUkfConfig(measurement_model="quartic"), camera=PinholeCamera.default_downward())


# --------------------------------------------------------------------------------------------------
# Models
# --------------------------------------------------------------------------------------------------


def test_euler_angles_round_trip_and_downward_camera() -> None:
    rng = np.random.default_rng(1)
    for _ in range(50):
        eta = rng.uniform([-3.1, -1.5, -3.1], [3.1, 1.5, 3.1])
        R = rotation_zyx(eta)
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-12) and np.linalg.det(R) == pytest.approx(1.0)
        assert np.allclose(euler_zyx(R), eta, atol=1e-9)
    assert np.allclose(euler_zyx(MOUNT.R_BC), [math.pi, 0.0, -math.pi / 2])


def test_transition_is_eq16_and_noise_is_the_white_acceleration_integral() -> None:
    rng = np.random.default_rng(2)
    X = rng.normal(size=(15, 7))
    u = rng.normal(size=7)
    dt = 0.07
    A = np.zeros((7, 7))
    A[0:4, 0:4] = np.block([[np.eye(2), dt * np.eye(2)], [np.zeros((2, 2)), np.eye(2)]])
    assert np.allclose(kim_transition(X, dt, u), X @ A.T + u, atol=1e-14)
    # Q(dt) = int_0^dt Phi(s) G G^T Phi(s)^T q^2 ds, G = (0, 1) per axis: by a fine midpoint sum
    q, s = 0.8, (np.arange(4000) + 0.5) * dt / 4000
    g = np.stack([s, np.ones_like(s)])
    Qx = (g @ g.T) * q**2 * dt / 4000
    Q = kim_process_noise(dt, q, 0.02)
    assert np.allclose(Q[np.ix_([0, 2], [0, 2])], Qx, rtol=1e-6)
    assert np.allclose(Q[4:, 4:], 0.02**2 * np.eye(3)) and Q[0, 1] == 0 and Q[0, 4] == 0


def test_measurement_model_is_the_lens_projection_of_the_relative_position() -> None:
    rng = np.random.default_rng(3)
    X = np.zeros((20, 7))
    X[:, 0:2] = rng.uniform(-8, 8, (20, 2))
    X[:, 4:7] = euler_zyx(MOUNT.R_BC) + rng.normal(0, 0.2, (20, 3))
    H = 6.0
    Z = kim_fisheye_h(X, H, LENS, math.nan)
    for i in range(20):
        x_C = rotation_zyx(X[i, 4:7]).T @ np.array([X[i, 0], X[i, 1], -H])
        assert np.allclose(Z[i], LENS.project_exact(x_C[None])[0], atol=1e-9)
    # the same through the camera-model path (the smallest root, the only one for this lens)
    assert np.allclose(kim_camera_h(X, H, LENS), Z, atol=1e-6)  # project: invpol + Newton


# --------------------------------------------------------------------------------------------------
# Simulated flights
# --------------------------------------------------------------------------------------------------


class Ego:
    """What update_pixel reads of an ego state."""

    def __init__(self, p: np.ndarray, v: np.ndarray, R: np.ndarray) -> None:
        self.p_WB, self.v_WB, self.R_WB = p, v, R


def vehicle(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A vehicle circling 3 m around the origin at 8-10 m, rolling, pitching and turning."""
    w = 0.4
    p = np.array([3 * math.cos(w * t), 3 * math.sin(w * t), 9.0 + math.sin(0.3 * t)])
    v = np.array([-3 * w * math.sin(w * t), 3 * w * math.cos(w * t), 0.3 * math.cos(0.3 * t)])
    R_WB = rotation_zyx(np.array([0.15 * math.sin(1.1 * t), 0.1 * math.cos(0.7 * t), 0.3 * t]))
    return p, v, R_WB


def fly(
    seed: int,
    cfg: KimUkfConfig,
    *,
    n_steps: int = 80,
    dt: float = 0.05,
    q: float = 0.3,
    gap: tuple[float, float] | None = None,
    v_target: tuple[float, float] = (1.5, 0.5),
) -> dict:
    """Target at constant velocity plus white acceleration ``q`` (exact discrete model), pixels from the
    exact lens with ``pixel_std`` noise, the ego's attitude with ``attitude_std`` per Euler angle and its
    height with ``height_std``, exactly the noises the filter assumes."""
    rng = np.random.default_rng(seed)
    f = KimUkf(cfg, camera=LENS, mount=MOUNT)
    pT = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), 0.0])
    vT = np.array([v_target[0], v_target[1], 0.0])
    Lq = np.linalg.cholesky(np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])) * q
    out: dict = {"nees": [], "nis": [], "t": [], "err": [], "accepted": [], "filter": f, "sd": []}
    for k in range(n_steps):
        t = k * dt
        p, v, R_WB = vehicle(t)
        if k > 0:
            w = Lq @ rng.normal(size=(2, 2))  # column i: (position, velocity) noise of axis i
            pT[:2] += vT[:2] * dt + w[0]
            vT[:2] += w[1]
        R_WC = R_WB @ MOUNT.R_BC
        rel = pT - p
        px = LENS.project_exact((R_WC.T @ rel)[None])[0] + rng.normal(0, cfg.pixel_std, 2)
        eta = euler_zyx(R_WC) + rng.normal(0, cfg.attitude_std, 3)
        ego = Ego(p + [0.0, 0.0, rng.normal(0, cfg.height_std)], v, rotation_zyx(eta) @ MOUNT.R_BC.T)
        if gap is not None and gap[0] <= t < gap[1]:
            continue
        accepted = f.update_pixel(t, px, ego)
        e = np.r_[rel[:2] - f.x[0:2], (vT - v)[:2] - f.x[2:4]]
        P = f.covariance[:4, :4]
        out["accepted"].append(accepted)
        out["t"].append(t)
        out["err"].append(np.linalg.norm(e[:2]))
        out["sd"].append(math.sqrt(np.linalg.eigvalsh(P[:2, :2])[-1]))
        out["nees"].append(e @ np.linalg.solve(P, e))
        out["nis"].append(f.last_nis if k > 0 else math.nan)
    out["pT"], out["vT"] = pT, vT
    return out


@pytest.mark.parametrize("update", ["standard", "joseph"])
@pytest.mark.parametrize("scheme", ["merwe", "cubature", "simplex"])
def test_compiled_step_is_the_generic_ukf(scheme: str, update: str) -> None:
    """kim_pixel_step (one compiled predict + update) against ukf_predict + ukf_update with the same
    models, on a simulated flight with a gap (long prediction) and a gated outlier."""
    cfg = KimUkfConfig(
        sigma_points=scheme, covariance_update=update, pixel_std=1.0, attitude_std=0.01, alpha=0.7
    )
    fast = KimUkf(cfg, camera=LENS, mount=MOUNT)
    slow = KimUkf(cfg, camera=LENS, mount=MOUNT)
    slow.use_compiled = False
    assert fast.use_compiled
    rng = np.random.default_rng(9)
    for k in range(40):
        t = 0.05 * k + (1.0 if k >= 20 else 0.0)
        p, v, R_WB = vehicle(t)
        pT = np.array([1.0 + 1.2 * t, -0.5 + 0.3 * t, 0.0])
        px = LENS.project_exact(((R_WB @ MOUNT.R_BC).T @ (pT - p))[None])[0] + rng.normal(0, 1.0, 2)
        if k == 30:
            px = px + 80.0  # an outlier for the gate
        a = fast.update_pixel(t, px, Ego(p, v, R_WB))
        b = slow.update_pixel(t, px, Ego(p, v, R_WB))
        assert a == b and (k != 30 or not a)
        np.testing.assert_allclose(fast.last_nis, slow.last_nis, rtol=1e-9)  # NaN before the first update
        assert np.allclose(fast.x, slow.x, rtol=0, atol=1e-10)
        assert np.allclose(fast.covariance, slow.covariance, rtol=0, atol=1e-12)


CONSISTENCY_CFG = KimUkfConfig(accel_noise=0.3, pixel_std=1.0, attitude_std=0.01, height_std=0.05)


@pytest.mark.parametrize("scheme", ["merwe", "cubature"])
def test_nees_and_nis_are_consistent_over_monte_carlo_runs(scheme: str) -> None:
    """50 runs of 4 s: the per-step average NEES (4 dof: relative position and velocity) and NIS (2 dof)
    against the two-sided 95 % chi-square band of a 50-run average."""
    N = 50
    # no gate: a 0.999 gate drops ~4 of the 4000 innovations, and the test is about the filter's statistics
    cfg = KimUkfConfig(**{**CONSISTENCY_CFG.__dict__, "sigma_points": scheme, "gating": False})
    runs = [fly(s, cfg) for s in range(N)]
    assert all(all(r["accepted"]) for r in runs)
    nees = np.array([r["nees"] for r in runs])  # (N, steps)
    nis = np.array([r["nis"][1:] for r in runs])
    lo4, hi4 = chi2.ppf([0.025, 0.975], 4 * N) / N
    lo2, hi2 = chi2.ppf([0.025, 0.975], 2 * N) / N
    anees, anis = nees.mean(axis=0), nis.mean(axis=0)
    assert lo4 < anees.mean() < hi4
    assert lo2 < anis.mean() < hi2
    # 95 % of the steps should fall in the band; allow for the steps' correlation
    assert np.mean((anees > lo4) & (anees < hi4)) > 0.85
    assert np.mean((anis > lo2) & (anis < hi2)) > 0.85


def test_reacquires_after_two_seconds_out_of_view() -> None:
    """Constant-velocity target (1.5 m/s), out of view from 2 s to 4 s: the prediction carries it, the gate
    accepts the first pixel after the gap, and the error is small again right after."""
    cfg = KimUkfConfig(accel_noise=0.3, pixel_std=1.0, attitude_std=0.005, height_std=0.02)
    for seed in range(5):
        r = fly(seed, cfg, n_steps=140, q=0.0, gap=(2.0, 4.0))
        f = r["filter"]
        t = np.array(r["t"])
        k = int(np.argmax(t >= 4.0))
        assert t[k] == pytest.approx(4.0) and t[k - 1] < 2.0  # the gap is 2 s without an update
        assert all(r["accepted"]) and f.n_rejected == 0 and f.n_reinitializations == 0
        assert r["nis"][k] < chi2.ppf(0.999, 2)  # the re-acquired pixel passes the gate
        # the error at re-acquisition stays inside 3 sigma of the filter's own position uncertainty
        assert r["err"][k] < 3 * r["sd"][k]
        assert max(r["err"][k + 10 :]) < 0.25  # and 0.5 s later the track is as good as before the gap
        assert f.initialized


def test_gate_rejects_a_false_lock_and_reinitialises_when_it_persists() -> None:
    cfg = KimUkfConfig(
        accel_noise=0.3, pixel_std=1.0, attitude_std=0.005, height_std=0.02, reinit_after_rejections=3
    )
    r = fly(0, cfg, n_steps=40, q=0.0)
    f = r["filter"]
    t0 = 40 * 0.05
    p, v, R_WB = vehicle(t0)
    state_before = f.x
    wrong = np.array([LENS.yc + 300.0, LENS.xc - 200.0])  # a red object elsewhere in the image
    assert not f.update_pixel(t0, wrong, Ego(p, v, R_WB))
    assert f.n_rejected == 1 and np.array_equal(f.x, state_before)
    assert not f.update_pixel(t0 + 0.05, wrong, Ego(p, v, R_WB))
    assert not f.update_pixel(t0 + 0.1, wrong, Ego(p, v, R_WB))  # the third: track restarts there
    assert f.n_reinitializations == 1 and f.t_filter == pytest.approx(t0 + 0.1)
    assert not f.initialized  # the velocity is unknown again


def test_invalid_inputs_leave_the_filter_unchanged() -> None:
    r = fly(1, CONSISTENCY_CFG, n_steps=10)
    f = r["filter"]
    x, P, t = f.x, f.covariance, f.t_filter
    p, v, R = vehicle(t + 0.05)
    assert not f.update_pixel(t + 0.05, np.array([math.nan, 3.0]), Ego(p, v, R))
    assert not f.update_pixel(t - 0.05, np.array([800.0, 800.0]), Ego(p, v, R))  # out of order
    assert not f.update_pixel(t + 0.05, np.array([800.0, 800.0]), Ego(np.array([0.0, 0.0, -1.0]), v, R))
    assert f.n_out_of_order == 1 and f.n_invalid == 2
    assert np.array_equal(f.x, x) and np.array_equal(f.covariance, P) and f.t_filter == t
    with pytest.raises(ConfigError):
        KimUkf().update_pixel(0.0, np.zeros(2), Ego(p, v, R))


def test_predicted_pixel_and_gate_radius_cover_the_next_measurement() -> None:
    """predict_pixel (for the detector's gate) at the next frame: the true pixel lies within the 3-sigma
    radius, and predicting does not change the filter."""
    for seed in range(20):
        r = fly(seed, CONSISTENCY_CFG, n_steps=30, q=0.0)
        f = r["filter"]
        x_before = f.x
        t = f.t_filter + 0.05
        p, v, R_WB = vehicle(t)
        pred = f.predict_pixel(t, Ego(p, v, R_WB), n_sigma=3.0)
        assert pred is not None and np.array_equal(f.x, x_before)
        px, radius = pred
        pT_next = r["pT"] + r["vT"] * 0.05
        true_px = LENS.project_exact(((R_WB @ MOUNT.R_BC).T @ (pT_next - p))[None])[0]
        assert 0 < np.linalg.norm(px - true_px) < radius < 30


# --------------------------------------------------------------------------------------------------
# World-frame measurements and the PlatformEstimator contract
# --------------------------------------------------------------------------------------------------


def test_world_measurements_give_the_kalman_filter() -> None:
    """With world-frame measurements the model is linear: the UKF must equal a constant-velocity Kalman
    filter on (p_x, p_y, v_x, v_y) to 1e-9, and the height a scalar random-walk filter."""
    cfg = KimUkfConfig(accel_noise=0.7, vertical_noise=0.1, init_speed_std=2.0, gating=False)
    f = KimUkf(cfg)
    rng = np.random.default_rng(4)
    x = P = None
    z = zv = 0.0
    t_prev = 0.0
    for k in range(30):
        t = 0.1 * k + rng.uniform(0, 0.05)
        A = rng.normal(size=(3, 3)) * 0.05
        cov = A @ A.T + 1e-3 * np.eye(3)
        meas = rng.normal(size=3) + [0.5 * t, -0.2 * t, 1.0]
        assert f.update(PlatformMeasurement(t=t, p_WP=meas, cov_p_WP=cov))
        if x is None:
            x = np.r_[meas[:2], 0.0, 0.0]
            P = np.diag([0, 0, 4.0, 4.0]).astype(float)
            P[:2, :2] = cov[:2, :2]
            z, zv = meas[2], cov[2, 2]
        else:
            dt = t - t_prev
            F = np.block([[np.eye(2), dt * np.eye(2)], [np.zeros((2, 2)), np.eye(2)]])
            x, P = F @ x, F @ P @ F.T + kim_process_noise(dt, 0.7, 0.0)[:4, :4]
            Hm = np.eye(2, 4)
            S = Hm @ P @ Hm.T + cov[:2, :2]
            K = P @ Hm.T @ np.linalg.inv(S)
            x = x + K @ (meas[:2] - Hm @ x)
            P = (np.eye(4) - K @ Hm) @ P
            zp = zv + 0.1**2 * dt
            z, zv = z + zp / (zp + cov[2, 2]) * (meas[2] - z), zp * cov[2, 2] / (zp + cov[2, 2])
        t_prev = t
        s = f.state(t)
        assert np.allclose(s.p_WP, [x[0], x[1], z], atol=1e-9)
        assert np.allclose(s.v_WP[:2], x[2:], atol=1e-9)
        assert np.allclose(s.cov_p_WP[:2, :2], P[:2, :2], atol=1e-9)
        assert s.cov_p_WP[2, 2] == pytest.approx(zv, abs=1e-12)


def test_satisfies_the_platform_estimator_contract() -> None:
    est = KimUkf()
    assert isinstance(est, PlatformEstimator)
    assert not est.initialized and not est.has_measurement
    with pytest.raises(EstimationError):
        est.state(0.0)
    rng = np.random.default_rng(0)
    times = np.linspace(0.0, 3.0, 61)
    for t in times:  # the arc of the shared contract test, 2 m/s
        p = np.array([5 * math.sin(0.4 * t), 5 * (1 - math.cos(0.4 * t)), 0.4]) + rng.normal(0, 0.05, 3)
        est.predict(t + 0.1)
        est.update(PlatformMeasurement(t=float(t), p_WP=p, cov_p_WP=np.eye(3) * 0.05**2))
        s = est.state(t + 0.1)
        assert isinstance(s, PlatformEstimate) and np.isfinite(s.cov_p_WP).all()
        assert np.linalg.eigvalsh(s.cov_p_WP).min() > 0
    assert est.initialized
    ahead = times[-1] + np.linspace(0.0, 2.0, 20)
    p, v, a, yaw = est.predict_ahead(ahead)
    assert p.shape == v.shape == a.shape == (20, 3) and yaw.shape == (20,)
    assert np.linalg.norm(v[0]) == pytest.approx(2.0, abs=0.3)
    s = est.state(ahead[7])
    assert np.allclose(s.p_WP, p[7]) and np.allclose(s.v_WP, v[7]) and s.yaw == pytest.approx(yaw[7])
    assert not est.update(PlatformMeasurement(t=1.0, p_WP=np.zeros(3), cov_p_WP=np.eye(3)))  # out of order
    est.reset()
    assert not est.initialized and not est.has_measurement


def test_world_and_pixel_measurements_mix() -> None:
    """A pixel after world measurements re-anchors the relative state to the camera: the world-frame
    estimate is continuous across the switch (the anchor moves, p_WP does not)."""
    f = KimUkf(CONSISTENCY_CFG, camera=LENS, mount=MOUNT)
    for k in range(10):
        t = 0.05 * k
        f.update(PlatformMeasurement(t=t, p_WP=[1.0 + 1.5 * t, 0.5 * t, 0.0], cov_p_WP=np.eye(3) * 0.01))
    t = 0.5
    p, v, R_WB = vehicle(t)
    before = f.state(t).p_WP
    rel = np.array([1.0 + 1.5 * t, 0.5 * t, 0.0]) - p
    px = LENS.project_exact(((R_WB @ MOUNT.R_BC).T @ rel)[None])[0]
    assert f.update_pixel(t, px, Ego(p, v, R_WB))
    after = f.state(t).p_WP
    assert np.allclose(f.anchor[0], p)
    assert np.linalg.norm(after[:2] - before[:2]) < 0.1
    assert (
        np.linalg.norm(after[:2] - (rel[:2] + p[:2])) < np.linalg.norm(before[:2] - (rel[:2] + p[:2])) + 1e-9
    )


def test_ego_state_message_is_accepted() -> None:
    from alight.types import EgoState

    p, v, R_WB = vehicle(0.0)
    ego = EgoState(t=0.0, p_WB=p, v_WB=v, q_WB=rotmat_to_quat(R_WB), w_WB_B=np.zeros(3))
    f = KimUkf(CONSISTENCY_CFG, camera=LENS)
    px = LENS.project_exact(((R_WB @ MOUNT.R_BC).T @ (np.array([1.0, 2.0, 0.0]) - p))[None])[0]
    assert f.update_pixel(0.0, px, ego)
    # the initial position is the unscented mean of flat-earth over the noises, not the noise-free point:
    # within the map's curvature (0.3 mm here) of it
    assert np.allclose(f.state(0.0).p_WP, [1.0, 2.0, 0.0], atol=1e-3)


@pytest.mark.parametrize(
    "bad",
    [
        {"pixel_std": 0.0},
        {"accel_noise": -1.0},
        {"gate_probability": 1.0},
        {"sigma_points": "julier"},
        {"alpha": 0.0},
        {"simplex_w0": 1.0, "sigma_points": "simplex"},
        {"measurement_model": "pinhole"},
        {"covariance_update": "sqrt"},
        {"max_nadir_angle": 2.0},
    ],
)
def test_config_rejects_invalid_values(bad: dict) -> None:
    with pytest.raises(ValueError):
        KimUkfConfig(**bad)


def test_camera_measurement_model_with_a_pinhole() -> None:
    """measurement_model='camera' runs the same filter through a pinhole's project (a pinhole preset)."""
    cam = PinholeCamera.default_downward()
    cfg = KimUkfConfig(measurement_model="camera", pixel_std=1.0, attitude_std=0.005, height_std=0.02)
    f = KimUkf(cfg, camera=cam, mount=MOUNT)
    rng = np.random.default_rng(0)
    pT = np.array([0.5, -0.3, 0.0])
    for k in range(60):
        t = 0.05 * k
        pT_t = pT + np.array([1.0, 0.2, 0.0]) * t
        p = np.array([0.8 * t, 0.0, 8.0])
        R_WB = np.eye(3)
        px = cam.project(((R_WB @ MOUNT.R_BC).T @ (pT_t - p))[None])[0] + rng.normal(0, 1.0, 2)
        assert f.update_pixel(t, px, Ego(p, np.array([0.8, 0.0, 0.0]), R_WB))
    s = f.state(t)
    assert np.linalg.norm(s.p_WP[:2] - pT_t[:2]) < 0.1
    assert np.linalg.norm(s.v_WP[:2] - [1.0, 0.2]) < 0.15


def test_confirmation_keeps_a_one_frame_sighting_from_becoming_a_track() -> None:
    from types import SimpleNamespace

    from alight.cameras.omni import OmniCamera
    from alight.cameras.pinhole import camera_pose_W

    cam = OmniCamera.synthetic(640, 480, fov_deg=186.0)
    mount = CameraMount.downward()
    ego = SimpleNamespace(p_WB=np.array([0.0, 0.0, 10.0]), v_WB=np.zeros(3), R_WB=np.eye(3))
    p_WC, R_WC = camera_pose_W(ego.p_WB, ego.R_WB, mount)
    px = cam.project((R_WC.T @ (np.array([1.0, 0.5, 0.0]) - p_WC))[None])[0]
    ukf = KimUkf(KimUkfConfig(confirm_updates=3, confirm_window_s=0.2), camera=cam, mount=mount)
    assert ukf.update_pixel(0.0, px, ego) is not None and not ukf.has_measurement  # tentative
    # nothing for 0.5 s (longer than the window), then the pixel again: a new tentative track
    ukf.update_pixel(0.5, px, ego)
    assert not ukf.has_measurement
    assert ukf.update_pixel(0.55, px, ego) and not ukf.has_measurement
    assert ukf.update_pixel(0.6, px, ego) and ukf.has_measurement  # three in a row: confirmed
    plain = KimUkf(KimUkfConfig(), camera=cam, mount=mount)
    plain.update_pixel(0.0, px, ego)
    assert plain.has_measurement  # the paper's filter trusts the first sighting
