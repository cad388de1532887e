"""Compile a preset's numba kernels in parallel processes before its warm-up flight (issue 18).

A cold warm-up compiles about 200 signatures, one at a time, in one process: numba's compiler is single
threaded (67-98 s of CPU for the alight preset on 2-core machines). The kernels that a warm-up flight
calls from Python, its *outermost* kernels, are listed in ``kernels.json`` with their signatures,
the presets whose flights call them, and the CPU time each compile took. When numba's cache lacks
entries of that list, :func:`compile_ahead` splits the missing ones across helper processes (the longest
compile first, onto the least-loaded helper) that compile them with ``Dispatcher.compile`` and so write
numba's cache. The warm-up flight then loads them in milliseconds.

Why helper processes and not threads: numba holds a global compiler lock. A kernel's callees are compiled
with it, so two helpers may both compile a small shared callee: the price of not sharing a compiler.
All signatures of one kernel go to the same helper (two processes writing one cache index could each drop
the other's entry).

The list is data derived from the code. ``python -m alight.compile.kernel_list --write`` flies each preset's
warm-up on an empty cache and records the kernels called from Python, and a test checks that the list is
what the warm-up flights call. A stale or missing list costs time, never correctness: whatever the
helpers did not compile, the flight compiles, as it always did. So every failure here (no list, a numba
that changed its internals, a helper that died) falls back to that, with a note in the report.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from alight.compile.cache import cache_dir
from alight.process_stats import max_rss_mib

MANIFEST = Path(__file__).with_name("kernels.json")
"""The outermost kernels of each preset's warm-up flight (see the module docstring)."""

MAX_HELPERS = 8
"""Most helper processes."""

HELPER_MEMORY_MIB = 400.0
"""Memory to count per helper when bounding their number by the memory available: a helper holds the
package and LLVM (its peak was 373 MiB compiling half of the alight preset's list, 2026-11-29)."""

HELPER_TIMEOUT_S = 1800.0
"""A helper still compiling after this is killed; the flight compiles what it left."""


@dataclass(frozen=True)
class Kernel:
    """One outermost kernel signature of the list."""

    module: str
    qualname: str
    signature: str
    """``repr`` of the argument types' tuple, e.g. ``(Array(float64, 1, 'C', False, aligned=True),)``."""
    presets: tuple[str, ...]
    compile_s: float
    """CPU time its compile took when the list was written (its callees included), for load balancing."""

    @property
    def name(self) -> str:
        return f"{self.module}.{self.qualname}"


@dataclass
class CompileAheadReport:
    """What :func:`compile_ahead` did."""

    helpers: int = 0
    """Helper processes started (0: nothing was missing, or the list could not be used)."""
    kernels: int = 0
    """Outermost signatures handed to the helpers."""
    wall_s: float = 0.0
    cpu_s: float = 0.0
    """CPU time the helpers spent compiling (their process time, as each reported it)."""
    failed: list[str] = field(default_factory=list)
    """One line per signature or helper that failed (the flight compiles those)."""
    spans: list[tuple[float, float]] = field(default_factory=list)
    """Each helper's (time it had its share, time it finished), ``time.time()`` seconds."""
    peak_mib: float = 0.0
    """The largest peak resident memory of a helper (MiB)."""
    note: str = ""
    """Why nothing was compiled ahead, when nothing was."""


def read_manifest(path: Path = MANIFEST) -> list[Kernel]:
    """The list; raises ``ValueError`` on a file that is not one."""
    data = json.loads(path.read_text(encoding="utf-8"))
    try:
        return [
            Kernel(
                str(k["module"]),
                str(k["qualname"]),
                str(k["signature"]),
                tuple(str(p) for p in k["presets"]),
                float(k["compile_s"]),
            )
            for k in data["kernels"]
        ]
    except (KeyError, TypeError) as err:
        raise ValueError(f"{path}: not a kernel list ({err!r})") from None


def _dispatcher(kernel: Kernel) -> Any:
    obj: Any = importlib.import_module(kernel.module)
    for part in kernel.qualname.split("."):
        obj = getattr(obj, part)
    return obj


def parse_signature(text: str) -> tuple[Any, ...]:
    """The numba argument types written by ``repr`` (numba's types print as their constructors)."""
    from numba.core import types

    namespace = {name: getattr(types, name) for name in dir(types) if not name.startswith("_")}
    value = eval(text, {"__builtins__": {}}, namespace)  # noqa: S307  (our own list, no builtins)
    if not isinstance(value, tuple):
        raise ValueError(f"not a tuple of numba types: {text}")
    return value


def _cached(kernel: Kernel) -> bool:
    """Whether numba's cache holds this signature (through numba's cache index; its internals, so any
    surprise counts as cached: the safe answer starts no helper)."""
    try:
        disp = _dispatcher(kernel)
        sig = parse_signature(kernel.signature)
        index = disp._cache._cache_file._load_index()
        return any(key[0] == sig for key in index)
    except Exception:  # noqa: BLE001
        return True


def _balanced(kernels: Sequence[Kernel], n: int) -> list[list[Kernel]]:
    """``n`` shares, each kernel's signatures together: the longest compile first, onto the share with
    the least work so far (the LPT rule, within 4/3 of the best split)."""
    groups: dict[str, list[Kernel]] = {}
    for k in kernels:
        groups.setdefault(k.name, []).append(k)
    order = sorted(groups.values(), key=lambda g: (-sum(k.compile_s for k in g), g[0].name))
    shares: list[list[Kernel]] = [[] for _ in range(n)]
    loads = [0.0] * n
    for g in order:
        i = loads.index(min(loads))
        shares[i].extend(g)
        loads[i] += sum(k.compile_s for k in g)
    return [s for s in shares if s]


def _available_mib() -> float | None:
    """MemAvailable of /proc/meminfo (MiB); None where there is none (not Linux)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


def helper_count(max_helpers: int | None = None) -> int:
    """Helpers to start: one per core, at most ``MAX_HELPERS`` and ``max_helpers``, and no more than the
    available memory holds at ``HELPER_MEMORY_MIB`` each."""
    n = min(_cores(), MAX_HELPERS, MAX_HELPERS if max_helpers is None else max_helpers)
    available = _available_mib()
    if available is not None:
        n = min(n, int(available // HELPER_MEMORY_MIB))
    return n


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@contextlib.contextmanager
def _exclusive(directory: Path) -> Iterator[None]:
    """Hold a lock file in the cache directory: of two processes warming up together (a campaign's
    sandboxes), one compiles ahead and the other then finds the cache filled."""
    try:
        import fcntl
    except ImportError:  # Windows: no lock; at worst both compile, as without compiling ahead
        yield
        return
    try:
        directory.mkdir(parents=True, exist_ok=True)
        f = open(directory / "compile-ahead.lock", "a+b")  # noqa: SIM115  (held across the yield)
    except OSError:  # a cache directory we cannot write to: numba will not cache there either
        yield
        return
    with f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)


def compile_ahead(
    presets: Iterable[str], *, max_helpers: int | None = None, kernels_file: Path = MANIFEST
) -> CompileAheadReport:
    """Compile the listed kernels of ``presets`` that numba's cache lacks, in parallel helper processes
    (at most one per core, and ``max_helpers``). Returns at once when there is nothing to do or one core
    only. ``kernels_file``: the list to use."""
    report = CompileAheadReport()
    wanted = set(presets)
    try:
        listed = [k for k in read_manifest(kernels_file) if wanted & set(k.presets)]
    except (OSError, ValueError) as err:
        report.note = f"no kernel list ({err})"
        return report
    n_max = helper_count(max_helpers)
    if n_max < 2:
        report.note = "one core, or memory for one helper only: compiling ahead would gain nothing"
        return report
    if all(_cached(k) for k in listed):
        return report
    with _exclusive(cache_dir()[0]):
        missing = [k for k in listed if not _cached(k)]
        if len(missing) < 2:
            return report
        shares = _balanced(missing, min(n_max, len(missing)))
        t0 = time.perf_counter()
        try:
            _run_helpers(shares, report)
        except OSError as err:  # no temporary directory, no process to start: the flight compiles
            report.failed.append(f"compiling ahead stopped: {err}")
        report.wall_s = time.perf_counter() - t0
        report.kernels = len(missing)
    return report


def _run_helpers(shares: list[list[Kernel]], report: CompileAheadReport) -> None:
    env = dict(os.environ)
    src = str(Path(__file__).resolve().parents[2])  # the helpers import this copy of alight
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    with tempfile.TemporaryDirectory(prefix="alight-compile-ahead-") as tmp:
        # Each helper's share in a file of its own, all written before any helper starts (and so before
        # any is waited for).
        paths = [Path(tmp) / f"share{i}.json" for i in range(len(shares))]
        for path, share in zip(paths, shares, strict=True):
            path.write_text(json.dumps([k.__dict__ for k in share]), encoding="utf-8")
        procs = []
        for path in paths:
            try:
                proc = subprocess.Popen(
                    [sys.executable, "-m", "alight.compile.parallel", "--helper", str(path)],
                    stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                    env=env,
                )  # fmt: skip
            except OSError as start_err:
                report.failed.append(f"cannot start a helper ({start_err})")
                continue
            procs.append(proc)
        _collect(procs, report)


def _collect(procs: list[subprocess.Popen[str]], report: CompileAheadReport) -> None:
    report.helpers = len(procs)
    try:
        _read_helpers(procs, report)
    finally:  # interrupted (Ctrl-C): no helper outlives us
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()


def _read_helpers(procs: list[subprocess.Popen[str]], report: CompileAheadReport) -> None:
    deadline = time.monotonic() + HELPER_TIMEOUT_S
    for proc in procs:
        try:
            out, err = proc.communicate(timeout=max(1.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            report.failed.append(f"a helper was still compiling after {HELPER_TIMEOUT_S:g} s")
            continue
        try:
            done = json.loads(out.strip().splitlines()[-1])
            results = done["results"]
            report.spans.append((float(done["read_at"]), float(done["done_at"])))
            report.peak_mib = max(report.peak_mib, float(done["max_rss_mib"]))
        except (ValueError, IndexError, KeyError, TypeError):
            last = (err.strip().splitlines() or ["no output"])[-1]
            report.failed.append(f"a helper ended with status {proc.returncode}: {last}")
            continue
        for r in results:
            report.cpu_s += float(r["cpu_s"])
            if r["error"]:
                report.failed.append(f"{r['name']}: {r['error']}")


def _helper(kernels: list[Kernel]) -> list[dict[str, Any]]:
    """Compile ``kernels`` into numba's cache (in a helper process)."""
    results = []
    for k in kernels:
        t0 = time.process_time()
        error = ""
        try:
            _dispatcher(k).compile(parse_signature(k.signature))
        except Exception as err:  # noqa: BLE001  (reported; the flight compiles it)
            error = f"{type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}"
        results.append({"name": k.name, "cpu_s": time.process_time() - t0, "error": error})
    return results


def _exit_with_parent(poll_s: float = 0.5) -> None:
    """End this helper when the process that started it is gone. An interrupt is cleaned up by
    :func:`_collect`; a parent that is killed (a campaign stopping a sandbox, the OOM killer) is not, and
    its helpers, re-parented, compiled on for nobody for up to :data:`HELPER_TIMEOUT_S`. A daemon thread
    polls the parent id: the compiler gives the interpreter up every few milliseconds."""
    parent = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(poll_s)
            if os.getppid() != parent:
                os._exit(3)

    threading.Thread(target=watch, name="alight-helper-parent-watch", daemon=True).start()


def main(argv: list[str] | None = None) -> int:
    """``python -m alight.compile.parallel --helper SHARE``: a helper process of :func:`compile_ahead`."""
    args = sys.argv[1:] if argv is None else argv
    if args[:1] == ["--helper"] and len(args) == 2:
        _exit_with_parent()
        share = Path(args[1]).read_text(encoding="utf-8")
        read_at = time.time()
        kernels = [Kernel(**{**d, "presets": tuple(d["presets"])}) for d in json.loads(share)]
        results = _helper(kernels)
        done = {"read_at": read_at, "done_at": time.time(), "results": results, "max_rss_mib": max_rss_mib()}
        print(json.dumps(done))
        return 0
    print(
        "usage: python -m alight.compile.parallel --helper SHARE.json (started by compile_ahead)",
        file=sys.stderr,
    )
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
