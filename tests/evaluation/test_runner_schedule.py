"""The runner's rate table (``evaluation/runner.py``): a handler runs at exactly the ticks its period
divides, in table order, and a rate of 0 ticks (a sensor not fitted) never runs."""

from __future__ import annotations

import pytest

from alight.evaluation.runner import RATES_HZ, Handler, _Schedule, _ticks
from alight.sim.world import TICK_DT


def _handler() -> Handler:
    def handler(k: int) -> None:
        return None

    return handler


@pytest.mark.parametrize(
    ("periods", "n_ticks"),
    [
        ((5, 2, 4, 1, 1, 4, 2, 4), 1000),  # the runner's own: odometry, range, flow, ..., log
        ((5, 2, 0, 1, 1, 4, 2, 4), 100),  # no optical-flow module
        ((7, 29, 3), 50),  # common period (609) past the last tick: indexed by the tick itself
        ((5,), 4),  # never due within the mission
    ],
)
def test_the_handlers_due_at_each_tick_are_those_whose_period_divides_it(
    periods: tuple[int, ...], n_ticks: int
) -> None:
    handlers = [_handler() for _ in periods]
    table = list(zip(periods, handlers, strict=True))
    schedule = _Schedule(table, n_ticks)
    runs = dict.fromkeys(handlers, 0)
    for k in range(1, n_ticks + 1):
        due = schedule.phases[k % schedule.period]
        assert due == tuple(h for n, h in table if n > 0 and k % n == 0), k
        for h in due:
            runs[h] += 1
    assert [runs[h] for h in handlers] == [n_ticks // n if n > 0 else 0 for n in periods]


def test_the_fixed_rates_are_whole_numbers_of_ticks() -> None:
    for name, rate_hz in RATES_HZ.items():
        n = _ticks(rate_hz)
        assert n >= 1 and abs(n * TICK_DT * rate_hz - 1.0) < 1e-9, name
    assert {k: _ticks(v) for k, v in RATES_HZ.items()} == {"odometry": 5, "range": 2, "control": 2, "log": 4}
