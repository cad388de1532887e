"""Shared numerical routines: one implementation of each algorithm that several packages need.

A leaf package: it imports nothing from ``alight`` but :mod:`alight.errors`, so the message types
(:mod:`alight.types`, which takes its rotation helpers and ``FloatArray`` from here), the cameras and every
stage can use it (``tests/meta`` checks the direction). The routines are numba kernels, callable from
other kernels, with typed Python wrappers where Python callers need them.
"""

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
"""The array type of every routine here and of alight's messages (:mod:`alight.types` re-exports it)."""

__all__ = ["FloatArray"]
