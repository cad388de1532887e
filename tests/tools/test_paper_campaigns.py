"""The per-paper campaign files of issue 41 fly what their comments say: each paper's own preset on at
least 20 seeds per cell, paper 000's paths and speeds and its real flight's 1.2 m/s, paper 004's calm and
gust cells on the same seeds, and every straight line inside its mission area for the whole mission
(the premise of paper 000: the platform "moves inside a large mission area of known size")."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from alight.campaign import load_campaign
from alight.sim.platform import Platform, PlatformConfig

ROOT = Path(__file__).resolve().parents[2]
CAMPAIGNS = ROOT / "examples" / "campaigns"


def _cells(name: str) -> set[tuple[str, float, str, float | None]]:
    c = load_campaign(CAMPAIGNS / f"{name}.yaml")
    assert c.spec.seeds_per_condition >= 20
    out = set()
    for m in c.missions:
        p, w = m.scenario["platform"], m.scenario["wind"]
        out.add((p["path"], p["speed_mps"], w["model"], w["gust_power_N"] if w["model"] == "gust" else None))
    return out


def test_each_paper_flies_its_own_preset_in_its_cells() -> None:
    presets = {n: load_campaign(CAMPAIGNS / f"{n}.yaml").presets for n in ("paper000_conditions",
               "paper003_conditions", "paper004_conditions")}  # fmt: skip
    assert presets == {
        "paper000_conditions": ["falanga2017"],
        "paper003_conditions": ["kim_kaist"],
        "paper004_conditions": ["zamanakos_sdu"],
    }
    speeds = (1.0, 2.0, 3.0, 4.2)
    paper000 = {(path, v, "none", None) for path in ("straight", "circle", "figure8") for v in speeds}
    assert _cells("paper000_conditions") == paper000 | {("straight", 1.2, "none", None)}
    assert _cells("paper004_conditions") == {
        ("straight", 1.5, "none", None),
        ("straight", 1.5, "gust", 3.45),
        ("straight", 1.5, "gust", 7.76),
    }
    assert {cell[0] for cell in _cells("paper003_conditions")} == {"straight"}


def test_paper_004_cells_share_their_seeds() -> None:
    c = load_campaign(CAMPAIGNS / "paper004_conditions.yaml")
    seeds: dict[str, list[int]] = {}
    for m in c.missions:
        seeds.setdefault(m.condition_id, []).append(m.seed)
    assert len(seeds) == 7
    assert all(s == seeds["c000"] for s in seeds.values())


def test_paper_004_flies_each_gust_upwind_downwind_and_across() -> None:
    c = load_campaign(CAMPAIGNS / "paper004_conditions.yaml")
    headings: dict[float, set[float]] = {}
    for m in c.missions:
        w = m.scenario["wind"]
        if w["model"] == "gust":
            headings.setdefault(w["gust_power_N"], set()).add(round(m.scenario["platform"]["heading_rad"], 6))
    assert headings == {f: {0.0, round(math.pi / 2, 6), round(math.pi, 6)} for f in (3.45, 7.76)}


def test_paper_000_circle_lies_beside_the_take_off_point() -> None:
    """The circle is not centred on the take-off point: the take-off point lies outside it."""
    c = load_campaign(CAMPAIGNS / "paper000_conditions.yaml")
    circles = [m for m in c.missions if m.scenario["platform"]["path"] == "circle" and m.replicate == 0]
    assert len(circles) == 4
    for m in circles:
        xy = _path_W(m.scenario)
        centre = 0.5 * (xy[:, :2].min(axis=0) + xy[:, :2].max(axis=0))
        assert np.allclose(centre, [10.0, 10.0], atol=1e-3), m.mission_id
        assert float(np.hypot(*centre)) > m.scenario["platform"]["circle_radius_m"], m.mission_id


def _path_W(scenario: dict[str, object]) -> np.ndarray:
    """The platform's positions (m, W) over the whole mission, every 10 ms."""
    p = scenario["platform"]
    assert isinstance(p, dict) and p["start_xy"] is not None and p["heading_rad"] is not None
    config = PlatformConfig(
        path=p["path"],
        speed_mps=p["speed_mps"],
        start_xy_m=tuple(p["start_xy"]),
        start_heading=p["heading_rad"],
        circle_radius_m=p["circle_radius_m"],
        figure8_length_m=p["figure8_length_m"],
    )
    t = np.linspace(0.0, float(scenario["duration_s"]), 12001)  # type: ignore[arg-type]
    return Platform(config, np.random.default_rng(0)).states(t).p_WP


@pytest.mark.parametrize(
    "name", ["paper000_conditions", "paper003_conditions", "paper004_conditions", "paper_conditions"]
)
def test_every_path_stays_inside_its_area_for_the_whole_mission(name: str) -> None:
    c = load_campaign(CAMPAIGNS / f"{name}.yaml")
    for m in (m for m in c.missions if m.replicate == 0):
        area = m.scenario["search_area"]
        xy = _path_W(m.scenario)
        assert np.all(xy[:, 0] >= area["x_min"]) and np.all(xy[:, 0] <= area["x_max"]), m.mission_id
        assert np.all(xy[:, 1] >= area["y_min"]) and np.all(xy[:, 1] <= area["y_max"]), m.mission_id
        # never nearer the take-off point than the 4 m the default placement keeps
        assert float(np.min(np.hypot(xy[:, 0], xy[:, 1]))) >= 4.0 - 0.05, m.mission_id
        if m.scenario["platform"]["path"] == "straight":
            # it drives into the 40 m square round the take-off point when the exploration starts (~10 s)
            # (whichever way the corridor runs; _path_W samples the mission 12000 times)
            inside = np.all(np.abs(xy) <= 20.0 + 1e-9, axis=1)
            t_enter = float(m.scenario["duration_s"]) * int(np.argmax(inside)) / 12000
            assert math.isclose(t_enter, 10.0, abs_tol=0.011), m.mission_id
            # and passes the take-off point 4 m to the side
            assert math.isclose(float(np.min(np.hypot(xy[:, 0], xy[:, 1]))), 4.0, abs_tol=0.05), m.mission_id
