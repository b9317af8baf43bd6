"""What every worker process the package starts is given: its environment and its start.

Sweeps and campaigns run on a Dask ``LocalCluster`` or a process pool, and
``estimate`` on a forked pool; each worker must be set up as the command
line's own process is, in one place:

* one thread each for MUMPS and BLAS (:data:`SINGLE_THREADED`): the workers
  share the cores, and MUMPS must not share a process's threads;
* large blocks kept in the heap (:func:`~morphoshell._runtime.allocator.keep_large_blocks`).
  Dask starts its workers with ``MALLOC_TRIM_THRESHOLD_=65536``
  (``distributed.nanny.pre-spawn-environ``), and setting any glibc threshold
  switches off its adaptive mmap threshold: every block above 128 KiB was
  mapped and unmapped at each evaluation (audit 18: 4.4 million page faults
  and 9-10 s of system time on a sweep of 999 ablations on 2 workers, against
  27 000 faults in one process).

A process that is *spawned* reads :data:`WORKER_ENVIRON` from the environment
it inherits (glibc reads its thresholds when it starts: the settings must be
there before); a *forked* one inherits its parent's allocator, whatever it is,
so a pool's initializer (:func:`worker_start`) sets them again.
"""
from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Iterator

from . import interrupts
from .allocator import ENVIRON as _ALLOCATOR, keep_large_blocks

__all__ = ["SINGLE_THREADED", "WORKER_ENVIRON", "worker_environment", "worker_start"]

#: Thread counts forced to 1 in workers: MUMPS and BLAS must not share a process's threads.
SINGLE_THREADED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: The environment of every worker process (threads and allocator).
WORKER_ENVIRON = {**SINGLE_THREADED, **_ALLOCATOR}


@contextmanager
def worker_environment() -> Iterator[None]:
    """:data:`WORKER_ENVIRON` in ``os.environ`` within the block, for the worker processes
    started there to inherit; the variables are restored (or removed) on leaving it.

    A Dask nanny takes a variable of its ``pre-spawn-environ`` from ``os.environ`` where
    it is set there: so ``MALLOC_TRIM_THRESHOLD_`` is this one, not Dask's 65536.
    """
    saved = {k: os.environ.get(k) for k in WORKER_ENVIRON}
    os.environ.update(WORKER_ENVIRON)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def worker_start() -> None:
    """A pool worker's start (a pool's ``initializer``): the signals of
    :func:`~morphoshell._runtime.interrupts.worker_start`, and large blocks kept in the
    heap (a forked worker has its parent's allocator: a library user's default one)."""
    interrupts.worker_start()
    keep_large_blocks()
