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
``MALLOC_TRIM_THRESHOLD_`` in the environment.
"""
from __future__ import annotations

import ctypes

__all__ = ["keep_large_blocks"]

#: ``mallopt`` parameters (glibc's malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


def keep_large_blocks(limit: int = 1 << 30) -> bool:
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
    limit = min(int(limit), 1 << 30)
    return bool(mallopt(_M_MMAP_THRESHOLD, limit)) and \
        bool(mallopt(_M_TRIM_THRESHOLD, 2 * limit - 1))
