"""Mission plots and the self-contained HTML report, on synthetic logs made here."""

from __future__ import annotations

import ast
import base64
import struct
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from alight.evaluation.log import MissionLog
from alight.evaluation.plots import DPI, mode_segments, plot_time_series, plot_top_view
from alight.evaluation.report import FIGURES, events_from_log, write_mission_report, yamlish
from alight.types import Mode

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
VOID = {"meta", "img", "br", "hr", "link", "input", "col", "area", "base", "wbr", "source"}

RADIUS_M, OMEGA = 8.0, 0.25  # platform on a circle: 2 m/s


def _circle_log(detect: bool = True, land: bool = True, duration_s: float = 60.0) -> dict[str, np.ndarray]:
    """A quad that closes in on a platform driving a circle, descends and lands on it (at 50 Hz)."""
    rng = np.random.default_rng(7)
    log = MissionLog()
    for k in range(int(duration_s * 50) + 1):
        t = k / 50
        c, s = np.cos(OMEGA * t), np.sin(OMEGA * t)
        p_WP = np.array([RADIUS_M * c, RADIUS_M * s, 0.6])
        v_WP = RADIUS_M * OMEGA * np.array([-s, c, 0.0])
        gap = max(0.0, 1.0 - t / 30.0)  # offset shrinks to zero at t = 30 s
        p_WB = p_WP + np.array([6.0 * gap, 0.0, 0.4 + 4.0 * max(0.0, 1.0 - t / 40.0)])
        v_WB = v_WP + np.array([-6.0 / 30.0 if gap > 0 else 0.0, 0.0, -0.1 if t < 40 else 0.0])
        if t < 3:
            mode = Mode.TAKEOFF
        elif t < 10 or not detect:
            mode = Mode.EXPLORE
        elif t < 25 or not land:
            mode = Mode.TRACK
        elif t < 40:
            mode = Mode.LAND
        else:
            mode = Mode.LANDED
        seen = detect and t >= 10
        log.append(
            t,
            mode=mode,
            p_WB=p_WB,
            v_WB=v_WB,
            p_WB_est=p_WB + rng.normal(0, 0.03, 3),
            v_WB_est=v_WB + rng.normal(0, 0.03, 3),
            p_WP=p_WP,
            v_WP=v_WP,
            p_WP_est=p_WP + 0.1 if seen else None,
            v_WP_est=v_WP if seen else None,
            p_ref=p_WB,
            v_ref=v_WB,
            thrust_N=9.81,
            w_cmd=np.zeros(3),
            w_WB_B=np.zeros(3),
            range_m=p_WB[2] - p_WP[2] if seen else None,
            f_wind_W=np.zeros(3),
            motor_N=np.full(4, 9.81 / 4),
        )
        if seen and k % 3 == 0:
            log.add_detection(t - 0.03, p_WP + rng.normal(0, 0.15, 3))
    return log.finalize()


RESULT = {
    "scenario": {
        "name": "circle <test>",
        "preset": "falanga2017",
        "platform": {"path": "circle", "speed_mps": 2.0},
        "faults": {"blackouts": [[12.0, 13.5]]},
        "note": "<script>alert(1)</script>",
    },
    "seed": 7,
    "preset": "falanga2017",
    "outcome": "landed",
    "success": True,
    "touchdown_error_m": 0.1234,
    "touchdown_rel_speed_mps": 0.31,
    "time_first_detection_s": 10.0,
    "time_to_land_s": 40.0,
    "energy_flight_J": 8123.4,
    "energy_compute_J": 55.5,
    "detections": 751,
    "platform_estimate_rmse_m": 0.17,
    "wall_time_s": 0.9,
    "alight_version": "0.1.0",
}


class _Checker(HTMLParser):
    """Checks that tags nest and close properly and collects every URL-bearing attribute."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.urls: list[str] = []
        self.tags: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        for name, value in attrs:
            if name in ("src", "href", "srcset", "action", "data") and value is not None:
                self.urls.append(value)
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"unexpected </{tag}> with open {self.stack[-3:]}")
        else:
            self.stack.pop()

    def handle_data(self, data):
        self.text.append(data)


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == PNG_MAGIC
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def _check_report(path) -> _Checker:
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    assert "http://" not in text and "https://" not in text
    assert "@import" not in text and "url(" not in text  # no external CSS resources either
    p = _Checker()
    p.feed(text)
    p.close()
    assert not p.errors, p.errors
    assert p.stack == [], f"unclosed tags {p.stack}"
    assert "script" not in p.tags
    assert p.urls, "expected embedded figures"
    for url in p.urls:
        assert url.startswith("data:image/png;base64,"), url[:60]
        assert base64.b64decode(url.split(",", 1)[1], validate=True)[:8] == PNG_MAGIC
    return p


@pytest.fixture(scope="module")
def landed_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("landed")
    log = _circle_log()
    events = {"t_first_detection": 10.0, "t_landing_start": 25.0, "t_touchdown": 40.0}
    return out, write_mission_report(out, RESULT, log, events), log


def test_report_files_and_pngs(landed_report):
    out, path, _ = landed_report
    assert path == out / "report.html"
    for stem, _, _ in FIGURES:
        data = (out / f"{stem}.png").read_bytes()
        w, h = _png_size(data)
        assert w > 500 and h > 400
        assert len(data) > 20_000  # a real plot, not an empty canvas
    # the figure sizes are fixed in inches, so the pixel size follows the dpi
    w, h = _png_size((out / "time_series.png").read_bytes())
    assert (w, h) == (round(11.0 * DPI), round(8.4 * DPI))


def test_report_html_is_self_contained_and_complete(landed_report):
    _, path, _ = landed_report
    p = _check_report(path)
    assert len(p.urls) == len(FIGURES)
    text = "".join(p.text)
    assert "landed" in text
    assert "0.123 m" in text  # touchdown error card
    for key in RESULT:
        assert key in text
    html_src = path.read_text(encoding="utf-8")
    # user strings are escaped, not interpreted
    assert "<script>" not in html_src and "&lt;script&gt;" in html_src
    assert "circle &lt;test&gt;" in html_src
    assert "speed_mps: 2.0" in text  # the scenario block


def test_report_without_detections_timeout(tmp_path):
    log = _circle_log(detect=False, land=False, duration_s=30.0)
    assert log["t_det"].size == 0 and np.isnan(log["p_WP_est"]).all()
    result = dict(
        RESULT,
        outcome="timeout",
        success=False,
        touchdown_error_m=None,
        touchdown_rel_speed_mps=None,
        time_first_detection_s=None,
        time_to_land_s=None,
        detections=0,
        platform_estimate_rmse_m=float("nan"),
        scenario="examples/circle.yaml",
    )
    events = events_from_log(log, result)
    assert events == {"t_first_detection": None, "t_landing_start": None, "t_touchdown": None}
    path = write_mission_report(tmp_path, result, log, dpi=60)  # low dpi: only robustness is tested here
    p = _check_report(path)
    text = "".join(p.text)
    assert "timeout" in text and "examples/circle.yaml" in text
    for stem, _, _ in FIGURES:
        assert (tmp_path / f"{stem}.png").stat().st_size > 5_000


def test_report_on_empty_log_and_crash(tmp_path):
    log = MissionLog().finalize()
    path = write_mission_report(tmp_path, {"outcome": "crashed", "success": False}, log, dpi=40)
    text = "".join(_check_report(path).text)
    assert "crashed" in text


def test_events_from_log():
    log = _circle_log()
    ev = events_from_log(log)
    # the first detection's capture time: sample k = 501 (the first multiple of 3 from t = 10 s) - 0.03 s
    assert ev["t_first_detection"] == pytest.approx(501 / 50 - 0.03)
    assert ev["t_landing_start"] == pytest.approx(25.0)
    assert ev["t_touchdown"] == pytest.approx(40.0)
    # the result's own first-detection time wins over the log's
    assert events_from_log(log, {"time_first_detection_s": 9.5})["t_first_detection"] == 9.5


def test_top_view_event_markers_sit_on_the_paths():
    log = _circle_log()
    fig = Figure()
    ax = fig.add_subplot()
    te = 17.31  # between samples: the marker must be interpolated
    assert plot_top_view(log, {"t_touchdown": te}, ax=ax) is fig
    squares = [ln.get_xydata() for ln in ax.get_lines() if ln.get_marker() == "s" and len(ln.get_xdata())]
    c, s = np.cos(OMEGA * te), np.sin(OMEGA * te)
    platform_xy = RADIUS_M * np.array([c, s])
    quad_xy = platform_xy + np.array([6.0 * (1 - te / 30.0), 0.0])
    got = np.vstack(squares)
    assert got.shape == (2, 2)
    # the log is sampled at 50 Hz, so linear interpolation of the circle is good to R (w dt)^2 / 8
    np.testing.assert_allclose(got[0], quad_xy, atol=1e-3)
    np.testing.assert_allclose(got[1], platform_xy, atol=1e-3)
    # an event outside the log is not drawn
    fig2 = Figure()
    ax2 = fig2.add_subplot()
    plot_top_view(log, {"t_touchdown": 1e3}, ax=ax2)
    assert not any(ln.get_marker() == "s" and len(ln.get_xdata()) for ln in ax2.get_lines())


def test_time_series_event_lines():
    log = _circle_log()
    # t_touchdown lies after the end of the log: it must not be drawn (nor its label spill over)
    fig = plot_time_series(log, {"t_first_detection": 10.0, "t_landing_start": None, "t_touchdown": 1e3})

    def vlines_at(x: float) -> int:
        return sum(
            1
            for ax in fig.axes
            for ln in ax.get_lines()
            if len(ln.get_xdata()) == 2 and np.ptp(ln.get_xdata()) == 0 and ln.get_xdata()[0] == x
        )

    assert vlines_at(10.0) == 8  # one per axis: 2 mode bands + 6 data axes
    assert vlines_at(1e3) == 0
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert texts.count("$t_{d}$") == 2 and "$t_{f}$" not in texts


def test_mode_segments():
    t = np.arange(5.0)
    mode = np.array(["a", "a", "b", "b", "c"])
    assert mode_segments(t, mode) == [("a", 0.0, 2.0), ("b", 2.0, 4.0), ("c", 4.0, 4.0)]
    assert mode_segments(np.zeros(0), np.zeros(0, dtype=str)) == []


def test_yamlish():
    lines = yamlish({"a": 1, "b": {"c": [1, 2], "d": None}, "e": [{"f": "x: y"}], "g": True})
    assert lines == ["a: 1", "b:", "  c: [1, 2]", "  d: null", "e:", '  - f: "x: y"', "g: true"]


def test_no_pyplot():
    # pyplot keeps global figure state (leaks in long campaigns, backend clashes in workers)
    import alight.evaluation.plots as plots_mod
    import alight.evaluation.report as report_mod

    for mod in (plots_mod, report_mod):
        tree = ast.parse(Path(mod.__file__).read_text(encoding="utf-8"))
        imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        imported |= {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        imported |= {
            f"{n.module}.{a.name}" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names
        }
        assert not {"matplotlib.pyplot", "pylab", "matplotlib.pylab"} & imported, mod.__name__
    had_pyplot = "matplotlib.pyplot" in sys.modules
    log = MissionLog()
    for k in range(10):
        log.append(0.1 * k, p_WB=np.ones(3) * k, p_WP=np.zeros(3), mode="track")
    for _, _, plot in FIGURES:
        plot(log.finalize(), {"t_touchdown": 0.5})
    assert had_pyplot or "matplotlib.pyplot" not in sys.modules


def test_compute_section_shares_the_wall_time_between_blocks_and_simulator() -> None:
    from alight.evaluation.report import _compute_html

    blocks = {"ego_estimator": 0.05, "detector": 0.2, "controller": 0.0}
    result = {"block_time_s": blocks, "wall_time_s": 0.5, "simulated_time_s": 20.0}
    page = _compute_html(result)
    p = _Checker()
    p.feed(page)
    p.close()
    assert not p.errors and p.stack == []
    text = "".join(p.text)
    # ms, ms per simulated second, share: the detector 200 ms = 10 ms/s = 40 %; the simulator gets the
    # 250 ms no block accounts for
    assert "detector200.010.0040.0 %" in text
    assert "simulator250.012.5050.0 %" in text
    assert "controller0.00.000.0 %" in text
    # nothing to show without the figures it needs, or with nonsense in them
    assert _compute_html({"wall_time_s": 0.5, "simulated_time_s": 20.0}) == ""
    assert _compute_html({**result, "wall_time_s": None}) == ""
    assert _compute_html({**result, "block_time_s": {"detector": float("nan")}}) == ""


def test_mission_report_has_the_compute_section(tmp_path) -> None:
    result = dict(RESULT, block_time_s={"detector": 0.3, "guidance": 0.1}, simulated_time_s=40.0)
    path = write_mission_report(tmp_path, result, _circle_log(), dpi=40)
    text = "".join(_check_report(path).text)
    assert "Compute" in text and "ms per simulated s" in text and "simulator" in text
