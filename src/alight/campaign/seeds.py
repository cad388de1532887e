"""Seeds of a campaign: one ``SeedSequence`` tree rooted at the campaign's ``seed``.

The tree has two branches under the root:

- ``(0, condition_index, replicate)``: the scenario seed of every mission of that condition and
  replicate. It does not depend on the preset, so every preset is flown on the same draws (platform
  start, wind, sensor noise) and the presets are compared pairwise; it does not depend on the engine,
  the number of workers or the order in which missions finish either.
- ``(1,)``: the generator that draws the sampled conditions (``sample:`` in a campaign file).

A child's ``spawn_key`` is its path from the root, so ``SeedSequence(seed, spawn_key=(0, c, r))`` is
exactly ``SeedSequence(seed).spawn(1)[0].spawn(c + 1)[c].spawn(r + 1)[r]``, without spawning the
siblings.
"""

from __future__ import annotations

import numpy as np

MISSION_BRANCH = 0
SAMPLE_BRANCH = 1


def mission_seed(campaign_seed: int, condition_index: int, replicate: int) -> int:
    """The scenario seed (an int in [0, 2**32)) of a mission.

    32 bits keep the number exact in a spreadsheet and in JavaScript, which the report and users read
    results.csv with.
    """
    if campaign_seed < 0 or condition_index < 0 or replicate < 0:
        raise ValueError("campaign seed, condition index and replicate must be >= 0")
    ss = np.random.SeedSequence(campaign_seed, spawn_key=(MISSION_BRANCH, condition_index, replicate))
    return int(ss.generate_state(1, np.uint32)[0])


def sample_rng(campaign_seed: int) -> np.random.Generator:
    """The generator that draws a campaign's sampled conditions."""
    if campaign_seed < 0:
        raise ValueError("campaign seed must be >= 0")
    return np.random.default_rng(np.random.SeedSequence(campaign_seed, spawn_key=(SAMPLE_BRANCH,)))
