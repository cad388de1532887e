"""alight: autonomous vision-based multirotor landing on moving platforms."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("alight")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+source"

__all__ = ["__version__"]
