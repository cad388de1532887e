"""Lawnmower coverage and the exploration route made of minimum-jerk segments."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.planning.exploration import ExplorationRoute, footprint_width_m, lawnmower_waypoints
from alight.planning.min_jerk import InputFeasibility, input_feasibility
from alight.types import GRAVITY_MPS2


def _dist_to_segments(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of each 2-D point (P, 2) to the nearest of the segments a[i] -> b[i] (S, 2)."""
    ab = b - a
    ap = pts[:, None, :] - a[None]
    s = np.clip(np.sum(ap * ab[None], axis=2) / np.sum(ab * ab, axis=1)[None], 0.0, 1.0)
    closest = a[None] + s[..., None] * ab[None]
    return np.linalg.norm(pts[:, None, :] - closest, axis=2).min(axis=1)


def test_footprint_width() -> None:
    assert footprint_width_m(10.0, math.pi / 2) == pytest.approx(20.0)
    assert footprint_width_m(10.0, math.pi / 2, overlap=0.25) == pytest.approx(15.0)
    assert footprint_width_m(4.0, math.radians(60)) == pytest.approx(8.0 * math.tan(math.radians(30)))
    for bad in ((0.0, 1.0, 0.0), (5.0, math.pi, 0.0), (5.0, 1.0, 1.0)):
        with pytest.raises(ValueError):
            footprint_width_m(*bad)


def test_lawnmower_covers_the_area() -> None:
    rng = np.random.default_rng(30)
    for _ in range(60):
        x_min, y_min = rng.uniform(-50, 50, 2)
        x_max, y_max = x_min + rng.uniform(1, 80), y_min + rng.uniform(1, 80)
        spacing = rng.uniform(0.5, 30.0)
        wp = lawnmower_waypoints(x_min, x_max, y_min, y_max, 7.0, spacing, start_xy=rng.uniform(-80, 80, 2))
        assert wp.shape[0] % 2 == 0 and (wp[:, 2] == 7.0).all()
        assert (wp[:, 0] >= x_min).all() and (wp[:, 0] <= x_max).all()
        assert (wp[:, 1] >= y_min).all() and (wp[:, 1] <= y_max).all()
        gx, gy = np.meshgrid(np.linspace(x_min, x_max, 41), np.linspace(y_min, y_max, 41))
        pts = np.column_stack([gx.ravel(), gy.ravel()])
        d = _dist_to_segments(pts, wp[0::2, :2], wp[1::2, :2])
        assert d.max() <= spacing / 2 + 1e-9
        # consecutive sweeps: neighbours, in opposite directions, turns on the same side
        sweeps = wp[1::2, :2] - wp[0::2, :2]
        assert (np.sum(sweeps[1:] * sweeps[:-1], axis=1) < 0).all()
        starts, ends = wp[0::2, :2], wp[1::2, :2]
        assert (np.linalg.norm(starts[1:] - ends[:-1], axis=1) <= spacing + 1e-9).all()
        # sweeps along the longer side
        along_x = abs(sweeps[0, 0]) > 0
        assert along_x == (x_max - x_min >= y_max - y_min)


def test_lawnmower_starts_at_the_nearest_corner_and_is_deterministic() -> None:
    args = (0.0, 40.0, 0.0, 20.0, 5.0, 5.0)
    for sx, sy in [(-5, -5), (45, -3), (42, 30), (-1, 25), (39, 1)]:
        wp = lawnmower_waypoints(*args, start_xy=(sx, sy))
        corners = np.array([[0.0, 2.5], [40.0, 2.5], [0.0, 17.5], [40.0, 17.5]])
        nearest = corners[np.argmin(np.hypot(corners[:, 0] - sx, corners[:, 1] - sy))]
        np.testing.assert_array_equal(wp[0, :2], nearest)
        np.testing.assert_array_equal(wp, lawnmower_waypoints(*args, start_xy=(sx, sy)))
    wp = lawnmower_waypoints(*args, rows_along="y")
    assert (wp[0::2, 0] == wp[1::2, 0]).all()  # sweeps along y
    with pytest.raises(ValueError):
        lawnmower_waypoints(0.0, 0.0, 0.0, 1.0, 5.0, 1.0)
    with pytest.raises(ValueError):
        lawnmower_waypoints(0.0, 1.0, 0.0, 1.0, 5.0, 0.0)


@pytest.fixture(scope="module")
def route() -> ExplorationRoute:
    wp = lawnmower_waypoints(-20.0, 20.0, -10.0, 10.0, 5.0, footprint_width_m(5.0, math.radians(70), 0.2))
    return ExplorationRoute(
        wp, t0=1.0, p0=[0.0, 0.0, 5.0], cruise_speed_mps=2.0, max_accel_mps2=2.0, floor_z=0.5
    )


def test_route_is_continuous_and_periodic(route: ExplorationRoute) -> None:
    joints = [route.approach.t_end] + [s.t_end for s in route.segments]
    for t in joints:
        before = route.reference(t - 1e-9)
        after = route.reference(t + 1e-9)
        for k in range(3):  # p, v, a continuous (jerk may step)
            np.testing.assert_allclose(before[k], after[k], atol=1e-6)
    for t in np.linspace(route.t_cycle_start, route.t_cycle_start + route.period_s, 97):
        for x, y in zip(route.reference(t), route.reference(t + 3 * route.period_s), strict=True):
            np.testing.assert_allclose(x, y, atol=1e-8)
    np.testing.assert_array_equal(route.reference(0.0)[0], [0.0, 0.0, 5.0])  # held before t0


def test_route_flies_sweeps_straight_at_cruise_speed(route: ExplorationRoute) -> None:
    sweeps = route.segments[0::2]
    assert len(sweeps) == 8  # 4 rows forward, 4 backward
    for s in sweeps:
        ts = np.linspace(s.t0, s.t_end, 11)
        p, v, a, _ = s.sample_many(ts)
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), 2.0, rtol=1e-12)
        np.testing.assert_allclose(a, 0.0, atol=1e-12)
        assert np.ptp(p[:, 1]) < 1e-9 and np.ptp(p[:, 2]) < 1e-9  # along x at constant y and height
    # every point of the area is within half a spacing of the first pass's sweeps
    first = sweeps[:4]
    a = np.array([s.p0[:2] for s in first])
    b = np.array([s.end_state()[0][:2] for s in first])
    gx, gy = np.meshgrid(np.linspace(-20, 20, 41), np.linspace(-10, 10, 21))
    spacing = footprint_width_m(5.0, math.radians(70), 0.2)
    assert _dist_to_segments(np.column_stack([gx.ravel(), gy.ravel()]), a, b).max() <= spacing / 2 + 1e-9
    assert route.done(route.t_first_pass_end) and not route.done(route.t_first_pass_end - 1e-6)
    assert route.t_first_pass_end == pytest.approx(first[-1].t_end)


def test_route_turns_are_gentle_and_feasible(route: ExplorationRoute) -> None:
    turns = [route.approach, *route.segments[1::2]]
    a0 = np.array([s.a0 for s in turns])
    al, be, ga = (np.array([getattr(s, k) for s in turns]) for k in ("alpha", "beta", "gamma"))
    T = np.array([s.T for s in turns])
    codes = input_feasibility(
        a0,
        al,
        be,
        ga,
        T,
        f_min=GRAVITY_MPS2 - 2.0,
        f_max=math.hypot(GRAVITY_MPS2, 2.0),
        w_max=6.0,
        min_section_s=0.02,
    )
    assert (codes == InputFeasibility.FEASIBLE).all()
    for s in turns:
        _, _, a, _ = s.sample_many(np.linspace(s.t0, s.t_end, 401))
        assert np.linalg.norm(a[:, :2], axis=1).max() <= 2.0 + 1e-9  # level flight: |a_h| <= max_accel


def test_route_rejects_bad_waypoints() -> None:
    with pytest.raises(ValueError):
        ExplorationRoute(np.zeros((3, 3)), t0=0.0, p0=np.zeros(3))
    with pytest.raises(ValueError):
        ExplorationRoute(np.zeros((2, 3)), t0=0.0, p0=np.zeros(3))  # zero-length sweep


def test_spiral_covers_the_area_from_its_centre_outwards() -> None:
    from alight.planning.exploration import spiral_waypoints

    for area, spacing, centre in [
        ((-20, 20, -20, 20), 10.0, (0.0, 0.0)),
        ((-30, 10, -5, 25), 7.0, (0.0, 0.0)),
    ]:
        w = spiral_waypoints(*area, 10.0, spacing, center_xy=np.array(centre))
        assert w.shape[1] == 3 and w.shape[0] % 2 == 0 and np.all(w[:, 2] == 10.0)
        legs = w[:, :2].reshape(-1, 2, 2)
        xs = np.linspace(area[0], area[1], 61)
        ys = np.linspace(area[2], area[3], 61)
        pts = np.array([(x, y) for x in xs for y in ys])
        d = np.full(len(pts), np.inf)
        for a, b in legs:
            ab = b - a
            tt = np.clip(((pts - a) @ ab) / (ab @ ab), 0.0, 1.0)
            d = np.minimum(d, np.linalg.norm(pts - (a + tt[:, None] * ab), axis=1))
        # half a spacing between rings; the quarter-spacing insets cut the corners and the clipped outer
        # ring leaves up to 2/3 of a spacing (measured on these areas; a lawnmower guarantees 1/2)
        assert d.max() <= 0.67 * spacing
        # the first leg starts next to the centre, and legs never leave the area
        assert np.linalg.norm(legs[0, 0] - np.array(centre)) <= 0.25 * spacing + 1e-9
        assert (legs[..., 0] >= area[0] - 1e-9).all() and (legs[..., 0] <= area[1] + 1e-9).all()
        assert (legs[..., 1] >= area[2] - 1e-9).all() and (legs[..., 1] <= area[3] + 1e-9).all()
