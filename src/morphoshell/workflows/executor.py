"""Parallel execution of small, picklable tasks: Dask distributed, or a local process pool.

Sweeps and fit campaigns send *specifications* (problem descriptions, file
names, numbers) to worker processes, each of which builds and caches its own
solvers: CasADi solvers pickle, but rebuilding them in a worker is cheaper
and robust, and MUMPS is not thread-safe (one thread per worker process).

:func:`open_executor` gives a ``concurrent.futures.Executor``:

* ``scheduler`` (or the environment variable ``DASK_SCHEDULER_ADDRESS``): a
  running Dask scheduler, e.g. on a cluster (``pip install morphoshell[dask]``);
* otherwise, with Dask installed, a ``LocalCluster`` of ``workers``
  single-threaded worker processes;
* without Dask, a ``ProcessPoolExecutor`` of ``workers`` processes;
* ``workers=1`` and no scheduler: the tasks run in this process, in order
  (no start-up cost, and errors keep their tracebacks).

The local workers are set up as :mod:`morphoshell._runtime.workers` says (one
thread each, large blocks kept in the heap).

:func:`run` submits tasks and yields their results as they complete, with a
progress bar on a terminal.
"""
from __future__ import annotations

import ast
import concurrent.futures as cf
import logging
import multiprocessing
import os
import signal
import sys
from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator, Sequence

from .._runtime import interrupts
from .._runtime.console import counter
from .._runtime.workers import worker_environment, worker_start

__all__ = ["open_executor", "run", "SerialExecutor", "backend_name", "check_workers",
           "no_free_core"]

log = logging.getLogger(__name__)

#: Seconds to wait for a Dask scheduler (--scheduler) to answer: a running scheduler on a
#: reachable host answers in well under a second; Dask's default, 30 s, made a mistyped
#: address look like a hang.
CONNECT_SECONDS = 5


class SerialExecutor(cf.Executor):
    """Runs each task at submission, in this process (``workers=1``)."""

    def submit(self, fn, /, *args, **kwargs):
        """Run ``fn(*args, **kwargs)`` now; return a finished future with its result.

        Raises ``KeyboardInterrupt`` first if a Ctrl-C of an earlier task was dropped on
        its way through CasADi (:func:`morphoshell._runtime.interrupts.check`): the tasks
        run at submission, and a sweep went on through all of them.
        """
        interrupts.check()
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # the caller sees it on .result()
            future.set_exception(exc)
        return future


def backend_name(executor: cf.Executor) -> str:
    """"serial", "processes" or "dask" (for reports)."""
    if isinstance(executor, SerialExecutor):
        return "serial"
    if isinstance(executor, cf.ProcessPoolExecutor):
        return "processes"
    return "dask"


@contextmanager
def open_executor(workers: int | None = None,
                  scheduler: str | None = None) -> Iterator[cf.Executor]:
    """A ``concurrent.futures.Executor`` for ``workers`` processes (see the module docstring).

    Parameters
    ----------
    workers : int, optional
        Worker processes (default: the CPU count); ignored with a scheduler.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default from
        ``DASK_SCHEDULER_ADDRESS``.

    Yields
    ------
    concurrent.futures.Executor
        A :class:`SerialExecutor`, a ``ProcessPoolExecutor`` or a Dask
        client's executor; closed (its workers stopped) on leaving the block.
        Left by an exception (Ctrl-C: ``KeyboardInterrupt``), its local
        workers are killed at once and its pending tasks cancelled, quietly:
        a graceful close waits for the running tasks (a process pool: to their
        end; Dask: 4 s, then kills them with three warnings).

    Raises
    ------
    ValueError
        ``workers`` is not a positive integer, or no Dask scheduler answers
        at ``scheduler`` (or Dask is not installed).
    """
    scheduler = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    workers = check_workers(workers) or (os.cpu_count() or 1)
    if scheduler is None and workers == 1:
        yield SerialExecutor()
        return
    # (threads and allocator: inherited by the worker processes, _runtime/workers.py)
    with worker_environment():
        try:
            import distributed  # noqa: F401
        except ImportError:
            if scheduler is not None:
                raise ValueError("--scheduler needs Dask: pip install 'morphoshell[dask]'") \
                    from None
            log.info("Dask is not installed: a local pool of %d processes", workers)
            _check_main_guard(multiprocessing.get_start_method())
            with _process_pool(workers) as pool:
                yield pool
            return
        if scheduler is not None:
            with _remote(scheduler) as executor:
                yield executor
            return
        _check_main_guard(dask_start_method())
        with _local_cluster(workers) as executor:
            yield executor


def check_workers(workers) -> int | None:
    """``workers`` as an int (None stays None); ValueError naming it unless a positive integer."""
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise ValueError(f"workers = {workers!r} must be a positive integer")
    return None if workers is None else int(workers)


def no_free_core() -> bool:
    """Whether the 1-minute load average is at least the CPU count (False where the system
    gives no load average): a second worker would then share a core with other work, and
    parallel routes pay only for far more work (docs/benchmarks.md, "when workers pay")."""
    try:
        return os.getloadavg()[0] >= (os.cpu_count() or 1)
    except (AttributeError, OSError):
        return False


def dask_start_method() -> str:
    """How a Dask ``LocalCluster`` starts its worker processes (Dask's default: spawn)."""
    import dask

    return str(dask.config.get("distributed.worker.multiprocessing-method", "spawn"))


def _check_main_guard(method: str) -> None:
    """RuntimeError, on one line, when worker processes that import the main script
    (``method`` not ``fork``) are started by that script's top-level code outside
    ``if __name__ == "__main__":``.

    Each such worker would run the script again on import, and multiprocessing refuses
    that in the worker ("an attempt has been made to start a new process before the
    current process has finished its bootstrapping phase"): the script got a cascade of
    Dask and multiprocessing tracebacks (299 lines) that did not name the cause.
    """
    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    # (a package's __main__, `python -m package`, is not run again by the workers)
    if method == "fork" or (spec is not None and spec.name.rpartition(".")[2] == "__main__"):
        return
    script = getattr(main, "__file__", None)
    frame = sys._getframe(1)
    while frame is not None:
        if (frame.f_code.co_name == "<module>" and frame.f_globals.get("__name__") == "__main__"
                and script
                and os.path.abspath(frame.f_code.co_filename) == os.path.abspath(script)):
            break
        frame = frame.f_back
    if frame is None or _guarded(script, frame.f_lineno):
        return
    raise RuntimeError(
        f"{script}, line {frame.f_lineno}: starts worker processes outside "
        f"'if __name__ == \"__main__\":'; each worker imports the script and would run it "
        f"again: put the call under that guard (or use workers=1)")


def _guarded(script: str, line: int) -> bool:
    """Whether ``line`` of ``script`` lies in an ``if __name__ == "__main__":`` block (True
    when the script cannot be read: no refusal on a guess)."""
    try:
        with open(script, encoding="utf-8") as fh:
            tree = ast.parse(fh.read())
    except (OSError, SyntaxError, ValueError):
        return True
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and node.lineno <= line <= (node.end_lineno or line):
            names = {getattr(n, "id", getattr(n, "value", None))
                     for n in (node.test.left, *node.test.comparators)} \
                if isinstance(node.test, ast.Compare) else set()
            if names == {"__name__", "__main__"}:
                return True
    return False


@contextmanager
def _process_pool(workers: int) -> Iterator[cf.Executor]:
    """A ``ProcessPoolExecutor``; left by an exception, its workers are killed at once."""
    pool = cf.ProcessPoolExecutor(max_workers=workers, initializer=worker_start)
    try:
        yield pool
    except BaseException:
        # shutdown() would wait for the running tasks (fits of minutes); Python 3.14's
        # terminate_workers() is this (the pool's own table of its processes)
        _kill(p.pid for p in list(getattr(pool, "_processes", {}).values()))
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


@contextmanager
def _local_cluster(workers: int) -> Iterator[cf.Executor]:
    """A Dask ``LocalCluster`` of ``workers`` single-threaded processes and its executor.

    Its scheduler and workers log nothing below CRITICAL: a task's error reaches the
    campaign through its future, and what else they logged were tracebacks of their own
    recovery (a worker's heartbeat that timed out while the scheduler's thread waited on
    the GIL, in a campaign that then finished with every fit done).  Its workers do not
    take Ctrl-C (:func:`_loop_without_ctrl_c`).

    A Ctrl-C or SIGTERM while it starts (a second or more) is held back until it has
    started, then raised (:func:`morphoshell._runtime.interrupts.deferred`) and handled
    as during the work.  Raised within the start, it stopped Dask half way (its ``sync``
    cancels what it waits for): Dask's exit hook then closed the half-built cluster and
    failed on nannies still starting ("Exception ignored in atexit callback ...
    AssertionError: Status.init"), and a worker's spawn left half done printed
    "EOFError: Ran out of input" once this process had gone (audit 23 F5).
    """
    from distributed import Client, LocalCluster

    log.info("starting a Dask LocalCluster of %d single-threaded workers", workers)
    with _level_kept("distributed") as dask_log, _loop_without_ctrl_c() as loop, \
            interrupts.deferred() as deliver, \
            LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                         dashboard_address=":0", silence_logs=logging.CRITICAL,
                         loop=loop) as cluster, \
            Client(cluster) as client:
        executor = client.get_executor()
        try:
            deliver()       # a Ctrl-C or SIGTERM held back while the cluster started
            yield executor
        except BaseException:
            # A graceful close asks each busy worker to stop, waits 4 s, kills it, and
            # logs three warnings (tasks cancelled, workers killed): kill them first, and
            # keep Dask's loggers quiet while the cluster closes (a shutdown asked for).
            dask_log.setLevel(logging.CRITICAL)
            _kill(_worker_pids(cluster))
            executor.shutdown(wait=False)
            raise


@contextmanager
def _loop_without_ctrl_c() -> Iterator[Any]:
    """Dask's event loop, run in a thread started with Ctrl-C (SIGINT) blocked; stopped on
    leaving the block.

    The loop's thread starts the threads that spawn the worker processes, and a blocked
    signal stays blocked through thread creation, fork and exec (Python's own
    ``multiprocessing.resource_tracker`` is started so): a Ctrl-C to the terminal's
    process group no longer reaches the workers, as in a process pool (their
    ``worker_start``).  A Dask worker took it while it started and printed its
    traceback ("Fatal Python error: init_import_site ... KeyboardInterrupt", audit 23
    F5); a running one is killed by this process anyway.  This thread still takes it.

    Python's resource tracker is started first, here: its start unblocks the signals in
    the thread that starts it (``SIG_UNBLOCK``, not the mask it found), and Dask started
    it from the loop's thread, whose threads then spawned workers that took Ctrl-C.
    """
    from distributed.utils import LoopRunner

    runner = LoopRunner()
    try:
        if hasattr(signal, "pthread_sigmask"):
            from multiprocessing import resource_tracker
            resource_tracker.ensure_running()
        with _ctrl_c_blocked():
            runner.start()
        yield runner.loop
    finally:
        runner.stop()


@contextmanager
def _ctrl_c_blocked() -> Iterator[None]:
    """SIGINT blocked in this thread within the block (where the system has signal masks);
    one that arrives meanwhile is delivered on leaving it."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@contextmanager
def _remote(scheduler: str) -> Iterator[cf.Executor]:
    """The executor of a client of the Dask scheduler at ``scheduler`` (ValueError if none
    answers); left by an exception, its pending tasks are cancelled."""
    import copy
    import gc

    import dask
    from distributed import Client

    log.info("connecting to the Dask scheduler at %s", scheduler)
    config = copy.deepcopy(dask.config.config)
    try:
        # (Dask's own connect timeout is 30 s of retries: a scheduler that does not
        # answer in CONNECT_SECONDS is refused before any work)
        client = Client(scheduler, timeout=CONNECT_SECONDS)
        failure = None
    except Exception as exc:      # unreachable, refused, not an address, ...
        failure = f"{type(exc).__name__}: {exc}"
    if failure is not None:
        # The failed Client closes itself in __del__ when the garbage collector
        # finds it; in the suite that happened inside the next Client's start and
        # deadlocked (its loop runner's lock), or raised an AssertionError there.
        # So collect it now, then undo the configuration it left (the scheduler at
        # "dask.distributed": later dask computations here, xarray's, failed).
        gc.collect()
        dask.config.config.clear()
        dask.config.config.update(config)
        source = ("" if scheduler != os.environ.get("DASK_SCHEDULER_ADDRESS")
                  else " (from DASK_SCHEDULER_ADDRESS)")
        raise ValueError(f"--scheduler {scheduler}{source}: no Dask scheduler "
                         f"answered there: {failure}")
    with _level_kept("distributed") as dask_log, client:
        executor = client.get_executor()
        try:
            yield executor
        except BaseException:
            dask_log.setLevel(logging.CRITICAL)
            executor.shutdown(wait=False)       # (the remote workers are its scheduler's)
            raise


def _worker_pids(cluster) -> list[int]:
    """The process ids of a ``LocalCluster``'s workers (its nannies' child processes)."""
    pids = []
    for nanny in list(getattr(cluster, "workers", {}).values()):
        process = getattr(getattr(nanny, "process", None), "process", None)
        if getattr(process, "pid", None):
            pids.append(process.pid)
    return pids


def _kill(pids: Iterable[int]) -> None:
    """Kill the processes ``pids`` (this process's workers); those already gone are skipped."""
    for pid in pids:
        try:
            os.kill(pid, getattr(signal, "SIGKILL", signal.SIGTERM))
        except (ProcessLookupError, PermissionError):
            pass


@contextmanager
def _level_kept(name: str) -> Iterator[logging.Logger]:
    """The logger ``name``, its level restored on leaving the block (whatever it was set to)."""
    logger = logging.getLogger(name)
    level = logger.level
    try:
        yield logger
    finally:
        logger.setLevel(level)


def run(function: Callable[[Any], Any], tasks: Iterable[Any], executor: cf.Executor, *,
        description: str = "tasks", sizes: Sequence[int] | None = None,
        unit: str = "task") -> Iterator[tuple[int, Any]]:
    """Submit ``function(task)`` for every task; yield ``(index, result)`` as each completes.

    ``function`` must be importable by the workers (a module-level function)
    and the tasks picklable.  An exception in a task is raised here when its
    result is collected, after the tasks already running.

    Parameters
    ----------
    function : callable
        ``function(task)`` → result, run in a worker.
    tasks : iterable
        The tasks, in order.
    executor : concurrent.futures.Executor
        From :func:`open_executor`.
    description : str
        The progress bar's label.
    sizes : sequence of int, optional
        What each task counts for on the bar (default 1: the bar counts tasks), e.g.
        a sweep's points per chunk, counted in ``unit``.
    unit : str
        What the bar counts.

    Yields
    ------
    index : int
        The task's position in ``tasks``.
    result
        ``function(task)``, in order of completion (not of ``tasks``).
    """
    tasks = list(tasks)
    sizes = [1] * len(tasks) if sizes is None else list(sizes)
    futures = {executor.submit(function, task): i for i, task in enumerate(tasks)}
    with counter(total=sum(sizes), desc=description, unit=unit) as bar:
        for future in cf.as_completed(futures):
            i = futures[future]
            result = future.result()
            bar.update(sizes[i])
            yield i, result
