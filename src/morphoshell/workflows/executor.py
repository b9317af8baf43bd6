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

:func:`run` submits tasks and yields their results as they complete, with a
progress bar on a terminal.
"""
from __future__ import annotations

import concurrent.futures as cf
import logging
import os
from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator

from .._runtime.console import progress

__all__ = ["open_executor", "run", "SerialExecutor", "backend_name"]

log = logging.getLogger(__name__)

#: Thread counts forced to 1 in workers: MUMPS and BLAS must not share a process's threads.
_SINGLE_THREADED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class SerialExecutor(cf.Executor):
    """Runs each task at submission, in this process (``workers=1``)."""

    def submit(self, fn, /, *args, **kwargs):
        """Run ``fn(*args, **kwargs)`` now; return a finished future with its result."""
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
def open_executor(workers: int | None = None, scheduler: str | None = None) -> Iterator[cf.Executor]:
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

    Raises
    ------
    ValueError
        ``workers`` is not a positive integer, or no Dask scheduler answers
        at ``scheduler`` (or Dask is not installed).
    """
    scheduler = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise ValueError(f"workers = {workers!r} must be a positive integer")
    workers = int(workers) if workers else (os.cpu_count() or 1)
    if scheduler is None and workers == 1:
        yield SerialExecutor()
        return
    saved = {k: os.environ.get(k) for k in _SINGLE_THREADED}
    os.environ.update(_SINGLE_THREADED)          # inherited by the worker processes
    try:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            if scheduler is not None:
                raise ValueError("--scheduler needs Dask: pip install 'morphoshell[dask]'") \
                    from None
            log.info("Dask is not installed: a local pool of %d processes", workers)
            with cf.ProcessPoolExecutor(max_workers=workers) as pool:
                yield pool
            return
        if scheduler is not None:
            log.info("connecting to the Dask scheduler at %s", scheduler)
            import copy
            import gc

            import dask
            config = copy.deepcopy(dask.config.config)
            try:
                client = Client(scheduler)
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
            with client:
                yield client.get_executor()
            return
        log.info("starting a Dask LocalCluster of %d single-threaded workers", workers)
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          dashboard_address=":0") as cluster, Client(cluster) as client:
            yield client.get_executor()
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def run(function: Callable[[Any], Any], tasks: Iterable[Any], executor: cf.Executor, *,
        description: str = "tasks") -> Iterator[tuple[int, Any]]:
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

    Yields
    ------
    index : int
        The task's position in ``tasks``.
    result
        ``function(task)``, in order of completion (not of ``tasks``).
    """
    tasks = list(tasks)
    futures = {executor.submit(function, task): i for i, task in enumerate(tasks)}
    for future in progress(cf.as_completed(futures), total=len(tasks), desc=description,
                           unit="task"):
        yield futures[future], future.result()
