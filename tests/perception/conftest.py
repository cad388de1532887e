"""Fixtures of the perception tests (helpers live in ``perception_scenes.py``)."""

from __future__ import annotations

from pathlib import Path

import pytest
from perception_scenes import real_dir_or_skip


@pytest.fixture
def real_dir() -> Path:
    """The folder of real test photos; the test is skipped, with the reason, when it is absent."""
    return real_dir_or_skip()
