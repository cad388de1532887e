"""The range finder's last three readings, filtered for the two readers that need them robust."""

from __future__ import annotations

import math
from collections import deque


class RangeFilter:
    """The last three range-finder readings (m, from the landing-gear feet) as the sensor reports them:
    None or non-finite when invalid (ROS REP 117: ``-inf`` closer than the minimum range, ``+inf`` beyond
    the maximum)."""

    def __init__(self) -> None:
        self._window: deque[float | None] = deque(maxlen=3)
        self.raw_m: float | None = None
        """The latest reading as the sensor reported it (``-inf``: closer than its minimum range): the
        land detector reads it, whose ``-inf`` (too close) is evidence of the floor."""
        self.high_m: float | None = None
        """The largest of the last three readings, robust to one noisy low reading (the detector's)."""
        self.low_m: float | None = None
        """The smallest of the last three readings: what the mission's ground check reads, so that one
        spurious long return cannot trigger it."""

    def update(self, range_m: float | None) -> None:
        """A new reading; ``high_m`` and ``low_m`` are None unless every reading of the window (the last
        three, fewer at the start) is valid."""
        self.raw_m = range_m
        window = self._window
        window.append(range_m if range_m is not None and math.isfinite(range_m) else None)
        if None in window:
            self.high_m = self.low_m = None
        else:
            self.high_m = max(window)  # type: ignore[type-var]  # no None in it
            self.low_m = min(window)  # type: ignore[type-var]
