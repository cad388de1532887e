"""The QoS -> energy model (powprofiler's multivariate linear interpolation), the budget choosers, the
phase policies, the QoS-aware detector and the profiler's quick mode."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from alight.cameras import PinholeCamera
from alight.energy.compute import DeviceProfile
from alight.energy.qos import (
    DEFAULT_PHASE_POLICY,
    FRAME_KINDS,
    LAND_SETTING,
    OBLIQUE_SEARCH_SETTING,
    PhasePolicy,
    QosEnergyModel,
    QosMeasurements,
    QosSetting,
    budget_policy,
)
from alight.errors import ConfigError
from alight.evaluation.qos_profile import Frame, ProfileConfig, render_frames, run_profile
from alight.pads.sdu_pad import SduPad
from alight.perception.nfold import NFoldDetector
from alight.perception.qos_detector import QosDetector, ScaledCamera
from alight.perception.sdu_marker import SduMarkerDetector
from alight.types import Mode, Observation

R = (5.0, 10.0, 20.0, 30.0)
S = (0.5, 0.75, 1.0)
K = (13.0, 21.0, 29.0, 41.0)


def _multilinear(r: float, s: float, k: float) -> float:
    # linear in each variable separately: trilinear interpolation reproduces it everywhere
    return (
        0.1
        + 0.02 * r
        + 0.3 * s
        + 0.004 * k
        + 0.05 * r * s
        + 0.0007 * r * k
        + 0.01 * s * k
        + 0.002 * r * s * k
    )


def _model(fn=_multilinear, **kw) -> QosEnergyModel:  # type: ignore[no-untyped-def]
    P = np.array([[[fn(r, s, k) for k in K] for s in S] for r in R])
    return QosEnergyModel(R, S, K, P, **kw)


# ------------------------------------------------------------------------------------------------ settings


def test_quality_is_the_normalised_product_and_orders_settings() -> None:
    assert QosSetting(30, 1.0, 41).quality == pytest.approx(1.0)
    assert QosSetting(15, 0.5, 41).quality == pytest.approx(0.25)
    assert QosSetting(30, 0.5, 41).quality == pytest.approx(QosSetting(15, 1.0, 41).quality)
    # equal products: the higher rate ranks higher, then the larger scale
    assert QosSetting(15, 1.0, 41) < QosSetting(30, 0.5, 41)
    assert QosSetting(10, 0.5, 42) < QosSetting(10, 1.0, 21)
    grid = [QosSetting(r, s, int(k)) for r, s, k in itertools.product(R, S, K)]
    order = sorted(grid)
    q = [g.quality for g in order]
    assert q == sorted(q) and max(grid) == QosSetting(30, 1.0, 41) and min(grid) == QosSetting(5, 0.5, 13)
    assert len(set(grid)) == len(grid)  # hashable, equal by value


@pytest.mark.parametrize(
    ("args", "field"),
    [
        ((0, 1.0, 13), "rate_hz"),
        ((10, 0.0, 13), "image_scale"),
        ((10, 1.5, 13), "image_scale"),
        ((10, 1.0, 3), "max_kernel_px"),
        ((10, 1.0, 13.5), "max_kernel_px"),
        ((float("nan"), 1.0, 13), "rate_hz"),
    ],
)
def test_bad_settings_are_rejected(args: tuple, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        QosSetting(*args)


# ------------------------------------------------------------------------------------------------ model


def test_interpolation_exact_at_grid_points_and_multilinear_between() -> None:
    model = _model()
    for r, s, k in itertools.product(R, S, K):
        assert model.energy_per_s(QosSetting(r, s, int(k))) == pytest.approx(_multilinear(r, s, k), rel=1e-12)
    rng = np.random.default_rng(3)
    for _ in range(200):
        r, s, k = rng.uniform(5, 30), rng.uniform(0.5, 1.0), int(rng.integers(13, 42))
        assert model.energy_per_s(QosSetting(r, s, k)) == pytest.approx(_multilinear(r, s, k), rel=1e-12)


def test_interpolation_is_the_chord_between_samples() -> None:
    """For a curved function (s^2) the model is the straight line between the two samples around the
    point, not the function."""
    model = _model(lambda r, s, k: s * s)
    got = model.energy_per_s(QosSetting(10, 0.6, 21))
    chord = 0.25 + (0.6 - 0.5) / 0.25 * (0.5625 - 0.25)
    assert got == pytest.approx(chord, rel=1e-12) and abs(got - 0.36) > 0.01


def test_outside_the_sampled_range_is_an_error() -> None:
    model = _model()
    with pytest.raises(ValueError, match=r"outside the sampled range: rate_hz must be in \[5, 30\]"):
        model.energy_per_s(QosSetting(40, 1.0, 21))
    with pytest.raises(ValueError, match="image_scale must be in"):
        model.energy_per_s(QosSetting(10, 0.25, 21))
    with pytest.raises(ValueError, match="max_kernel_px must be in"):
        model.energy_per_s(QosSetting(10, 1.0, 61))


def test_model_rejects_bad_grids() -> None:
    with pytest.raises(ValueError, match="shape"):
        QosEnergyModel(R, S, K, np.zeros((4, 3, 3)))
    with pytest.raises(ConfigError, match="strictly increasing"):
        QosEnergyModel((5.0, 5.0), S, K, np.zeros((2, 3, 4)))
    with pytest.raises(ValueError, match="finite and >= 0"):
        QosEnergyModel(R, S, K, -np.ones((4, 3, 4)))


def test_energy_per_frame_baseline_and_mission_energy() -> None:
    # energy linear in the rate, as the measured models are: per-frame energy does not depend on it
    model = _model(lambda r, s, k: r * (s + k / 100), baseline_W=1.5)
    a, b = QosSetting(5, 1.0, 21), QosSetting(20, 1.0, 21)
    assert model.energy_per_frame_J(a) == pytest.approx(1.21) == pytest.approx(model.energy_per_frame_J(b))
    assert model.energy_per_s(b) == pytest.approx(1.5 + 20 * 1.21)
    assert model.predict_J(b, 10.0) == pytest.approx(10 * (1.5 + 20 * 1.21))
    counts = {a: 7, QosSetting(10, 0.5, 13): 3}
    assert model.mission_energy_J(counts, 4.0) == pytest.approx(7 * 1.21 + 3 * 0.63 + 1.5 * 4.0)
    assert model.mission_energy_J({}, 0.0) == 0.0


def test_best_within_budget_picks_the_highest_quality_that_fits() -> None:
    model = _model(busy_core_W=None)
    grid = model.grid_settings()
    duration = 60.0
    energies = {g: model.predict_J(g, duration) for g in grid}
    for budget in np.quantile(list(energies.values()), [0.05, 0.3, 0.5, 0.8, 1.0]):
        choice = model.best_within_budget(float(budget), duration)
        fits = [g for g in grid if energies[g] <= budget]
        assert choice.setting == max(fits)
        assert choice.predicted_J == pytest.approx(energies[choice.setting])
        assert choice.predicted_J <= budget
    # a subset of candidates, off the grid too
    cands = [QosSetting(7, 0.6, 17), QosSetting(25, 0.9, 37), QosSetting(12, 1.0, 13)]
    budget = sorted(model.predict_J(c, duration) for c in cands)[1]
    best = model.best_within_budget(budget, duration, cands).setting
    assert best == max(c for c in cands if model.predict_J(c, duration) <= budget)


def test_best_within_budget_none_when_nothing_fits() -> None:
    model = _model(baseline_W=2.0)
    cheapest = min(model.predict_J(g, 10.0) for g in model.grid_settings())
    choice = model.best_within_budget(0.99 * cheapest, 10.0)
    assert choice.setting is None and choice.predicted_J is None
    assert "no setting fits" in choice.reason and "idle baseline alone" not in choice.reason
    choice = model.best_within_budget(15.0, 10.0)  # baseline 2 W x 10 s = 20 J > 15 J
    assert choice.setting is None and "idle baseline alone is 20 J" in choice.reason


def test_best_within_budget_leaves_out_settings_slower_than_real_time() -> None:
    """busy_core_W = 1 W: a setting drawing more than 1 W keeps more than one core busy."""
    model = _model(lambda r, s, k: r * s * k / 300.0, busy_core_W=1.0)
    top = QosSetting(30, 1.0, 41)
    assert model.utilisation(top) == pytest.approx(30 * 41 / 300.0)
    choice = model.best_within_budget(1e9, 1.0)
    assert choice.setting is not None and model.utilisation(choice.setting) <= 1.0
    assert model.best_within_budget(1e9, 1.0, max_utilisation=None).setting == top


def test_budget_policy_is_the_exact_optimum() -> None:
    """Compared with brute force over every combination of a few candidates in 3 phases, for the utility
    sum_p w_p d_p ln quality_p, with given weights and with the default ones."""
    model = _model(busy_core_W=None)
    cands = [QosSetting(r, s, k) for r, s, k in itertools.product((5, 10, 30), (0.5, 1.0), (13, 41))]
    durations = {Mode.EXPLORE: 40.0, Mode.TRACK: 20.0, Mode.LAND: 8.0}
    e_rate = {c: model.energy_per_s(c) for c in cands}

    def brute(budget: float, w: dict) -> float | None:
        best = None
        for combo in itertools.product(cands, repeat=3):
            e = sum(e_rate[c] * d for c, d in zip(combo, durations.values(), strict=True))
            if e <= budget:
                pairs = zip(combo, durations.items(), strict=True)
                v = sum(w[m] * d * math.log(c.quality) for c, (m, d) in pairs)
                best = v if best is None else max(best, v)
        return best

    lo = sum(min(e_rate.values()) * d for d in durations.values())
    hi = sum(max(e_rate.values()) * d for d in durations.values())
    default_w = {m: DEFAULT_PHASE_POLICY[m].quality for m in durations}
    for weights in ({Mode.EXPLORE: 1.0, Mode.TRACK: 1.0, Mode.LAND: 3.0}, None):
        w = default_w if weights is None else weights
        for budget in (lo, lo + 0.2 * (hi - lo), lo + 0.6 * (hi - lo), hi):
            res = budget_policy(model, budget, durations, cands, weights=weights)
            assert res.policy is not None and res.predicted_J is not None
            assert res.predicted_J <= budget * (1 + 1e-12)
            assert res.policy.predict_J(model, durations) == pytest.approx(res.predicted_J)
            v = sum(w[m] * d * math.log(res.policy[m].quality) for m, d in durations.items())
            assert v == pytest.approx(brute(budget, w))
            assert res.policy.default == min(cands, key=lambda c: e_rate[c])  # phases not listed: cheapest
    res = budget_policy(model, 0.5 * lo, durations, cands)
    assert res.policy is None and "no per-phase choice fits" in res.reason


def test_budget_policy_keeps_landing_above_exploring() -> None:
    """On the shipped model (Jetson Nano 10 W) with a long exploration: for every budget that fits, the
    default weights never give the landing less quality than the exploration."""
    model = QosEnergyModel.load(device="jetson_nano", mode="10W")
    durations = {Mode.EXPLORE: 120.0, Mode.TRACK: 30.0, Mode.LAND: 10.0}
    lo = DEFAULT_PHASE_POLICY.predict_J(model, durations) * 0.3
    for budget in np.linspace(lo, 20 * lo, 6):
        res = budget_policy(model, float(budget), durations)
        if res.policy is not None:
            assert res.policy[Mode.LAND].quality >= res.policy[Mode.EXPLORE].quality


# ------------------------------------------------------------------------------------------------ policies


def test_phase_policy_lookups() -> None:
    a, b = QosSetting(5, 0.5, 21), QosSetting(30, 1.0, 21)
    pol = PhasePolicy({Mode.LAND: b, "explore": a}, a)
    assert pol[Mode.LAND] == b and pol["land"] == b and pol[Mode.EXPLORE] == a
    assert pol.setting_for(Mode.TRACK) == a  # default
    assert pol.all_settings() == [a, b]
    fixed = PhasePolicy.fixed(b)
    assert all(fixed[m] == b for m in Mode)
    with pytest.raises(ValueError):
        PhasePolicy({"hover": a}, a)
    with pytest.raises(ValueError, match="must be a QosSetting"):
        PhasePolicy({Mode.LAND: (30, 1.0, 21)}, a)  # type: ignore[dict-item]
    # the default rule: cheap while exploring, everything while landing
    d = DEFAULT_PHASE_POLICY
    assert d[Mode.EXPLORE] < d[Mode.TRACK] < d[Mode.LAND] == LAND_SETTING
    assert d[Mode.LAND].image_scale == 1.0 and d[Mode.EXPLORE].image_scale < 1.0


# ------------------------------------------------------------------------------------------------ detector


@pytest.fixture(scope="module")
def frames() -> list[Frame]:
    return render_frames(ProfileConfig.quick(), np.random.default_rng(11))


def _sdu() -> SduMarkerDetector:
    return SduMarkerDetector(SduPad.default(), camera=PinholeCamera.default_downward())


def test_qos_detector_maps_pixels_back_to_full_resolution(frames: list[Frame]) -> None:
    """The same frames at scale 1.0, 0.75 and 0.5: with the pad fully in view the fused landing-marker
    pixel (the n-fold tip dominates it) lands on the projected pad centre within 1 px at full scale and
    2 px at the smaller ones, so geolocation needs no change. A partial view near the image border may
    lose the tip at half scale (its kernel patch leaves the image) and fall back on the ArUco
    extrapolation: within the profiler's tolerance there."""
    inner = _sdu()
    checked = 0
    for f in frames:
        if f.center_px is None:
            continue
        found = {}
        for scale in (1.0, 0.75, 0.5):
            det = QosDetector(inner, QosSetting(30, scale, 41), throttle=False)
            obs = det.detect(f.image, 0.0)
            assert obs, (f.kind, scale)
            assert obs[0].pixels.shape[1] == 2 and obs[0].kind == "sdu"
            found[scale] = obs[0].pixels[0]
        err = {s: float(np.linalg.norm(p - f.center_px)) for s, p in found.items()}
        if f.kind == "partial":
            assert max(err.values()) < max(3.0, 0.05 * f.pad_side_px), err
            continue
        assert err[1.0] < 1.0 and err[0.75] < 2.0 and err[0.5] < 2.0, (f.kind, err)
        assert np.linalg.norm(found[0.5] - found[1.0]) < 2.0
        checked += 1
    assert checked == 2


def test_qos_detector_caps_the_kernel_sizes(frames: list[Frame]) -> None:
    inner = _sdu()
    det = QosDetector(inner, QosSetting(30, 1.0, 21), throttle=False)
    assert det.kernel_sizes() == (13, 17, 21)
    absent = next(f for f in frames if f.kind == "absent")
    assert det.detect(absent.image, 0.0) == []
    variant = next(iter(det._variants.values()))
    assert variant.nfold.config.kernel_sizes == (13, 17, 21)
    assert inner.nfold.config.kernel_sizes == tuple(range(13, 42, 4))  # the wrapped detector is untouched
    det.set_setting(QosSetting(30, 1.0, 29))
    assert det.kernel_sizes() == (13, 17, 21, 25, 29)
    with pytest.raises(ValueError, match="below the detector's smallest kernel size"):
        det.set_setting(QosSetting(30, 1.0, 9))
    # a bare n-fold detector is capped too, and finds the tip at half scale
    nf = QosDetector(NFoldDetector(), QosSetting(30, 0.5, 21), throttle=False)
    near = next(f for f in frames if f.kind == "near")
    (o,) = nf.detect(near.image, 0.0)
    assert o.kind == "nfold" and np.linalg.norm(o.pixels[0] - near.center_px) < 2.0


def test_qos_detector_throttles_to_the_rate_and_counts_frames(frames: list[Frame]) -> None:
    img = frames[0].image
    model = _model(lambda r, s, k: r * s * k / 1000.0)
    slow, fast = QosSetting(5, 0.5, 21), QosSetting(30, 0.5, 21)
    det = QosDetector(_sdu(), PhasePolicy({Mode.EXPLORE: slow, Mode.LAND: fast}, slow))
    det.set_mode(Mode.EXPLORE)
    times = [k / 20.0 for k in range(40)]  # a 20 Hz camera for 2 s
    processed = []
    for t in times:
        n = det.frames_processed
        det.detect(img, t)
        if det.frames_processed > n:
            processed.append(t)
    assert processed == pytest.approx([0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8])
    assert det.frames_by_setting == {slow: 10} and det.frames_skipped == 30
    det.set_mode("land")  # 30 Hz on a 20 Hz camera: every frame
    for t in [2.0 + k / 20.0 for k in range(20)]:
        det.detect(img, t)
    assert det.frames_by_setting == {slow: 10, fast: 20}
    assert det.energy_J(model) == pytest.approx(10 * 0.5 * 21 / 1000 + 20 * 0.5 * 21 / 1000)
    assert det.cpu_s_measured > 0
    # a rate that does not divide the camera's: 7 Hz from 20 Hz gives 7 frames a second on average
    det7 = QosDetector(_sdu(), QosSetting(7, 0.5, 13))
    for t in [k / 20.0 for k in range(200)]:
        det7.detect(img, t)
    assert det7.frames_processed in (70, 71)


def test_rescaled_observation_keeps_the_angle_and_scaled_camera_round_trips() -> None:
    from alight.perception.qos_detector import _rescale

    o = Observation(t=1.0, kind="sdu", quality=0.8, pixels=[[10.0, 20.0]], yaw_CP=0.7)
    r = _rescale(o, 2.0, 2.0)
    np.testing.assert_allclose(r.pixels, [[20.5, 40.5]])
    assert r.yaw_CP == pytest.approx(0.7) and r.quality == 0.8
    cam = PinholeCamera.default_downward()
    sc = ScaledCamera(cam, 376, 240)
    pts = np.array([[0.3, -0.2, 2.0], [-1.0, 0.5, 4.0]])
    px = sc.project(pts)
    np.testing.assert_allclose(px, (cam.project(pts) + 0.5) / 2 - 0.5)
    rays = sc.unproject(px)
    np.testing.assert_allclose(rays, pts / np.linalg.norm(pts, axis=1, keepdims=True), atol=1e-9)


# ------------------------------------------------------------------------------------------------ profiler


def test_profiler_quick_mode_writes_a_well_formed_model(frames: list[Frame], tmp_path: Path) -> None:
    cfg = ProfileConfig.quick()
    meas = run_profile(cfg, host_mips_1t=2000.0, frames=frames)
    shape = (len(cfg.image_scale), len(cfg.max_kernel_px))
    assert set(meas.cpu_s_per_frame) == {"mix", *FRAME_KINDS}
    for t in meas.cpu_s_per_frame.values():
        assert t.shape == shape and (t > 0).all() and (t < 1.0).all()
    for t in meas.detection_rate.values():
        assert ((t >= 0) & (t <= 1)).all()
    assert meas.false_detection_rate is not None and meas.false_detection_rate.shape == shape
    assert meas.info["host"]["cpu"] is not None and meas.host_mips_1t == 2000.0
    path = tmp_path / "q.yaml"
    meas.save(path, "header line")
    assert path.read_text().startswith("# header line\n")
    back = QosMeasurements.load(path)
    np.testing.assert_allclose(back.cpu_s_per_frame["mix"], meas.cpu_s_per_frame["mix"], atol=1e-7)
    # the energy model at a grid point is rate x CPU time x speed ratio x W per busy core
    nano = DeviceProfile.load("jetson_nano").mode("10W")
    model = QosEnergyModel.load(path, device="jetson_nano", mode="10W")
    s = QosSetting(cfg.rate_hz[1], cfg.image_scale[0], cfg.max_kernel_px[1])
    want = s.rate_hz * back.cpu_s_per_frame["mix"][0, 1] * 2000.0 / nano.cpu_mips_1t * nano.busy_core_W
    assert model.energy_per_s(s) == pytest.approx(want, rel=1e-12)
    total = QosEnergyModel.load(path, device="jetson_nano", mode="10W", include_idle=True)
    assert total.energy_per_s(s) == pytest.approx(want + nano.idle_W, rel=1e-12)


def test_bad_measurement_files_are_config_errors(tmp_path: Path) -> None:
    import yaml

    good = QosMeasurements.load().to_dict()
    for mutate, msg in [
        (lambda d: d.update(format="other/1"), "format must be"),
        (lambda d: d["axes"].update(image_scale=[1.0, 0.5, 0.75]), "strictly increasing"),
        (lambda d: d["cpu_s_per_frame"].update(mix=[[1.0]]), r"cpu_s_per_frame\.mix must have shape"),
        (lambda d: d.pop("host_mips_1t"), "host_mips_1t must be a positive number"),
        (lambda d: d["cpu_s_per_frame"].pop("mix"), "must have a 'mix' table"),
    ]:
        d = yaml.safe_load(yaml.safe_dump(good))
        mutate(d)
        p = tmp_path / "bad.yaml"
        p.write_text(yaml.safe_dump(d), encoding="utf-8")
        with pytest.raises(ConfigError, match=msg):
            QosMeasurements.load(p)
    with pytest.raises(ConfigError, match="not found"):
        QosMeasurements.load(tmp_path / "none.yaml")


def test_shipped_model_is_well_formed_and_covers_the_default_policy() -> None:
    meas = QosMeasurements.load()
    # the shipped file was measured before the profiler moved out of energy/ (its provenance is kept)
    assert meas.info["source"] in ("alight.energy.profile", "alight.evaluation.qos_profile")
    assert meas.host_mips_1t > 0
    for device in ("jetson_nano", "odroid_xu4"):
        prof = DeviceProfile.load(device)
        for mode in prof.modes:
            model = QosEnergyModel.load(device=device, mode=mode)
            for s in DEFAULT_PHASE_POLICY.all_settings():
                e = model.energy_per_s(s)
                assert 0 < e < prof.mode(mode).active_W  # never more than the whole busy board
            # energy grows with the rate (exactly linearly)
            low, high = QosSetting(5, 1.0, 41), QosSetting(30, 1.0, 41)
            assert model.energy_per_s(high) == pytest.approx(6 * model.energy_per_s(low), rel=1e-9)
    assert math.isfinite(QosEnergyModel.load().energy_per_frame_J(LAND_SETTING))


def test_oblique_views_switch_the_search_to_its_oblique_setting(frames: list[Frame]) -> None:
    img = frames[0].image
    cheap, oblique, land = QosSetting(5, 0.5, 21), QosSetting(20, 1.0, 41), QosSetting(30, 1.0, 21)
    pol = PhasePolicy(
        {Mode.EXPLORE: cheap, Mode.LAND: land}, cheap, oblique={Mode.EXPLORE: oblique}, oblique_tilt_rad=0.35
    )
    assert pol.setting_for(Mode.EXPLORE, oblique=True) == oblique
    assert pol.setting_for(Mode.LAND, oblique=True) == land  # no oblique entry: the usual setting
    assert set(pol.all_settings()) == {cheap, oblique, land} and pol.all_settings()[0] == cheap
    det = QosDetector(_sdu(), pol, throttle=False)
    det.set_mode(Mode.EXPLORE)
    tilt = 0.0
    t = 0.0
    for t in np.arange(0.0, 2.0, 0.02):  # level: cheap
        det.set_view_tilt(float(t), tilt)
    assert det.setting == cheap and not det.oblique
    # a brief lean (a pattern corner) is low-passed away
    for t in np.arange(2.0, 2.3, 0.02):
        det.set_view_tilt(float(t), 0.6)
    assert det.setting == cheap
    # a sustained lean into the wind switches within a couple of seconds...
    for t in np.arange(2.3, 6.0, 0.02):
        det.set_view_tilt(float(t), 0.6)
    assert det.setting == oblique and det.oblique
    det.detect(img, 6.0)
    assert det.frames_by_setting == {oblique: 1}
    # ... holds it in the hysteresis band (5 deg under the threshold) ...
    for t in np.arange(6.0, 12.0, 0.02):
        det.set_view_tilt(float(t), 0.35 - math.radians(3.0))
    assert det.setting == oblique
    # ... leaves it below, and a mode without an oblique entry ignores the tilt
    for t in np.arange(12.0, 20.0, 0.02):
        det.set_view_tilt(float(t), 0.1)
    assert det.setting == cheap and not det.oblique
    det.set_mode(Mode.LAND)
    for t in np.arange(20.0, 26.0, 0.02):
        det.set_view_tilt(float(t), 0.6)
    assert det.setting == land
    det.set_view_tilt(26.0, float("nan"))  # ignored
    assert det.setting == land
    with pytest.raises(ValueError, match="oblique_tilt_rad"):
        PhasePolicy({}, cheap, oblique_tilt_rad=2.0)
    with pytest.raises(ValueError, match="oblique setting"):
        PhasePolicy({}, cheap, oblique={Mode.EXPLORE: (20, 1.0, 41)})  # type: ignore[dict-item]
    # the default rule searches at full quality only when leaning
    assert DEFAULT_PHASE_POLICY.setting_for(Mode.EXPLORE, oblique=True) == OBLIQUE_SEARCH_SETTING
    assert DEFAULT_PHASE_POLICY.setting_for(Mode.EXPLORE) < OBLIQUE_SEARCH_SETTING
