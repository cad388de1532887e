"""Shared numerical routines: one implementation of each algorithm that several packages need.

A leaf package: it imports nothing from ``alight`` but :mod:`alight.types` and :mod:`alight.errors`, so
cameras, perception, estimation, planning and campaign can all use it (``tests/meta`` checks the
direction). The polynomial routines are numba kernels, callable from other kernels.
"""
