"""MissionLog: recording, NaN for missing channels, growth, validation, npz/csv round trips."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from alight.errors import InputError
from alight.evaluation.log import CHANNELS, MissionLog, load_arrays
from alight.types import Mode


def _assert_same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert set(a) == set(b)
    for k in a:
        assert a[k].shape == b[k].shape, k
        if a[k].dtype.kind == "U":
            assert a[k].tolist() == b[k].tolist(), k
        else:
            # exact equality (NaN == NaN here): the CSV must carry full float64 precision
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def _random_log(rng: np.random.Generator, n: int = 157) -> MissionLog:
    log = MissionLog(capacity=8)  # small, so the test also exercises growth
    modes = [Mode.TAKEOFF, "explore", Mode.TRACK, "land", Mode.LANDED]
    for k in range(n):
        ch: dict[str, object] = {}
        for name, width in CHANNELS.items():
            if rng.random() < 0.2:
                continue  # left out -> NaN
            v = rng.normal(size=width) * 10 ** rng.uniform(-8, 4)
            ch[name] = float(v[0]) if width == 1 else v
        if k % 11 == 0:
            ch["p_WP_est"] = None  # explicit None -> NaN as well
        log.append(0.02 * k, mode=modes[(k // 30) % len(modes)], **ch)
        if rng.random() < 0.3:
            log.add_detection(0.02 * k - 0.01, rng.normal(size=3))
    return log


def test_round_trip_npz_and_csv_agree(tmp_path):
    rng = np.random.default_rng(1)
    log = _random_log(rng)
    arrays = log.finalize()
    paths = log.save(tmp_path)
    assert {p.name for p in paths.values()} == {"log.npz", "log.csv", "log_detections.csv"}

    from_npz = load_arrays(tmp_path, "npz")
    from_csv = load_arrays(tmp_path, "csv")
    _assert_same(arrays, from_npz)
    _assert_same(arrays, from_csv)
    _assert_same(arrays, MissionLog.load(tmp_path).finalize())
    _assert_same(arrays, MissionLog.load(tmp_path, source="csv").finalize())
    assert arrays["t_det"].shape[0] == log.n_detections > 0
    assert arrays["p_WP_meas"].shape == (log.n_detections, 3)


def test_shapes_dtypes_and_mode_strings():
    log = MissionLog()
    log.append(0.0, mode=Mode.TRACK, p_WB=[1, 2, 3], thrust_N=9.81, motor_N=np.arange(4.0))
    log.append(0.5, mode="land")
    log.append(1.0)
    a = log.finalize()
    n = 3
    assert a["t"].tolist() == [0.0, 0.5, 1.0]
    for name, width in CHANNELS.items():
        assert a[name].dtype == np.float64
        assert a[name].shape == ((n,) if width == 1 else (n, width))
    assert a["mode"].tolist() == ["track", "land", ""]
    assert a["mode"].dtype.kind == "U"
    np.testing.assert_array_equal(a["motor_N"][0], [0, 1, 2, 3])
    assert a["t_det"].shape == (0,) and a["p_WP_meas"].shape == (0, 3)


def test_missing_channels_are_nan():
    log = MissionLog()
    log.append(0.0, p_WB=np.ones(3))
    log.append(0.1, v_WB=np.ones(3), range_m=None)
    a = log.finalize()
    np.testing.assert_array_equal(a["p_WB"][0], [1, 1, 1])
    assert np.isnan(a["p_WB"][1]).all()
    assert np.isnan(a["v_WB"][0]).all()
    for name in CHANNELS:
        if name not in ("p_WB", "v_WB"):
            assert np.isnan(a[name]).all(), name


def test_growth_keeps_every_sample():
    log = MissionLog(capacity=1)
    n = 1000
    for k in range(n):
        log.append(float(k), p_WB=(k, 2 * k, 3 * k), thrust_N=-k, mode=("a", "b")[k % 2])
    a = log.finalize()
    k = np.arange(n, dtype=float)
    np.testing.assert_array_equal(a["t"], k)
    np.testing.assert_array_equal(a["p_WB"], np.column_stack([k, 2 * k, 3 * k]))
    np.testing.assert_array_equal(a["thrust_N"], -k)
    assert a["mode"].tolist() == [("a", "b")[i % 2] for i in range(n)]


def test_finalize_is_a_copy_and_recording_continues():
    log = MissionLog()
    log.append(0.0, p_WB=np.zeros(3))
    a = log.finalize()
    a["p_WB"][0, 0] = 42.0
    log.append(1.0, p_WB=np.ones(3))
    b = log.finalize()
    assert b["p_WB"][0, 0] == 0.0 and b["t"].tolist() == [0.0, 1.0]


@pytest.mark.parametrize(
    "bad",
    [
        {"p_wb": np.zeros(3)},  # unknown (case matters)
        {"p_WB": 1.0},  # a scalar must not be broadcast over a vector channel
        {"p_WB": np.zeros(2)},
        {"p_WB": np.zeros((3, 1))},
        {"motor_N": np.zeros(3)},
        {"thrust_N": np.zeros(3)},
        {"thrust_N": "heavy"},
    ],
)
def test_bad_append_raises_and_leaves_no_trace(bad):
    log = MissionLog()
    log.append(0.0, v_WB=np.ones(3))
    with pytest.raises(ValueError):
        # the good channel comes first, so a partly written row would show up below
        log.append(0.1, range_m=5.0, p_WP=np.ones(3), **bad)
    assert len(log) == 1
    log.append(0.2)
    a = log.finalize()
    assert np.isnan(a["range_m"][1]) and np.isnan(a["p_WP"][1]).all()


def test_time_must_not_decrease_and_be_finite():
    log = MissionLog()
    log.append(1.0)
    log.append(1.0)  # equal times are allowed (e.g. a sample at a mode switch)
    for t in (0.5, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            log.append(t)
    assert len(log) == 2


def test_add_detection_validates_shape():
    log = MissionLog()
    with pytest.raises(ValueError):
        log.add_detection(0.0, [1.0, 2.0])
    for k in range(200):  # past the initial detection buffer
        log.add_detection(0.1 * k, [k, -k, 0.5])
    a = log.finalize()
    np.testing.assert_allclose(a["t_det"], 0.1 * np.arange(200))
    np.testing.assert_array_equal(a["p_WP_meas"][:, 1], -np.arange(200.0))


def test_csv_layout(tmp_path):
    log = MissionLog()
    log.append(0.0, mode=Mode.EXPLORE, p_WB=[0.1, 0.2, 0.3], motor_N=[1, 2, 3, 4])
    log.append(0.02, mode=Mode.TRACK)
    log.save(tmp_path)
    with open(tmp_path / "log.csv", newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    assert header[:4] == ["t", "p_WB_x", "p_WB_y", "p_WB_z"]
    assert header[-1] == "mode"
    assert "motor_N_3" in header and "thrust_N" in header and "range_m" in header
    assert len(header) == 1 + sum(CHANNELS.values()) + 1
    assert len(rows) == 3
    assert rows[1][-1] == "explore" and rows[2][-1] == "track"
    assert float(rows[1][header.index("p_WB_y")]) == 0.2
    assert rows[2][header.index("p_WB_y")] == "nan"


def test_extra_channels_round_trip(tmp_path):
    log = MissionLog(extra_channels={"yaw_est": 1, "q_WC": 4, "a_WB": 3, "gain": 4})
    log.append(0.0, yaw_est=0.3, q_WC=[0, 0, 0, 1], a_WB=[1, 2, 3], gain=[1, 2, 3, 4])
    log.append(0.1, yaw_est=0.4)
    a = log.finalize()
    assert a["q_WC"].shape == (2, 4) and a["yaw_est"].shape == (2,)
    log.save(tmp_path)
    header = (tmp_path / "log.csv").read_text().splitlines()[0].split(",")
    assert [h for h in header if h.startswith("q_WC")] == ["q_WC_x", "q_WC_y", "q_WC_z", "q_WC_w"]
    _assert_same(a, load_arrays(tmp_path, "csv"))
    _assert_same(a, MissionLog.load(tmp_path).finalize())
    with pytest.raises(ValueError):
        MissionLog(extra_channels={"p_WB": 3})


def test_attitude_channels_in_csv(tmp_path):
    """The true and estimated attitude are standard channels, written as q_*_x, _y, _z, _w columns."""
    log = MissionLog()
    log.append(0.0, q_WB=[0.0, 0.0, 0.38268343, 0.92387953], q_WB_est=[0.0, 0.0, 0.0, 1.0])
    log.save(tmp_path)
    header = (tmp_path / "log.csv").read_text().splitlines()[0].split(",")
    i = header.index("q_WB_x")
    assert header[i : i + 8] == [f"q_WB{s}_{a}" for s in ("", "_est") for a in "xyzw"]
    back = load_arrays(tmp_path, "csv")
    assert back["q_WB"][0, 2] == 0.38268343 and back["q_WB_est"][0, 3] == 1.0


def test_load_errors(tmp_path):
    with pytest.raises(InputError):
        load_arrays(tmp_path)
    with pytest.raises(InputError):
        load_arrays(tmp_path, "csv")
    (tmp_path / "log.csv").write_text("x,y\n1,2\n")
    with pytest.raises(InputError):
        load_arrays(tmp_path, "csv")
    with pytest.raises(ValueError):
        load_arrays(tmp_path, "hdf5")
