"""Engines that fly a campaign's missions in parallel: ``local`` (a pool of worker processes) and
``dask`` (Dask distributed: a scheduler address, or an embedded ``LocalCluster``).

Both run every mission inside a *sandbox*: a child Python process (``subprocess.Popen``, its own
session, so a Ctrl-C at the terminal reaches only the parent) that receives missions over a socket,
flies them one after another and sends back a ``MissionOutcome``. The process that owns a sandbox
(the campaign process for ``local``, a Dask worker for ``dask``) waits for each answer with the
mission's wall-clock deadline; when the deadline passes it kills the sandbox's whole process group
and starts a new one. So:

- a mission that raises becomes an outcome with ``error`` and the traceback, and the sandbox goes on;
- a mission that hangs (even in compiled code that never returns to the interpreter) is killed at its
  deadline and becomes an ``error`` outcome; the worker slot is replaced by a fresh process;
- a sandbox that dies (segfault, ``os._exit``, out of memory) closes its socket, which its owner sees
  at once: an ``error`` outcome, and a fresh process.

With Dask the sandbox lives inside the Dask worker (one per worker thread, kept between tasks, so
start-up costs are paid once per worker); a Dask task never blocks the worker's event loop on a hung
mission and the Dask worker itself is never killed. A Dask worker that dies anyway is Dask's business
(it reschedules the task; past ``distributed.scheduler.allowed-failures`` the task fails, which also
becomes an ``error`` outcome). The engine submits one mission per worker thread at a time and releases
each future as soon as its outcome is here, so a dead worker makes Dask fly again only the mission it was
flying (and one it had just finished whose result had not reached the campaign), never one already
recorded.

A sandbox polls its parent's pid and exits when the parent is gone (a SIGKILLed campaign leaves no
worker behind for long). A sandbox writes nothing where the campaign keeps its results: the files a
mission produces are written into a scratch directory and returned as bytes inside the outcome, and
the campaign process writes them into ``missions/<id>/``. That keeps a single writer, and works with
Dask workers on other machines.

Scratch directories live in one directory per sandbox, ``$TMPDIR/alight-box-<owner pid>-*``, made by the
process that owns the sandbox. The owner removes it when the sandbox is killed, dies or stops (a
SIGKILLed sandbox cannot clean up after itself); a sandbox removes it itself when its socket closes (its
owner stopped it, or died: a SIGKILLed Dask worker's socket closes at once, and the sandbox, which then
exits, must not leave that to its parent watcher's next poll); a sandbox whose owner is gone removes it
before exiting; and the first sandbox a process starts, and every Dask worker when a campaign ends, sweeps
the directories whose owner pid is no longer alive (owner and sandbox both killed at once, e.g. a Dask
worker killed with its process group, or before its sandbox learnt the directory's name). The owner's
pid, not the sandbox's, names the directory, because the owner exists before the sandbox and outlives it.

A sandbox running the default mission function (or its views variant, ``fly_mission_views``) warms up
before it reports ready (:func:`alight.compile.warmup.warm_up`: a short flight of each of the campaign's
presets compiles every numba kernel they use), so compile time never lands in a mission's ``wall_time_s``,
block timers or deadline.

Sandboxes need ``fork``/``exec`` with inherited file descriptors (``pass_fds``): Linux and macOS.

A mission function takes ``(scenario: Scenario, out_dir: Path)``, returns the result dict of
``alight.evaluation.runner.run_mission`` (at least ``outcome``), and may write files into ``out_dir``
(a scratch directory; its contents end up in the mission's directory). It is named by
``"module:qualname"`` (or given as a module-level function, which is turned into that name), because
the sandbox imports it.
"""

from __future__ import annotations

import asyncio
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
import uuid
from collections import deque
from collections.abc import Callable, Generator, Iterable
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from alight.errors import AlightError, ConfigError
from alight.process_stats import max_rss_mib

DEFAULT_MISSION_FN = "alight.campaign.engines:fly_mission"
VIEWS_MISSION_FN = "alight.campaign.engines:fly_mission_views"
"""The default mission with its views: a campaign flies a failure again with it to draw them."""
SIMULATED_MISSION_FNS = (DEFAULT_MISSION_FN, VIEWS_MISSION_FN)
"""Mission functions that fly the simulator: their sandboxes import it and warm up before "ready"."""
CLOCK_FIELDS = frozenset({"wall_time_s", "block_time_s"})
"""The fields of a mission's result that are clocks: two flights of one scenario and seed differ only in
these."""
ENGINES = ("local", "dask")
STARTUP_TIMEOUT_S = 900.0
"""A sandbox that is not ready (imports and warm-up done) after this long is treated as broken (s). The
warm-up compiles numba kernels when the cache is cold: 25-100 s of CPU per preset (100-200 signatures,
``benchmarks/numba_compile.py``; the high end on a slow machine), minutes of wall time on a busy one."""
SCRATCH_PREFIX = "alight-box-"
"""Name of a sandbox's scratch directory in the temporary directory: ``alight-box-<owner pid>-<random>``."""
PARENT_POLL_S = 0.5

MissionFn = Callable[[Any, Path], dict[str, Any]]


@dataclass(frozen=True)
class MissionTask:
    mission_id: str
    scenario: dict[str, Any]
    """The scenario as JSON-compatible data."""
    timeout_s: float
    """Wall-clock limit (s), counted from the moment a ready sandbox receives the mission."""


@dataclass
class MissionOutcome:
    mission_id: str
    result: dict[str, Any] | None
    """The mission function's result; None when ``error`` is set."""
    error: str | None = None
    """One line saying what went wrong (exception, timeout, dead worker); None on success."""
    details: str | None = None
    """The traceback or the circumstances of the error (for ``error.txt``)."""
    files: dict[str, bytes] = field(default_factory=dict)
    """Files the mission wrote (path relative to the mission directory -> contents)."""
    wall_time_s: float = 0.0
    """Wall time from the sandbox receiving the mission to its answer (or to the kill)."""
    max_rss_mib: float | None = None
    """The sandbox's resident-memory high-water mark after the mission (MiB, since the sandbox started,
    warm-up included); None when the sandbox did not answer."""


def fly_mission(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """The campaign's mission: fly ``scenario`` with the log on (the flight energy and the platform
    estimate's RMSE come from it). When it did not land, write the mission's log (log.npz, log.csv,
    log_detections.csv), scenario.yaml and result.json into ``out_dir``: everything needed to study the
    failure, or to fly it again.

    Its views (figures, report.html, replay.gif) are not drawn here: they cost more than the flight
    (about 4 s against 3 s for a 30 s falanga2017 mission, issue 18), and a campaign draws them for the
    first few failures of each cell only (``views_per_cell``, :func:`fly_mission_views`)."""
    from alight.evaluation.mission_io import write_mission_dir
    from alight.evaluation.runner import run_mission

    run = run_mission(scenario, record=True)
    if run.result["outcome"] != "landed":
        write_mission_dir(Path(out_dir), scenario, run, report=False)
    return dict(run.result)


def fly_mission_views(scenario: Any, out_dir: Path) -> dict[str, Any]:
    """:func:`fly_mission` with the views: the same flight, also with a
    :class:`~alight.evaluation.replay.FrameRecorder`; when it did not land, its figures, report.html and
    animated replay (replay.gif) beside the log.

    The recorder keeps 10 downscaled frames per second (about 27 MB for 30 s of a 752x480 camera; at most
    400 frames, 127 MB in colour, however long the mission), and has no frame rendered that the detector
    would not have read except the ones it keeps; the flight is the same as without it."""
    from alight.evaluation.mission_io import write_mission_dir
    from alight.evaluation.replay import FrameRecorder
    from alight.evaluation.runner import run_mission

    recorder = FrameRecorder()
    run = run_mission(scenario, record=True, frame_sink=recorder, frame_wanted=recorder.wants)
    if run.result["outcome"] != "landed":
        write_mission_dir(Path(out_dir), scenario, run, recorder=recorder)
    return dict(run.result)


# -- naming mission functions -----------------------------------------------------------------------------


def function_spec(fn: MissionFn | str | None) -> str:
    """``"module:qualname"`` of a mission function (checked importable here, with one-line errors)."""
    if fn is None:
        return DEFAULT_MISSION_FN
    if isinstance(fn, str):
        resolve_function(fn)
        return fn
    # any callable: a function has both names, a functools.partial or a callable object may have neither
    module, qualname = getattr(fn, "__module__", None), getattr(fn, "__qualname__", "")  # third-party
    if not module or "<" in qualname or module == "__main__":
        raise AlightError(f"mission function {fn!r} must be a module-level function of an importable module")
    spec = f"{module}:{qualname}"
    resolve_function(spec)
    return spec


def resolve_function(spec: str) -> MissionFn:
    import importlib

    module_name, _, qualname = spec.partition(":")
    if not module_name or not qualname:
        raise AlightError(f"mission function '{spec}' must be written module:function")
    try:
        obj: Any = importlib.import_module(module_name)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as err:
        raise AlightError(f"mission function '{spec}' cannot be imported ({err})") from None
    if not callable(obj):
        raise AlightError(f"mission function '{spec}' is not callable")
    return obj  # type: ignore[no-any-return]


# -- inside the sandbox -----------------------------------------------------------------------------------


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    name = type(err).__name__
    return f"{name}: {text}" if text else name


def _collect_files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def execute(task: MissionTask, fn: MissionFn, scratch_root: str | None = None) -> MissionOutcome:
    """Fly one mission in this process; every exception becomes an error outcome. The mission's scratch
    directory is made in ``scratch_root`` (default: the temporary directory)."""
    from alight.scenario import Scenario

    t0 = time.perf_counter()
    scratch = Path(tempfile.mkdtemp(prefix=f"alight-{task.mission_id}-", dir=scratch_root))
    try:
        scenario = Scenario.model_validate(task.scenario)
        result = fn(scenario, scratch)
        if not isinstance(result, dict) or "outcome" not in result:
            raise TypeError(f"the mission function returned {type(result).__name__}, not a result dict")
        return MissionOutcome(
            task.mission_id, result, files=_collect_files(scratch), wall_time_s=time.perf_counter() - t0
        )
    except (Exception, SystemExit) as err:
        return MissionOutcome(
            task.mission_id,
            None,
            error=_one_line(err),
            details=traceback.format_exc(),
            wall_time_s=time.perf_counter() - t0,
        )
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _watch_parent(ppid: int, scratch_root: str | None) -> None:
    def loop() -> None:
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != ppid:
                # The owner, which would have removed it, is gone.
                if scratch_root:
                    shutil.rmtree(scratch_root, ignore_errors=True)
                os._exit(0)

    threading.Thread(target=loop, name="alight-parent-watch", daemon=True).start()


def worker_main(fd: int) -> None:
    """Entry point of a sandbox process: serve missions on the socket ``fd`` until it closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the campaign process decides what a Ctrl-C stops
    conn = Connection(fd)
    try:
        # plain strings and lists of them: safe to unpickle before sys.path is set
        _, sys_path, fn_name, scratch_root, warmup = conn.recv()
    except EOFError:
        return
    _watch_parent(os.getppid(), scratch_root)
    try:
        _serve(conn, sys_path, fn_name, scratch_root, warmup)
    finally:
        # The socket closed: the owner stopped this sandbox, or died (a SIGKILLed Dask worker). This
        # thread sees that at once, before the parent watcher's next poll, and the process then exits:
        # remove the scratch directory here, or a dead owner's would stay behind.
        if scratch_root:
            shutil.rmtree(scratch_root, ignore_errors=True)


def _serve(
    conn: Connection, sys_path: list[str] | None, fn_name: str, scratch_root: str | None, warmup: list[str]
) -> None:
    if sys_path:
        sys.path[:] = list(sys_path)
    try:
        fn = resolve_function(fn_name)
        # Imports before "ready", so a mission's deadline does not pay for them: validating a scenario
        # imports the presets (the whole pipeline), and the default mission the simulator.
        import alight.mission.presets  # noqa: F401
        import alight.scenario  # noqa: F401

        if fn_name in SIMULATED_MISSION_FNS:
            import alight.evaluation.mission_io  # noqa: F401
            import alight.evaluation.runner  # noqa: F401
    except BaseException as err:  # noqa: BLE001  (reported to the owner, which stops the campaign)
        conn.send(("fatal", _one_line(err)))
        return
    warmed: dict[str, Any] = {}
    if warmup:
        # Compile before "ready": a mission's clocks and deadline start after this. A preset whose
        # warm-up flight fails is not fatal: its missions will say what is wrong, each in its own row.
        from alight.compile.warmup import warm_up

        try:
            report = warm_up(warmup)
            warmed = {"wall_s": report.wall_s, "compile_s": report.compile_s}
        except Exception as err:  # noqa: BLE001
            warmed = {"error": _one_line(err)}
    try:
        conn.send(("ready", os.getpid(), warmed))
    except OSError:  # the owner is gone (BrokenPipeError is an OSError)
        return
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message[0] != "run":
            return
        try:
            outcome = execute(message[1], fn, scratch_root)
            outcome.max_rss_mib = max_rss_mib()
            conn.send(("done", outcome))
        except (BrokenPipeError, OSError):
            return


_WORKER_CODE = "import sys; from alight.campaign.engines import worker_main; worker_main(int(sys.argv[1]))"


_LIVE_LOCK = threading.Lock()
_LIVE: set[Sandbox] = set()
"""Sandboxes of this process that are not reaped yet (their process group ids are still theirs)."""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def sweep_stale_scratch(root: str | Path | None = None) -> list[Path]:
    """Remove the sandbox scratch directories in ``root`` (default: the temporary directory) whose owner
    process is no longer alive; return them. A directory whose owner pid was reused by another process
    stays until that one ends: the sweep never removes a live owner's directory."""
    base = Path(root) if root is not None else Path(tempfile.gettempdir())
    removed: list[Path] = []
    try:
        entries = list(base.glob(f"{SCRATCH_PREFIX}*"))
    except OSError:
        return removed
    for path in entries:
        owner = path.name[len(SCRATCH_PREFIX) :].split("-", 1)[0]
        if owner.isdigit() and int(owner) != os.getpid() and not _pid_alive(int(owner)):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


_SWEPT = threading.Event()


class Sandbox:
    """A child process that flies missions; owned by one thread of one process."""

    def __init__(self, fn_spec: str, sys_path: list[str] | None, warmup: tuple[str, ...] = ()) -> None:
        if not _SWEPT.is_set():  # once per owning process, on the machine where its sandboxes run
            _SWEPT.set()
            sweep_stale_scratch()
        self.scratch = Path(tempfile.mkdtemp(prefix=f"{SCRATCH_PREFIX}{os.getpid()}-"))
        ours, theirs = socket.socketpair()
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-c", _WORKER_CODE, str(theirs.fileno())],
                pass_fds=(theirs.fileno(),),
                stdin=subprocess.DEVNULL,
                start_new_session=True,
            )
        except BaseException:
            ours.close()
            shutil.rmtree(self.scratch, ignore_errors=True)
            raise
        finally:
            theirs.close()
        with _LIVE_LOCK:
            _LIVE.add(self)
        self.conn = Connection(ours.detach())
        self.conn.send(("init", sys_path, fn_spec, str(self.scratch), list(warmup)))
        self.ready = False
        self.started = time.monotonic()
        self.task: MissionTask | None = None
        self.deadline = float("inf")
        self.t_sent = 0.0

    def send(self, task: MissionTask) -> None:
        self.task = task
        self.t_sent = time.monotonic()
        self.deadline = self.t_sent + task.timeout_s
        self.conn.send(("run", task))

    def _kill_group(self) -> None:
        # Only while the sandbox is not reaped: until then its pid, and so its process group id, cannot
        # have been reused by an unrelated process.
        if self.proc.returncode is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass

    def kill(self) -> int:
        """Kill the process group (the mission may have started processes of its own); its exit status."""
        with _LIVE_LOCK:
            self._kill_group()
            code = self.proc.wait()  # prompt after SIGKILL
            _LIVE.discard(self)
        self.conn.close()
        shutil.rmtree(self.scratch, ignore_errors=True)  # a killed sandbox cannot remove it itself
        return code

    def close(self) -> None:
        """Ask an idle sandbox to stop (its socket closes); kill it if it does not within a second."""
        self.conn.close()
        try:
            with _LIVE_LOCK:
                self.proc.wait(timeout=1.0)
                _LIVE.discard(self)
        except subprocess.TimeoutExpired:
            pass
        self.kill()

    def died(self) -> int:
        """The sandbox's socket closed: take down what the mission may have started, reap the sandbox and
        return its exit status (a process already exiting keeps its own status)."""
        return self.kill()

    def error_outcome(self, task: MissionTask, what: str, details: str) -> MissionOutcome:
        return MissionOutcome(
            task.mission_id, None, error=what, details=details, wall_time_s=time.monotonic() - self.t_sent
        )


def _status_text(code: int) -> str:
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


def _timeout_outcome(box: Sandbox, task: MissionTask) -> MissionOutcome:
    timeout = task.timeout_s
    box.kill()
    return box.error_outcome(
        task,
        f"timeout: no result after {timeout:g} s wall time; the worker process was killed",
        f"The mission ran longer than the campaign's timeout_s = {timeout:g} s of wall time.\n"
        f"Its worker process (pid {box.proc.pid}) was killed and replaced by a new one.\n",
    )


def _death_outcome(box: Sandbox, task: MissionTask, code: int) -> MissionOutcome:
    return box.error_outcome(
        task,
        f"the worker process died during the mission ({_status_text(code)})",
        f"The worker process (pid {box.proc.pid}) flying this mission ended with {_status_text(code)}\n"
        "without sending a result (a crash in compiled code, os._exit, or the system killing it).\n",
    )


def _over_memory(outcome: MissionOutcome, limit_mib: float | None) -> bool:
    """The sandbox that flew ``outcome`` went over ``limit_mib``: it is replaced by a fresh one (the
    high-water mark never comes down in a living process). The mission itself keeps its result."""
    return limit_mib is not None and outcome.max_rss_mib is not None and outcome.max_rss_mib > limit_mib


def _handshake(box: Sandbox, message: Any) -> None:
    if message[0] == "fatal":
        box.kill()
        raise AlightError(f"campaign worker could not start: {message[1]}")
    if message[0] == "ready":
        box.ready = True


# -- the local engine -------------------------------------------------------------------------------------


class LocalEngine:
    """Missions on ``workers`` sandboxes of this machine, managed by the calling process."""

    name = "local"

    def __init__(
        self,
        workers: int | None = None,
        fn_spec: str = DEFAULT_MISSION_FN,
        warmup: tuple[str, ...] = (),
        memory_limit_mib: float | None = None,
    ) -> None:
        n = (os.cpu_count() or 1) if workers is None else workers
        if n < 1:
            raise AlightError(f"--workers must be >= 1, got {n}")
        self.workers = n
        self.fn_spec = fn_spec
        self.warmup = warmup
        """Presets each sandbox warms up before it reports ready (see alight.compile.warmup)."""
        self.memory_limit_mib = _check_limit(memory_limit_mib)
        """A sandbox whose resident-memory high-water mark is over this after a mission is replaced by a
        fresh one (None: never)."""

    def run(self, tasks: Iterable[MissionTask]) -> Generator[MissionOutcome, None, None]:
        """Yield one outcome per task, in the order they finish. Closing the generator (or an exception
        such as KeyboardInterrupt inside it) kills every sandbox."""
        queue = deque(tasks)
        if not queue:
            return
        sys_path = list(sys.path)
        # With a warm-up, the first sandbox starts alone: it compiles into numba's cache, and the others,
        # started once it is ready, load from there instead of each compiling the same kernels at once.
        n_boxes = min(self.workers, len(queue))
        boxes: list[Sandbox] = [
            Sandbox(self.fn_spec, sys_path, self.warmup) for _ in range(1 if self.warmup else n_boxes)
        ]
        to_start = n_boxes - len(boxes)
        try:
            while queue or any(b.task is not None for b in boxes):
                for b in boxes:
                    if b.ready and b.task is None and queue:
                        b.send(queue.popleft())
                now = time.monotonic()
                deadline = min(
                    [b.deadline for b in boxes if b.task is not None]
                    + [b.started + STARTUP_TIMEOUT_S for b in boxes if not b.ready],
                    default=now + 1.0,
                )
                ready = wait([b.conn for b in boxes], timeout=max(0.0, min(deadline - now, 3600.0)))
                replace: list[Sandbox] = []
                for b in boxes:
                    if b.conn not in ready:
                        continue
                    try:
                        message = b.conn.recv()
                    except (EOFError, OSError):
                        code = b.died()
                        if not b.ready:
                            raise AlightError(
                                f"campaign worker process ended during start-up ({_status_text(code)})"
                            ) from None
                        replace.append(b)
                        if b.task is not None:
                            yield _death_outcome(b, b.task, code)
                        continue
                    if message[0] == "done":
                        b.task, b.deadline = None, float("inf")
                        if _over_memory(message[1], self.memory_limit_mib):
                            b.close()  # idle now: a fresh process starts from the imports' footprint
                            replace.append(b)
                        yield message[1]
                    else:
                        _handshake(b, message)
                        if b.ready and to_start:
                            boxes.extend(
                                Sandbox(self.fn_spec, sys_path, self.warmup) for _ in range(to_start)
                            )
                            to_start = 0
                now = time.monotonic()
                for b in boxes:
                    if b in replace:
                        continue
                    if b.task is not None and now >= b.deadline:
                        replace.append(b)
                        yield _timeout_outcome(b, b.task)
                    elif not b.ready and now >= b.started + STARTUP_TIMEOUT_S:
                        b.kill()
                        raise AlightError(f"campaign worker did not start within {STARTUP_TIMEOUT_S:g} s")
                for b in replace:
                    boxes.remove(b)
                    if queue:
                        boxes.append(Sandbox(self.fn_spec, sys_path, self.warmup))
        finally:
            for b in boxes:
                if b.task is None and b.ready:
                    b.close()
                else:
                    b.kill()


# -- the dask engine --------------------------------------------------------------------------------------

_local = threading.local()


def _dask_task(
    task: MissionTask,
    fn_spec: str,
    sys_path: list[str] | None,
    warmup: tuple[str, ...] = (),
    memory_limit_mib: float | None = None,
) -> MissionOutcome:
    """Runs in a Dask worker thread: fly ``task`` in this thread's sandbox with the task's deadline."""
    box: Sandbox | None = getattr(_local, "box", None)
    key = (fn_spec, tuple(sys_path or ()), tuple(warmup))
    if box is not None and (getattr(_local, "key", None) != key or box.proc.poll() is not None):
        box.close()  # another mission function or campaign, or the sandbox died while idle
        box = None
    if box is None:
        box = Sandbox(fn_spec, sys_path, warmup)
        _local.box, _local.key = box, key
    try:
        while not box.ready:
            left = box.started + STARTUP_TIMEOUT_S - time.monotonic()
            if left <= 0 or not box.conn.poll(left):
                raise AlightError(f"campaign worker did not start within {STARTUP_TIMEOUT_S:g} s")
            _handshake(box, box.conn.recv())
        box.send(task)
        if box.conn.poll(max(0.0, box.deadline - time.monotonic())):
            message = box.conn.recv()
            box.task = None
            if _over_memory(message[1], memory_limit_mib):
                _local.box = None
                box.close()
            return message[1]  # type: ignore[no-any-return]
        _local.box = None
        return _timeout_outcome(box, task)
    except (EOFError, OSError):
        _local.box = None
        code = box.died()
        if box.task is None:
            raise AlightError(
                f"campaign worker process ended during start-up ({_status_text(code)})"
            ) from None
        return _death_outcome(box, task, code)
    except BaseException:
        _local.box = None
        box.kill()
        raise


def stop_sandboxes() -> int:
    """Kill every sandbox of this process (run on each Dask worker when a campaign ends or is stopped):
    idle ones would hold memory on a shared cluster, busy ones belong to cancelled missions. The thread
    that owns a busy one sees its socket close; an idle one is replaced at the next mission. Returns
    how many were signalled."""
    with _LIVE_LOCK:
        boxes = list(_LIVE)
        for box in boxes:
            box._kill_group()
            if box.task is None:  # nobody waits on an idle one: reap it here
                box.proc.wait()
                _LIVE.discard(box)
                shutil.rmtree(box.scratch, ignore_errors=True)
    return len(boxes)


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise AlightError(
            "the dask engine needs dask.distributed, which is not installed: pip install 'alight[dask]'"
        ) from None
    return distributed


def _check_limit(limit_mib: float | None) -> float | None:
    if limit_mib is not None and not limit_mib > 0:
        raise ConfigError(f"memory_limit_mib must be > 0, got {limit_mib}")
    return limit_mib


class DaskEngine:
    """Missions as Dask tasks: on the scheduler at ``scheduler``, or on an embedded ``LocalCluster``
    of ``workers`` processes (one thread each) when no address is given.

    At most as many missions as the cluster has worker threads are submitted at a time, and each future
    is released as soon as its outcome is in this process (before the campaign writes its row). So
    results do not pile up in worker memory, no worker holds a mission waiting behind the one it flies,
    and when a worker dies Dask recomputes only the mission it was flying (and one it had finished whose
    result had not reached this process yet), never one already recorded (a held future whose result
    lived on the dead worker would be flown again)."""

    name = "dask"

    def __init__(
        self,
        scheduler: str | None = None,
        workers: int | None = None,
        fn_spec: str = DEFAULT_MISSION_FN,
        warmup: tuple[str, ...] = (),
        memory_limit_mib: float | None = None,
    ) -> None:
        if scheduler and workers is not None:
            # The cluster at the address has the workers it has: alight cannot start more there, and
            # silently ignoring the number would make two runs look comparable when they are not.
            raise ConfigError(
                "--workers sets the size of the embedded Dask cluster and cannot be used with --scheduler "
                "(the cluster's own workers fly the missions)"
            )
        self.scheduler = scheduler
        n = (os.cpu_count() or 1) if workers is None else workers
        if n < 1:
            raise AlightError(f"--workers must be >= 1, got {n}")
        self.workers = n
        self.fn_spec = fn_spec
        self.warmup = warmup
        self.memory_limit_mib = _check_limit(memory_limit_mib)
        """A sandbox over this high-water mark after a mission is replaced (as in the local engine); in the
        embedded cluster it is also each Dask worker's ``memory_limit``, which its nanny enforces by
        restarting the worker (the worker process itself holds little: the sandbox flies)."""
        _import_distributed()

    def _connect(self) -> tuple[Any, Any]:
        import logging

        distributed = _import_distributed()
        if self.scheduler:
            try:
                return distributed.Client(self.scheduler, timeout="20s"), None
            except (OSError, TimeoutError) as err:
                raise AlightError(
                    f"cannot reach the Dask scheduler at {self.scheduler} ({_one_line(err)})"
                ) from None
        # The embedded cluster's worker processes inherit an ignored SIGINT: a Ctrl-C is the campaign
        # process's to handle (it closes the cluster), instead of each worker printing a traceback.
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            cluster = distributed.LocalCluster(
                n_workers=self.workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
                memory_limit="auto" if self.memory_limit_mib is None else f"{self.memory_limit_mib}MiB",
            )
        finally:
            if main:
                signal.signal(signal.SIGINT, previous)
        return distributed.Client(cluster), cluster

    def run(self, tasks: Iterable[MissionTask]) -> Generator[MissionOutcome, None, None]:
        todo = deque(tasks)
        if not todo:
            return
        distributed = _import_distributed()
        client, cluster = self._connect()
        # An embedded cluster runs on this machine: its sandboxes import from this process's sys.path.
        sys_path = None if cluster is None else list(sys.path)
        live: dict[Any, MissionTask] = {}
        run_id = uuid.uuid4().hex[:8]
        completed = distributed.as_completed()

        def top_up() -> None:
            # One mission per worker thread, no more: what a worker holds when it dies is what Dask flies
            # again (or fails), so it must be only what it is flying (or has just flown and not yet
            # handed over). With more futures than threads the scheduler hands a worker extra tasks that
            # wait there (or in its queue: worker-saturation 1.1 gives a 1-thread worker 2), and a killed
            # worker took three missions with it. A free thread waits only for one round trip (ms) for
            # its next mission of tens of seconds. The cluster may grow or shrink while the campaign runs.
            window = max(1, sum(client.nthreads().values()))
            while todo and len(live) < window:
                t = todo.popleft()
                f = client.submit(
                    _dask_task,
                    t,
                    self.fn_spec,
                    sys_path,
                    self.warmup,
                    self.memory_limit_mib,
                    key=f"alight-{t.mission_id}-{run_id}",
                    pure=False,
                )
                live[f] = t
                completed.add(f)

        try:
            top_up()
            for f in completed:
                task = live.pop(f)
                try:
                    outcome = f.result()
                except (Exception, asyncio.CancelledError) as err:
                    # A Dask-level failure of this mission only: KilledWorker after its workers died more
                    # than distributed.scheduler.allowed-failures times, or a cancellation.
                    if isinstance(err, AlightError):
                        raise
                    outcome = MissionOutcome(
                        task.mission_id,
                        None,
                        error=f"dask task failed: {_one_line(err)}",
                        details="".join(traceback.format_exception(err)),
                    )
                # The outcome is here: from now on the cluster must forget the mission, or a worker death
                # would make Dask fly it again to restore a result nobody needs.
                f.release()
                del f
                top_up()
                yield outcome
        finally:
            try:
                client.cancel(list(live), force=True)
                client.run(stop_sandboxes)
                # a worker killed before its sandbox got its scratch directory's name leaves the directory
                # to whoever sweeps next: every live worker does, now
                client.run(sweep_stale_scratch)
            except Exception:  # noqa: BLE001  (shutting down; the client may already be gone)
                pass
            client.close()
            if cluster is not None:
                cluster.close()


def make_engine(
    name: str,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    fn_spec: str = DEFAULT_MISSION_FN,
    warmup: tuple[str, ...] = (),
    memory_limit_mib: float | None = None,
) -> LocalEngine | DaskEngine:
    """The engine ``name``; ``warmup``: presets every sandbox warms up before its first mission;
    ``memory_limit_mib``: replace a sandbox whose memory high-water mark goes over it."""
    if name == "local":
        if scheduler:
            raise ConfigError("--scheduler needs --engine dask")
        return LocalEngine(workers, fn_spec, warmup, memory_limit_mib)
    if name == "dask":
        return DaskEngine(scheduler, workers, fn_spec, warmup, memory_limit_mib)
    raise AlightError(f"unknown engine '{name}', expected one of {list(ENGINES)}")
