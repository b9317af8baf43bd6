"""Large arrays from the heap: glibc's default made solves on big meshes superlinear in N.

glibc's ``malloc`` serves a block above its mmap threshold (adaptive, at
most 32 MiB on 64-bit) with fresh pages from the kernel and gives them back
on ``free``.  Every CasADi evaluation on a mesh of 10⁴–10⁵ nodes allocates
and frees such blocks (outputs of tens of MB), so each one page-faults its
way through memory it just had, and a warm re-solve's time grows faster than
the mesh (``scripts/bench_equilibrium.py --only large`` shows it); with large
blocks kept in the heap it grows linearly.  Smaller meshes, whose blocks stay
below the threshold, are not affected.

:func:`keep_large_blocks` raises the mmap and trim thresholds with
``mallopt``; the command line calls it.  It changes the allocator of the
whole process (freed memory is kept for reuse instead of returned at once),
so library users opt in: call it, or set ``MALLOC_MMAP_THRESHOLD_`` and
``MALLOC_TRIM_THRESHOLD_`` in the environment (:data:`ENVIRON`, the same values).
The package's own worker processes get them (:mod:`morphoshell._runtime.workers`).
:func:`served_from_heap` tells which way a process's allocator serves a large block.
"""
from __future__ import annotations

import ctypes

__all__ = ["keep_large_blocks"]

#: ``mallopt`` parameters (glibc's malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: The largest ``limit`` (``mallopt`` takes C ints).
_MAX_LIMIT = 1 << 30


def _thresholds(limit: int) -> tuple[int, int]:
    """(mmap threshold, trim threshold) of :func:`keep_large_blocks` ``(limit)``."""
    limit = min(int(limit), _MAX_LIMIT)
    return limit, 2 * limit - 1


#: The environment variables that give a process started with them the settings of
#: :func:`keep_large_blocks` (glibc reads them at the process's start).
ENVIRON = dict(zip(("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_"),
                   map(str, _thresholds(_MAX_LIMIT))))


def keep_large_blocks(limit: int = _MAX_LIMIT) -> bool:
    """Serve blocks of up to ``limit`` bytes from the heap, and trim it only above 2 ``limit``.

    Parameters
    ----------
    limit : int
        Bytes; at most 1 GiB (``mallopt`` takes C ints).

    Returns
    -------
    bool
        True if glibc accepted both settings; False elsewhere (another C
        library, or no ``mallopt``), where nothing changes.

    Examples
    --------
    >>> import morphoshell
    >>> morphoshell.keep_large_blocks()         # doctest: +SKIP
    True
    """
    try:        # the process's own symbols: glibc's, where it is the C library
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    mmap, trim = _thresholds(limit)
    return bool(mallopt(_M_MMAP_THRESHOLD, mmap)) and bool(mallopt(_M_TRIM_THRESHOLD, trim))


class _Mallinfo2(ctypes.Structure):
    """glibc's ``struct mallinfo2`` (malloc.h, glibc >= 2.33)."""

    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks",
                 "uordblks", "fordblks", "keepcost")]


def served_from_heap(nbytes: int = 4 << 20) -> bool | None:
    """Whether this process's ``malloc`` serves a block of ``nbytes`` from its heap (as
    :func:`keep_large_blocks` makes it do) rather than mapping fresh pages for it.

    Allocates and frees one such block and reads glibc's count of mapped bytes
    (``mallinfo2().hblkhd``) around it: glibc has no call that reads a threshold back.

    Parameters
    ----------
    nbytes : int
        The block's size (default 4 MiB: above glibc's default threshold of 128 KiB and
        below its adaptive one's ceiling, 32 MiB).

    Returns
    -------
    bool or None
        None where the C library has no ``mallinfo2`` (not glibc, or glibc < 2.33).
    """
    try:
        libc = ctypes.CDLL(None)
        mallinfo2, malloc, free = libc.mallinfo2, libc.malloc, libc.free
    except (OSError, AttributeError, TypeError):
        return None
    mallinfo2.restype, malloc.restype = _Mallinfo2, ctypes.c_void_p
    malloc.argtypes, free.argtypes = (ctypes.c_size_t,), (ctypes.c_void_p,)
    before = mallinfo2().hblkhd
    block = malloc(nbytes)
    try:
        return mallinfo2().hblkhd - before < nbytes
    finally:
        free(block)
