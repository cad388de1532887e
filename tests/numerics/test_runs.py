"""The shared run labelling on small images with known components, and against scipy's 8-connected
labelling on random ones."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from alight.numerics.runs import link_run, run_roots


def label_runs(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Runs of a binary image (row order) linked by the shared routines: ``(runs (n, 3) as row, x0, x1;
    root (n,))``."""
    runs: list[tuple[int, int, int]] = []
    row_start = []
    for i, r in enumerate(img.astype(bool)):
        row_start.append(len(runs))
        j = 0
        while j < r.size:
            if r[j]:
                s = j
                while j < r.size and r[j]:
                    j += 1
                runs.append((i, s, j - 1))
            else:
                j += 1
    row_start.append(len(runs))
    n = len(runs)
    arr = np.array(runs, dtype=np.int32).reshape(-1, 3)
    x0 = np.ascontiguousarray(arr[:, 1])
    x1 = np.ascontiguousarray(arr[:, 2])
    parent = np.arange(max(n, 1), dtype=np.int32)
    for i in range(img.shape[0]):
        if i == 0:
            continue
        q = row_start[i - 1]
        for k in range(row_start[i], row_start[i + 1]):
            q = link_run(parent, x0, x1, k, q, row_start[i])
    return arr, run_roots(parent, n)


def components(img: np.ndarray) -> set[frozenset[tuple[int, int]]]:
    """The image's components as sets of pixels, from the runs and their roots."""
    runs, root = label_runs(img)
    comps: dict[int, set[tuple[int, int]]] = {}
    for (i, a, b), r in zip(runs, root, strict=True):
        comps.setdefault(int(r), set()).update((int(i), j) for j in range(a, b + 1))
    return {frozenset(c) for c in comps.values()}


def test_known_small_images() -> None:
    # two blobs joined only diagonally are one component (8-connectivity); a U joins at its bottom
    img = np.array(
        [
            [1, 1, 0, 0, 0, 1, 0, 1],
            [0, 0, 1, 0, 0, 1, 0, 1],
            [0, 0, 0, 0, 0, 1, 1, 1],
            [1, 0, 1, 0, 0, 0, 0, 0],
        ]
    )
    runs, root = label_runs(img)
    assert runs.tolist() == [
        [0, 0, 1], [0, 5, 5], [0, 7, 7], [1, 2, 2], [1, 5, 5], [1, 7, 7], [2, 5, 7], [3, 0, 0], [3, 2, 2],
    ]  # fmt: skip
    # roots are the components' first runs: {diagonal pair}, {U}, and two single pixels
    assert root.tolist() == [0, 1, 1, 0, 1, 1, 1, 7, 8]
    assert run_roots(np.zeros(0, np.int32), 0).shape == (0,)


def test_a_spiral_needs_unions_of_roots_found_late() -> None:
    # the right arm reaches the first run only through the last row: a union of two existing roots
    img = np.array(
        [
            [1, 0, 0, 0, 1],
            [1, 0, 1, 0, 1],
            [1, 0, 1, 0, 1],
            [1, 1, 1, 0, 1],
            [0, 0, 0, 1, 0],
        ]
    )
    _, root = label_runs(img)
    assert set(root.tolist()) == {0}


@pytest.mark.parametrize("seed", range(10))
def test_matches_scipy_8_connected_labelling(seed: int) -> None:
    rng = np.random.default_rng(seed)
    img = rng.random((40, 53)) < rng.uniform(0.2, 0.6)
    lab, n = ndimage.label(img, structure=np.ones((3, 3)))
    ref = {frozenset(zip(*np.nonzero(lab == k), strict=True)) for k in range(1, n + 1)}
    ref = {frozenset((int(i), int(j)) for i, j in c) for c in ref}
    assert components(img) == ref
