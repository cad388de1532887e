"""What numba compiles, measured: the compile meter (CPU time per kernel and per callee) and the record of
the kernel signatures first called from Python (what writes and checks ``kernels.json``).

A leaf of :mod:`alight.compile`: it reads numba's events and wraps its dispatcher, and imports nothing of
alight. Both are for measuring and for writing the kernel list, never for flying.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any


@dataclass
class FunctionCompile:
    """The compiles of one numba function (a kernel, a callee it pulled in, or an overload of numba's own
    such as ``np.empty``'s) seen by a :func:`compile_meter`."""

    exclusive_s: float = 0.0
    """CPU time (s) of its own compiles, the nested compiles of its callees taken out: where the compile
    goes, function by function (the exclusive times of all functions add up to ``compile_s``)."""
    inclusive_s: float = 0.0
    """CPU time (s) of its compiles with their nested compiles (a function compiled inside another's
    compile is counted in both)."""
    signatures: int = 0
    """Signatures compiled (cache misses)."""


@dataclass
class CompileMeter:
    """numba compile work seen while the meter is installed (see :func:`compile_meter`)."""

    compile_s: float = 0.0
    """CPU time (s, this process) spent compiling, outermost compiles only (a kernel's callees are part of
    its compile). CPU rather than wall time, so a busy machine does not inflate it."""
    n_signatures: int = 0
    """Signatures compiled, callees included (cache misses)."""
    by_kernel: dict[str, float] = field(default_factory=dict)
    """Outermost kernel ``module.qualname`` -> CPU seconds of its compile."""
    by_function: dict[str, FunctionCompile] = field(default_factory=dict)
    """Every function compiled, callees included, ``module.qualname`` -> its account."""


@contextlib.contextmanager
def compile_meter() -> Iterator[CompileMeter]:
    """Measure numba compiles in this process while the block runs (loads from the cache do not count:
    numba signals ``numba:compile`` only on a cache miss). numba compiles a kernel's callees inside the
    kernel's own compile, so the events nest: each open compile keeps its start and the CPU time of the
    compiles nested in it."""
    from numba.core import event

    meter = CompileMeter()
    stack: list[list[float]] = []  # per open compile: [CPU time at its start, CPU time of nested compiles]
    lock = threading.Lock()

    class _Listener(event.Listener):
        def on_start(self, ev: Any) -> None:
            with lock:
                stack.append([time.process_time(), 0.0])

        def on_end(self, ev: Any) -> None:
            with lock:
                t0, nested = stack.pop()
                dt = time.process_time() - t0
                fn = ev.data["dispatcher"].py_func
                name = f"{fn.__module__}.{fn.__qualname__}"
                account = meter.by_function.setdefault(name, FunctionCompile())
                account.exclusive_s += dt - nested
                account.inclusive_s += dt
                account.signatures += 1
                meter.n_signatures += 1
                if stack:
                    stack[-1][1] += dt
                    return
                meter.compile_s += dt
                meter.by_kernel[name] = meter.by_kernel.get(name, 0.0) + dt

    listener = _Listener()
    event.register("numba:compile", listener)  # type: ignore[no-untyped-call]
    try:
        yield meter
    finally:
        event.unregister("numba:compile", listener)  # type: ignore[no-untyped-call]


@contextlib.contextmanager
def python_calls() -> Iterator[list[tuple[str, str, str, float]]]:
    """Record each numba kernel signature first called (or compiled with ``.compile``) from Python while
    the block runs, as ``(module, qualname, signature, CPU seconds of the call)``; what a kernel calls is
    compiled inside its caller's compile and is not recorded. How: a Python call that finds no compiled
    signature enters the dispatcher's ``_compile_for_args`` (which loads it from the cache or compiles
    it), and a controller that skips the dispatcher calls ``Dispatcher.compile`` itself; both are wrapped,
    and only the outermost entry counts. These are numba's internals, so this is for writing and checking
    the list, never for flying."""
    from numba.core import dispatcher

    Dispatcher: Any = dispatcher.Dispatcher  # noqa: N806  (numba's stubs lack its internals)
    calls: list[tuple[str, str, str, float]] = []
    depth = threading.local()
    originals = {name: getattr(Dispatcher, name) for name in ("_compile_for_args", "compile")}

    def wrap(original: Any) -> Any:
        def recording(self: Any, *args: Any, **kws: Any) -> Any:
            level = getattr(depth, "n", 0)
            before = set(self.signatures) if level == 0 else set()
            t0 = time.process_time()
            depth.n = level + 1
            try:
                return original(self, *args, **kws)
            finally:
                depth.n = level
                fn = self.py_func
                if level == 0 and fn.__module__.startswith("alight."):
                    dt = time.process_time() - t0
                    for sig in set(self.signatures) - before:
                        calls.append((fn.__module__, fn.__qualname__, repr(sig), dt))

        return recording

    for name, original in originals.items():
        setattr(Dispatcher, name, wrap(original))
    try:
        yield calls
    finally:
        for name, original in originals.items():
            setattr(Dispatcher, name, original)
