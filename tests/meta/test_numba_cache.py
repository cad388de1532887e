"""Every numba kernel of alight caches its machine code (``cache=True``): the compile is paid once per
install, not by every process (each campaign sandbox, each ``alight fly``)."""

from __future__ import annotations

import importlib
import pkgutil

import numba.core.registry
from numba.core.caching import NullCache

import alight


def _dispatchers() -> dict[str, object]:
    found: dict[str, object] = {}
    for info in pkgutil.walk_packages(alight.__path__, "alight."):
        try:
            module = importlib.import_module(info.name)
        except ImportError:  # an optional extra that is not installed (its kernels are not in use either)
            continue
        for name, obj in vars(module).items():
            if isinstance(obj, numba.core.registry.CPUDispatcher) and obj.py_func.__module__ == info.name:
                found[f"{info.name}.{name}"] = obj
    return found


def test_every_numba_kernel_has_cache_enabled() -> None:
    kernels = _dispatchers()
    assert len(kernels) > 100  # the walk found them (the planner, the simulator, the filters, ...)
    uncached = sorted(k for k, d in kernels.items() if isinstance(d._cache, NullCache))  # type: ignore[attr-defined]
    assert uncached == [], f"@njit without cache=True: {uncached}"
