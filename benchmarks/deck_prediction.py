"""The deck estimator's prediction error against the truth, per sea state and horizon (issue 37, point 3).

The patrol boat at 5 m/s in bow-quartering seas (150 deg), sea states 2-5, with and without the ship's
motion telemetry (MRU). Each run feeds the simulated pose (30 Hz, 0.1 s latency) and MRU (10 Hz, 0.05 s)
messages of :mod:`alight.sim.sea.deck_sensors` in arrival order; from 60 s on, every 0.5 s, the deck is
predicted 1, 2 and 4 s ahead of the arrival clock and compared with :class:`alight.sim.sea.DeckMotion`.
Prints a markdown table: the RMS error of the pad's height (m), roll and pitch (deg), and, in brackets,
that error over the motion's own standard deviation (1 = no better than guessing the mean); and the
estimator's mean NEES over its 6 physical states at the present.

With ``--ar-order P`` (P > 0) a second table scores a candidate for the longer horizons, not in the
flight: a discrete AR(P) fitted by least squares to the same 0.4 s bins of the last 120 s that the
estimator fits its CAR(4) to (pose and, for roll and pitch, MRU samples averaged per bin), iterated ahead
from the last complete bin and interpolated to the horizon.

    PYTHONPATH=src python benchmarks/deck_prediction.py [--seeds 2] [--duration 240]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from alight.estimation.deck_estimator import DeckEstimator, fit_ar
from alight.sim.sea import DeckMotion, SeaConfig
from alight.sim.sea.deck_sensors import DeckReading, deck_truth, simulate_deck_readings
from alight.types import FloatArray as FloatArr

HORIZONS_S = (1.0, 2.0, 4.0)
SPEED_MPS = 5.0


def feed(est: DeckEstimator, r: DeckReading) -> None:
    """Deliver one message to the estimator at its arrival time."""
    est.set_clock(r.t_arrival)
    if r.kind == "pose":
        est.update_pose(r.t_stamp, r.p_WP, r.cov_p_WP, r.attitude, r.cov_attitude)
    else:
        cov = np.zeros((3, 3))
        cov[:2, :2] = r.cov_attitude
        cov[2, 2] = r.heave_rate_var
        est.update_mru(r.t_stamp, r.attitude, r.heave_rate, cov)


def score(sea_state: int, seed: int, mru: bool, duration_s: float) -> tuple[FloatArr, FloatArr, list[float]]:
    """Errors (n, len(HORIZONS_S), 6), the truth's std (6,), and the NEES samples of one run."""
    config = SeaConfig(sea_state=sea_state, vessel="patrol_boat", wave_direction_deg=150.0)
    deck = DeckMotion.from_config(config, np.random.default_rng(seed), speed_mps=SPEED_MPS)
    readings = simulate_deck_readings(
        deck, duration_s, np.random.default_rng(seed + 1000), speed_mps=SPEED_MPS, mru=mru
    )
    est = DeckEstimator()
    errs: list[FloatArr] = []
    nees: list[float] = []
    t_next = 60.0
    for r in readings:
        feed(est, r)
        if r.t_arrival < t_next:
            continue
        t_next += 0.5
        times = r.t_arrival + np.array((0.0, *HORIZONS_S))
        pred = est.predict(times)
        e = deck_truth(deck, times, SPEED_MPS).state - pred.state
        nees.append(float(e[0] @ np.linalg.solve(pred.cov[0], e[0])))
        errs.append(e[1:])
    sd = deck_truth(deck, np.arange(0.0, duration_s, 0.1), SPEED_MPS).state.std(axis=0)
    return np.array(errs), sd, nees


BIN_S = 0.4
FIT_S = 120.0


def _bins(readings: list[DeckReading], t_end: float) -> FloatArr:
    """(n, 3) bin means of [height, roll, pitch] over [0, t_end) (NaN where a bin is empty)."""
    n = int(t_end / BIN_S)
    acc = np.zeros((n, 3))
    cnt = np.zeros((n, 3))
    for r in readings:
        k = int(r.t_stamp / BIN_S)
        if k >= n:
            continue
        if r.kind == "pose":
            acc[k] += (r.p_WP[2], r.attitude[0], r.attitude[1])
            cnt[k] += 1.0
        else:
            acc[k, 1:] += r.attitude
            cnt[k, 1:] += 1.0
    with np.errstate(invalid="ignore"):
        out: FloatArr = acc / cnt
    return out


def ar_forecast(record: FloatArr, order: int, steps: int) -> FloatArr:
    """The AR(order) forecast of the record's next ``steps`` values (its mean removed and restored)."""
    mu = float(record.mean())
    ar = fit_ar(record, order)
    hist = list(record - mu)
    out = np.empty(steps)
    for i in range(steps):
        v = sum(float(ar[j]) * hist[-1 - j] for j in range(order)) if ar is not None else 0.0
        hist.append(v)
        out[i] = v + mu
    return out


def score_ar(
    sea_state: int, seed: int, mru: bool, duration_s: float, order: int
) -> tuple[FloatArr, FloatArr]:
    """Errors (n, len(HORIZONS_S), 3) of the AR forecast of [height, roll, pitch] and the truth's std (3,)."""
    config = SeaConfig(sea_state=sea_state, vessel="patrol_boat", wave_direction_deg=150.0)
    deck = DeckMotion.from_config(config, np.random.default_rng(seed), speed_mps=SPEED_MPS)
    readings = simulate_deck_readings(
        deck, duration_s, np.random.default_rng(seed + 1000), speed_mps=SPEED_MPS, mru=mru
    )
    bins = _bins(readings, duration_s)
    t_bin = (np.arange(bins.shape[0]) + 0.5) * BIN_S
    steps = int(max(HORIZONS_S) / BIN_S) + 3
    errs: list[FloatArr] = []
    for t_now in np.arange(60.0, duration_s - max(HORIZONS_S) - 1.0, 0.5):
        # the bins complete (and delivered, 0.1 s of camera latency) by t_now
        k1 = int((t_now - 0.1) / BIN_S) - 1
        k0 = max(0, k1 - int(FIT_S / BIN_S) + 1)
        e = np.empty((len(HORIZONS_S), 3))
        times = t_now + np.array(HORIZONS_S)
        truth = deck_truth(deck, times, SPEED_MPS).state[:, [0, 2, 4]]
        for ch in range(3):
            rec = bins[k0 : k1 + 1, ch]
            ok = np.isfinite(rec)
            rec = np.interp(np.arange(rec.shape[0]), np.nonzero(ok)[0], rec[ok])
            fut = ar_forecast(rec, order, steps)
            e[:, ch] = np.interp(times, t_bin[k1] + BIN_S * np.arange(1, steps + 1), fut) - truth[:, ch]
        errs.append(e)
    sd = deck_truth(deck, np.arange(0.0, duration_s, 0.1), SPEED_MPS).state.std(axis=0)[[0, 2, 4]]
    return np.array(errs), sd


def table_ar(seeds: int, duration_s: float, order: int) -> str:
    rows = [
        f"| SS | MRU | horizon | AR({order}) height RMS [m] | roll RMS [deg] | pitch RMS [deg] |",
        "|---|---|---|---|---|---|",
    ]
    for ss in (2, 3, 4, 5):
        for mru in (False, True):
            runs = [score_ar(ss, seed, mru, duration_s, order) for seed in range(seeds)]
            e = np.concatenate([r[0] for r in runs])
            sd = np.mean([r[1] for r in runs], axis=0)
            for k, h in enumerate(HORIZONS_S):
                rms = np.sqrt(np.mean(e[:, k, :] ** 2, axis=0))
                cells = [
                    f"{rms[0]:.3f} ({rms[0] / sd[0]:.2f})",
                    f"{math.degrees(rms[1]):.2f} ({rms[1] / sd[1]:.2f})",
                    f"{math.degrees(rms[2]):.2f} ({rms[2] / sd[2]:.2f})",
                ]
                rows.append(f"| {ss} | {'yes' if mru else 'no'} | {h:g} s | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def table(seeds: int, duration_s: float) -> str:
    rows = [
        "| SS | MRU | horizon | height RMS [m] | roll RMS [deg] | pitch RMS [deg] | NEES (6 dof) |",
        "|---|---|---|---|---|---|---|",
    ]
    for ss in (2, 3, 4, 5):
        for mru in (False, True):
            runs = [score(ss, seed, mru, duration_s) for seed in range(seeds)]
            e = np.concatenate([r[0] for r in runs])
            sd = np.mean([r[1] for r in runs], axis=0)
            nees = float(np.mean(np.concatenate([r[2] for r in runs])))
            for k, h in enumerate(HORIZONS_S):
                rms = np.sqrt(np.mean(e[:, k, :] ** 2, axis=0))
                cells = [
                    f"{rms[0]:.3f} ({rms[0] / sd[0]:.2f})",
                    f"{math.degrees(rms[2]):.2f} ({rms[2] / sd[2]:.2f})",
                    f"{math.degrees(rms[4]):.2f} ({rms[4] / sd[4]:.2f})",
                ]
                n = f"{nees:.2f}" if k == 0 else ""
                rows.append(
                    f"| {ss} | {'yes' if mru else 'no'} | {h:g} s | " + " | ".join(cells) + f" | {n} |"
                )
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--duration", type=float, default=240.0)
    ap.add_argument("--ar-order", type=int, default=0, help="also score an AR of this order (0: no)")
    ap.add_argument("--only-ar", action="store_true", help="score the AR only")
    a = ap.parse_args()
    if not a.only_ar:
        print(table(a.seeds, a.duration))
    if a.ar_order > 0:
        print(table_ar(a.seeds, a.duration, a.ar_order))


if __name__ == "__main__":
    main()
