"""Where numba caches alight's compiled kernels: one directory per version of the whole package's source.

Every ``@njit`` in alight has ``cache=True``. numba invalidates a kernel's cache entry when *its own*
source file changes, not when a kernel it calls, in another file, does (numba's documented limitation:
"changes in functions called by the cached function are not detected"). ``tick_batch`` in
``sim/physics.py`` calls the rigid body of ``sim/quadrotor.py`` and the rate loop of
``control/``: after an edit of those alone, or a ``git pull`` into an editable install, a process loaded
the old machine code and flew the old physics without a word. So the cache directory is keyed by a hash
of every ``.py`` file of the package: any change of alight's source starts a fresh cache (one full
compile, ``python -m alight.compile.warmup``), and an unchanged install keeps loading in milliseconds.

The directory is ``<root>/alight-<key>``, the root being ``NUMBA_CACHE_DIR`` when set, else
``__pycache__/numba`` inside the package when it is writable (a source checkout), else the user's cache
(``~/.cache/alight/numba/<install>`` on Linux, one per installed copy of the package). Older
``alight-*`` directories under a root of alight's own are removed (a checkout does not grow by a
cache per edit); a root given by ``NUMBA_CACHE_DIR`` is left as it is. It is set before any kernel is
defined: :mod:`alight`'s ``__init__`` calls :func:`configure`, through the environment when numba is not
imported yet (child processes inherit it) and numba's config when it is.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import sys
from pathlib import Path

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
"""The ``alight`` package directory, whose source keys the cache."""
_PREFIX = "alight-"


def source_key(root: Path = PACKAGE_ROOT) -> str:
    """16 hex digits of the SHA-256 of every ``.py`` file under ``root`` (relative path and content, in
    sorted order): equal for equal sources, different after any change."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()[:16]


def _own_root() -> Path:
    local = PACKAGE_ROOT / "__pycache__" / "numba"
    try:
        local.mkdir(parents=True, exist_ok=True)
        if os.access(local, os.W_OK):
            return local
    except OSError:
        pass
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    install = hashlib.sha256(str(PACKAGE_ROOT).encode()).hexdigest()[:12]
    return base / "alight" / "numba" / install


def cache_dir(key: str | None = None) -> tuple[Path, bool]:
    """The cache directory for this source and whether its root is alight's own (prunable)."""
    key = source_key() if key is None else key
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        path = Path(given)
        if path.name == _PREFIX + key:  # inherited from a parent alight process: already keyed
            return path, False
        return path / (_PREFIX + key), False
    return _own_root() / (_PREFIX + key), True


def _prune(current: Path) -> None:
    """Remove the other ``alight-*`` caches beside ``current`` (best effort: another process may be
    using or removing one)."""
    try:
        siblings = list(current.parent.iterdir())
    except OSError:
        return
    for path in siblings:
        if path.name.startswith(_PREFIX) and path != current and path.is_dir():
            shutil.rmtree(path, ignore_errors=True)


def configure() -> Path:
    """Point numba's cache at this source's directory (see the module docstring); returns it."""
    path, own = cache_dir()
    if own:
        _prune(path)
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba is imported already: it read the environment at its import
        config.CACHE_DIR = str(path)  # type: ignore[attr-defined]
    return path
