"""The candidate planner of paper 000 Sec. II-D: min-cost feasible pick, hysteresis, no-feasible fallback."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.airframe import Airframe
from alight.errors import ConfigError
from alight.planning.candidates import CandidatePlanner, PlannerConfig, PlanStatus, sample_end_times
from alight.planning.min_jerk import EndConstraint, InputFeasibility, evaluate_candidates


def _realistic(rng: np.random.Generator, t: float, n: int):
    """Start near hover at (0, 0, 5); a platform 2-20 m away at 1-3 m, moving at 0-4.2 m/s; the end
    states are its predicted states at n end times over [0.5, 6] s."""
    p0 = np.array([0.0, 0.0, 5.0]) + rng.uniform(-0.5, 0.5, 3)
    d = rng.normal(size=3)
    v0 = d / np.linalg.norm(d) * rng.uniform(0.0, 3.0)
    a0 = rng.uniform(-0.5, 0.5, 3)
    heading = rng.uniform(-np.pi, np.pi)
    start = np.array([math.cos(heading), math.sin(heading), 0.0]) * rng.uniform(2.0, 20.0)
    start[2] = rng.uniform(1.0, 3.0)
    course = rng.uniform(-np.pi, np.pi)
    vp = np.array([math.cos(course), math.sin(course), 0.0]) * rng.uniform(0.0, 4.2)
    te = t + np.sort(rng.uniform(0.5, 6.0, n))
    return p0, v0, a0, te, start + (te - t)[:, None] * vp, np.tile(vp, (n, 1))


def test_sample_end_times() -> None:
    te = sample_end_times(10.0, 5, 1.0, 5.0)
    np.testing.assert_allclose(te, [11.0, 12.0, 13.0, 14.0, 15.0])
    assert sample_end_times(10.0, 1, 1.0, 5.0)[0] == pytest.approx(13.0)
    r1 = sample_end_times(2.0, 50, 1.0, 5.0, np.random.default_rng(7))
    r2 = sample_end_times(2.0, 50, 1.0, 5.0, np.random.default_rng(7))
    np.testing.assert_array_equal(r1, r2)
    assert (np.diff(r1) >= 0).all() and r1.min() >= 3.0 and r1.max() <= 7.0
    with pytest.raises(ValueError):
        sample_end_times(0.0, 0, 1.0, 5.0)
    with pytest.raises(ValueError):
        sample_end_times(0.0, 3, 5.0, 1.0)


def test_config_defaults_and_validation() -> None:
    c = PlannerConfig()
    assert (c.f_min, c.f_max) == Airframe().collective_accel_limits
    assert c.w_max == Airframe().max_body_rate and c.n_candidates == 20 and c.floor_z == 0.5
    heavy = Airframe(thrust_to_weight=3.0)
    assert PlannerConfig.from_airframe(heavy, floor_z=None).f_max == heavy.collective_accel_limits[1]
    for bad in (
        {"n_candidates": 0},
        {"horizon_min_s": 0.0},
        {"f_min": 20.0},
        {"w_max": -1.0},
        {"min_section_s": 0},
    ):
        with pytest.raises(ConfigError):
            PlannerConfig(**bad)


def test_picks_the_min_cost_feasible_candidate() -> None:
    rng = np.random.default_rng(20)
    cfg = PlannerConfig()
    cheaper_infeasible_seen = 0
    for _ in range(200):
        p0, v0, a0, te, pe, ve = _realistic(rng, 3.0, 20)
        # The cost falls with the duration, so the longest candidate usually wins; drop some end points
        # to 0.2-0.5 m (under the 0.5 m floor) so that the filter has to pass over cheaper candidates.
        low = rng.random(20) < 0.3
        pe[low, 2] = rng.uniform(0.2, 0.5, low.sum())
        planner = CandidatePlanner(cfg)
        res = planner.plan(3.0, p0, v0, a0, te, pe, ve)
        ref = evaluate_candidates(
            p0, v0, a0, te - 3.0, pe, ve, mode=EndConstraint.POS_VEL, f_min=cfg.f_min, f_max=cfg.f_max,
            w_max=cfg.w_max, min_section_s=cfg.min_section_s, plane_point=[0.0, 0.0, cfg.floor_z],
        )  # fmt: skip
        np.testing.assert_array_equal(res.costs, ref.cost)
        np.testing.assert_array_equal(res.codes, ref.codes)
        np.testing.assert_array_equal(res.floor_ok, ref.floor_ok)
        feasible = ref.feasible
        assert res.n_feasible == feasible.sum()
        if not feasible.any():
            assert res.status is PlanStatus.NO_FEASIBLE and res.trajectory is None
            continue
        b = int(np.argmin(np.where(feasible, ref.cost, np.inf)))
        assert res.best_index == b and res.adopted and res.status is PlanStatus.ADOPTED
        tr = res.trajectory
        assert tr is res.best and tr is planner.previous
        assert tr.t0 == 3.0 and tr.t_end == pytest.approx(te[b], abs=1e-12)
        np.testing.assert_array_equal(tr.alpha, ref.alpha[b])
        np.testing.assert_array_equal(tr.gamma, ref.gamma[b])
        assert tr.cost == pytest.approx(ref.cost[b], rel=1e-12)
        assert (ref.cost[feasible] >= ref.cost[b]).all()
        np.testing.assert_allclose(tr.end_state()[0], pe[b], atol=1e-9)
        np.testing.assert_allclose(tr.end_state()[1], ve[b], atol=1e-9)
        cheaper_infeasible_seen += int(np.argmin(ref.cost) != b)
    assert cheaper_infeasible_seen > 20  # the feasibility filter mattered in many cycles


def test_indeterminable_counts_as_infeasible_and_previous_plan_is_kept() -> None:
    planner = CandidatePlanner(PlannerConfig(min_section_s=0.5))
    p0, v0, a0 = np.array([0.0, 0.0, 5.0]), np.zeros(3), np.zeros(3)
    # durations shorter than a section: every verdict INDETERMINABLE
    res = planner.plan(
        0.0, p0, v0, a0, np.array([0.1, 0.2, 0.3]), np.tile([0.1, 0.0, 5.0], (3, 1)), np.zeros((3, 3))
    )
    assert (res.codes == InputFeasibility.INDETERMINABLE).all()
    assert res.status is PlanStatus.NO_FEASIBLE and res.trajectory is None and res.n_feasible == 0
    ok = planner.plan(0.0, p0, v0, a0, np.array([2.0]), np.array([[1.0, 0.0, 5.0]]), np.zeros((1, 3)))
    assert ok.adopted
    # every end below the floor: nothing feasible, the previous plan stays
    res = planner.plan(0.1, p0, v0, a0, np.array([6.0]), np.array([[1.0, 0.0, 0.2]]), np.zeros((1, 3)))
    assert not res.floor_ok[0] and res.status is PlanStatus.NO_FEASIBLE and res.trajectory is ok.trajectory
    # the same end with the floor lowered for this call only is feasible
    res = planner.plan(
        0.1, p0, v0, a0, np.array([6.0]), np.array([[1.0, 0.0, 0.2]]), np.zeros((1, 3)), floor_z=0.0
    )
    assert res.floor_ok[0] and res.adopted
    planner.reset()
    assert planner.previous is None


def test_hysteresis_keeps_a_consistent_plan_and_adopts_a_changed_one() -> None:
    cfg = PlannerConfig(adopt_threshold_m=0.2)
    planner = CandidatePlanner(cfg)
    vp = np.array([3.0, 0.5, 0.0])
    start = np.array([8.0, 4.0, 1.5])

    def targets(t, offset=(0.0, 0.0, 0.0)):
        te = sample_end_times(t, 20, cfg.horizon_min_s, cfg.horizon_max_s)
        return te, start + np.asarray(offset) + te[:, None] * vp, np.tile(vp, (20, 1))

    first = planner.plan(0.0, [0.0, 0.0, 5.0], [1.0, 0.0, 0.0], np.zeros(3), *targets(0.0))
    assert first.adopted and math.isnan(first.end_distance_m)
    plan = first.trajectory
    # 20 ms later, following the plan, same platform motion: a different end time is picked along the
    # same platform path, but compared at a common time the end points agree, so the plan is kept
    t = 0.02
    p, v, a, _ = plan.sample(t)
    res = planner.plan(t, p, v, a, *targets(t))
    assert res.status is PlanStatus.KEPT_SIMILAR and res.trajectory is plan and not res.adopted
    assert res.end_distance_m < 1e-9
    # a prediction that moved by 0.15 m: still kept; by 0.3 m: adopted
    res = planner.plan(t, p, v, a, *targets(t, np.array([0.15, 0.0, 0.0])))
    assert res.status is PlanStatus.KEPT_SIMILAR and res.end_distance_m == pytest.approx(0.15, abs=1e-9)
    res = planner.plan(t, p, v, a, *targets(t, np.array([0.0, 0.3, 0.0])))
    assert res.status is PlanStatus.ADOPTED and res.trajectory is res.best is planner.previous
    assert res.end_distance_m == pytest.approx(0.3, abs=1e-9)
    # the distance is the one between the two plans continued to a common time
    new = res.trajectory
    t_c = max(new.t_end, plan.t_end)
    assert res.end_distance_m == pytest.approx(
        np.linalg.norm(new.sample(t_c)[0] - plan.sample(t_c)[0]), abs=1e-12
    )


def test_fixed_final_acceleration_mode() -> None:
    planner = CandidatePlanner(PlannerConfig(end_constraint=EndConstraint.POS_VEL_ACC, floor_z=None))
    te = np.array([3.0, 4.0])
    pe = np.array([[5.0, 0.0, 3.0], [6.0, 1.0, 3.0]])
    ve = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    ae = np.array([0.0, 0.5, 0.0])
    res = planner.plan(0.0, [0.0, 0.0, 3.0], np.zeros(3), np.zeros(3), te, pe, ve, a_end=ae)
    assert res.adopted
    np.testing.assert_allclose(res.trajectory.end_state()[2], ae, atol=1e-9)


def test_rejects_bad_input() -> None:
    planner = CandidatePlanner()
    p0 = np.array([0.0, 0.0, 5.0])
    z = np.zeros(3)
    pe = np.array([[1.0, 0.0, 5.0]])
    with pytest.raises(ValueError):
        planner.plan(1.0, p0, z, z, np.array([1.0]), pe, np.zeros((1, 3)))  # end time not after t
    with pytest.raises(ValueError):
        planner.plan(0.0, p0, z, z, np.array([1.0]), pe * np.nan, np.zeros((1, 3)))
    with pytest.raises(ValueError):
        planner.plan(0.0, [np.inf, 0, 0], z, z, np.array([1.0]), pe, np.zeros((1, 3)))
    with pytest.raises(ValueError):
        planner.plan(0.0, p0, z, z, np.array([1.0, 2.0]), pe, np.zeros((1, 3)))
