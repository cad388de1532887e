"""numba's cache directory is keyed by the whole package's source (alight/compile/cache.py): numba alone
would keep a kernel's machine code after a change to a kernel it calls in another file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from alight.compile import cache as numba_cache
from alight.compile.cache import cache_dir, source_key


def _tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_the_key_changes_with_any_source_file_and_only_with_them(tmp_path: Path) -> None:
    root = _tree(tmp_path / "pkg", {"a.py": "x = 1\n", "sub/b.py": "def f(): return 2\n"})
    key = source_key(root)
    assert len(key) == 16 and source_key(root) == key
    (root / "notes.txt").write_text("not source")
    assert source_key(root) == key  # only .py files count
    (root / "sub" / "b.py").write_text("def f(): return 3\n")  # a callee's file, not the caller's
    changed = source_key(root)
    assert changed != key
    (root / "sub" / "b.py").rename(root / "sub" / "c.py")  # same content, another module
    assert source_key(root) not in (key, changed)


def test_a_given_cache_dir_gets_the_key_once_and_is_not_pruned(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    path, own = cache_dir("0123456789abcdef")
    assert path == tmp_path / "alight-0123456789abcdef" and not own
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(path))  # a child process inherits the keyed directory
    assert cache_dir("0123456789abcdef") == (path, False)
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    path, own = cache_dir("0123456789abcdef")
    assert own and path.name == "alight-0123456789abcdef"


def test_older_caches_beside_the_current_one_are_removed(tmp_path: Path) -> None:
    current = tmp_path / "alight-new"
    for name in ("alight-old", "alight-new", "other"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "kernel.nbi").write_text("x")
    numba_cache._prune(current)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["alight-new", "other"]


def test_importing_alight_points_numba_at_the_keyed_directory(tmp_path: Path) -> None:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    code = "import alight, numba, os; print(numba.config.CACHE_DIR); print(os.environ['NUMBA_CACHE_DIR'])"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    expect = str(tmp_path / f"alight-{source_key()}")
    assert out.stdout.split() == [expect, expect]
    # numba imported before alight: its config is set directly
    code = "import numba, alight; print(numba.config.CACHE_DIR)"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == expect
