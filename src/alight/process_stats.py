"""What this process has used: its resident-memory high-water mark (campaign sandboxes, compile helpers)."""

from __future__ import annotations

import sys


def max_rss_mib() -> float:
    """This process's resident-memory high-water mark (MiB); 0 where the platform does not say (Windows)."""
    try:
        import resource
    except ImportError:
        return 0.0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 2**10  # bytes on macOS, KiB on Linux
