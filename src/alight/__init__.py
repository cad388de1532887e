"""alight: autonomous vision-based multirotor landing on moving platforms."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("alight")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+source"

# Before any kernel is defined: numba's cache keyed by the whole source (see alight/compile/cache.py).
from alight.compile.cache import configure as _configure_numba_cache  # noqa: E402

_configure_numba_cache()

__all__ = ["__version__"]
