"""8-connected labelling of a binary image's runs by union-find, compiled with numba: one
implementation for the Falanga tag detector's white runs (:mod:`alight.perception.falanga_tag`) and its
close-range detector's dark runs (:mod:`alight.perception.falanga_close`); each finds its runs its own way
(an adaptive or a global threshold) and links them here.

A run is a horizontal segment of set pixels: row ``row[k]``, columns ``x0[k]..x1[k]``, runs numbered in
row order and, within a row, left to right. Two runs of adjacent rows are 8-connected when their column
ranges overlap or touch diagonally (``x0[j] <= x1[k] + 1`` and ``x1[j] >= x0[k] - 1``). Union-find
(Tarjan 1975) with path halving; a union always links the larger root under the smaller, so the root of
a component is its first run (top-most, then left-most) and every parent pointer points backwards
(``parent[k] <= k``), which :func:`run_roots` uses to resolve all roots in one forward pass.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def find_root(parent, i):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The root of run ``i``, halving the path on the way (every node then points to its grandparent)."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True)
def link_run(parent, x0, x1, k, q, prev_end):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Union run ``k`` with the runs of the previous row that touch it (8-connectivity). ``q``: the first
    previous-row run that may touch it, ``prev_end``: one past that row's last run. Returns the first
    candidate for run ``k + 1`` of the same row: both rows are sorted, so it only moves right."""
    while q < prev_end and x1[q] < x0[k] - 1:
        q += 1
    j = q
    while j < prev_end and x0[j] <= x1[k] + 1:
        a = find_root(parent, k)
        b = find_root(parent, j)
        if a < b:
            parent[b] = a
        elif b < a:
            parent[a] = b
        j += 1
    return q


@numba.njit(cache=True)
def run_roots(parent, n):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The root (first run) of each of the ``n`` runs' components, (n,) int32: one forward pass, since
    ``parent[k] <= k`` makes the root of ``parent[k]`` known before ``k``'s."""
    root = np.empty(n, np.int32)
    for k in range(n):
        root[k] = k if parent[k] == k else root[parent[k]]
    return root
