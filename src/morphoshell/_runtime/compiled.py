"""Compiled C for CasADi's SX functions: generated once per machine, cached, loaded on use.

A utility for the layers above (no physics here): :func:`compiled_point_function`
compiles one SX function for numerical evaluation;
:func:`morphoshell.numerics.cell_kernels.compiled_cell_functions` builds the cell
kernels' library with :func:`compiled_library`.  Nothing depends on a
compiler: without one (or with ``MORPHOSHELL_COMPILE=0``) the callers keep
CasADi's virtual machine.
"""
from __future__ import annotations

import logging
import os
import platform
import shutil
from functools import lru_cache
from hashlib import blake2b
from pathlib import Path

import casadi as ca
import numpy as np

from .buffered import Buffered
from .console import NOTE


_log = logging.getLogger("morphoshell")
#: Flags of every compilation (the optimisation level is chosen per library).
CFLAGS = ("-O2", "-fPIC", "-shared")
#: Points (or cells) per call of a compiled block (:func:`block_map`): CasADi's
#: map calls a compiled function once per point, at a fixed cost per call; a block
#: loops in C (tuned by scripts/bench_equilibrium.py: warm re-solves).
BLOCK = 64
#: Fewest points mapped in blocks: below, the map's calls cost less than padding
#: and cutting the blocks adds to a build; from here on the point maps (parameter
#: data, geometry, profiles) cost builds nothing noticeable and save warm solves
#: time (tuned by scripts/bench_equilibrium.py: builds and warm re-solves).
BLOCKED_POINTS = 2 * BLOCK
#: Optimisation for large kernels (tens of thousands of SX instructions), where
#: gcc's -O2 takes minutes and -O1 seconds, and the code is still several times
#: faster than CasADi's virtual machine (the KKT fit's per-point misfit kernel).
LARGE = "-O1"


def kernel_cache_dir() -> Path:
    """Where compiled cell kernels are kept: ``$MORPHOSHELL_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/morphoshell`` (default ``~/.cache/morphoshell``)."""
    env = os.environ.get("MORPHOSHELL_CACHE_DIR")
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "morphoshell"


def compiled_library(tag: str, functions: list[ca.Function], compiler: str,
                      optimisation: str = "-O2") -> Path:
    """The shared library of ``functions`` (C by CasADi), compiled once and cached.

    Keyed on the serialised expressions (cheaper than generating the C code),
    the compiler, its flags (``optimisation`` replaces -O2), CasADi's version and the machine, in
    :func:`kernel_cache_dir`; written atomically, so that processes compiling
    at once never load a partial file.  Raises on any failure.
    """
    import hashlib

    flags = (optimisation, *CFLAGS[1:])
    key = hashlib.sha256("\0".join([*(f.serialize() for f in functions), compiler, *flags,
                                     ca.__version__, platform.machine()]).encode())
    path = kernel_cache_dir() / f"{tag}_{key.hexdigest()[:20]}.so"
    if not path.exists():
        import subprocess   # here only: imports that a cached library does not need
        import tempfile

        _note_compiling(path.parent)
        _log.debug("compiling %s (%s)", tag, optimisation)
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            gen = ca.CodeGenerator(f"{tag}.c", {"with_header": False})
            for f in functions:
                gen.add(f)
            gen.generate(tmp + os.sep)
            out = Path(tmp) / "kernels.so"
            subprocess.run([compiler, *flags, str(Path(tmp) / f"{tag}.c"), "-o", str(out),
                            "-lm"], check=True, capture_output=True, timeout=300)
            part = path.with_suffix(f".{os.getpid()}.part")
            shutil.copyfile(out, part)
            os.replace(part, path)
    return path


@lru_cache(maxsize=1)
def _note_compiling(cache: Path) -> None:
    """Say once per process that kernels are being compiled: the first run on a machine
    (or after an upgrade: the cache is keyed on the package's sources) waits for gcc,
    up to 10 s and more for a KKT fit, and had said nothing."""
    _log.log(NOTE, "compiling C kernels for this machine, once (a few seconds; about 10 s "
             "more for a KKT fit); cached in %s", cache)


def compiled_point_function(f: ca.Function, optimisation: str = "-O2",
                            serialised: str | None = None) -> ca.Function:
    """The SX Function ``f`` compiled to C (:func:`compiled_library`), or ``f`` itself.

    For numerical evaluation only (a compiled function has no derivatives):
    per-point functions that results and solves evaluate over every point,
    the parameter data D (:attr:`morphoshell.numerics.parameter_data.ParameterData.numeric`),
    the geometry and the profiles, several times faster than in CasADi's
    virtual machine.
    ``f`` itself if ``MORPHOSHELL_COMPILE=0``, no compiler (``$CC`` or
    ``cc``) is found, or anything fails (logged at debug level).  Compiled
    once per machine (:data:`LARGE` kernels at ``optimisation = LARGE``),
    loaded once per process and expression.  ``serialised``: ``f.serialize()``,
    if the caller has it (serialising is a noticeable part of a build).
    """
    if os.environ.get("MORPHOSHELL_COMPILE", "1") == "0":
        return f
    compiled = _compiled_point(serialised or f.serialize(), optimisation)
    return f if compiled is None else compiled


def compiled_point_map(f: ca.Function, n: int, *args, optimisation: str = "-O2",
                       serialised: str | None = None):
    """``f.map(n)(*args)`` for an SX per-point function ``f``, evaluated in compiled blocks.

    The same numbers as ``compiled_point_function(f).map(n)``, faster from
    :data:`BLOCKED_POINTS` points on (:data:`BLOCK`), and that below;
    ``f.map(n)`` in CasADi's virtual machine where
    :func:`compiled_point_function` would keep it.  ``args`` as for a map:
    each either n times one point's columns, or one point's, shared by all;
    ``serialised`` as for :func:`compiled_point_function`.
    """
    # (below BLOCKED_POINTS block_map would not use a block: none is compiled)
    if n >= BLOCKED_POINTS and os.environ.get("MORPHOSHELL_COMPILE", "1") != "0":
        block = _compiled_block(serialised or f.serialize(), optimisation)
        if block is not None:
            return block_map(block, f, n, args)
    return compiled_point_function(f, optimisation, serialised).map(n)(*args)


def point_map_function(f: ca.Function, n: int, optimisation: str = "-O2",
                       shared: tuple[int, ...] = ()) -> ca.Function:
    """:func:`compiled_point_map` of ``f`` over ``n`` points as a Function.

    Every input is mapped (n times one point's columns) but those numbered in
    ``shared``, given once for all points.
    """
    args = [ca.MX.sym(f.name_in(i), f.size1_in(i), f.size2_in(i) * (1 if i in shared else n))
            for i in range(f.n_in())]
    out = compiled_point_map(f, n, *args, optimisation=optimisation)
    return ca.Function(f"{f.name()}_map{n}", args, list(out) if f.n_out() > 1 else [out],
                       f.name_in(), f.name_out())


#: Points per call of a :class:`PointEvaluator`.
CHUNK = 512


class ChunkedMap:
    """Numbers of a function mapped over ``chunk`` columns, for any number of columns.

    ``mapped`` is the per-column function mapped over ``chunk`` columns
    (``f.map(chunk)`` or :func:`point_map_function`), whose inputs numbered in
    ``shared`` are given once for all columns.  Called once per chunk of
    columns, the last padded with its last column (the padding's values
    are dropped): one evaluator serves every number of columns, where a map
    per size would cost every new size its construction (a Function map costs
    its build time in proportion to the entries of its inputs and outputs).
    """

    def __init__(self, mapped: ca.Function, chunk: int, shared: tuple[int, ...] = ()):
        self.chunk, self._shared = chunk, shared
        # (inputs set in place, outputs read in place: copying each chunk through
        # Buffered's call would cost every warm re-solve)
        self._f = Buffered(mapped)
        self._args, self._res = self._f.args, self._f.res
        self._width = [a.size // (1 if i in shared else chunk) for i, a in enumerate(self._args)]
        self._out = [r.size // chunk for r in self._res]
        self._mapped = [i for i in range(len(self._args)) if i not in shared]

    def __call__(self, n: int, *args) -> list[np.ndarray]:
        """Each output at ``n`` columns, flat (column-major), from each input's ``n`` columns
        (flat, column-major) or, for a shared input, its value."""
        if len(args) != len(self._args):
            raise TypeError(f"{len(self._args)} inputs expected, got {len(args)}")
        args = [np.ravel(a, order="F") for a in args]
        for i in self._shared:
            self._args[i][:] = args[i]
        C = self.chunk
        if n == 0:
            return [np.empty(0) for _ in self._out]
        if n <= C:          # (one call, the common case: no loop, outputs copied once)
            self._fill(args, 0, n)
            self._f.run()
            return [res[:n * w].copy() for res, w in zip(self._res, self._out)]
        outs = [np.empty(w * n) for w in self._out]
        for a in range(0, n, C):
            k = min(C, n - a)
            self._fill(args, a, k)
            self._f.run()
            for out, res, w in zip(outs, self._res, self._out):
                out[a * w:(a + k) * w] = res[:k * w]
        return outs

    def _fill(self, args: list, a: int, k: int) -> None:
        """Put columns a … a + k − 1 of the mapped inputs in place, padded with the last."""
        C = self.chunk
        for i in self._mapped:
            w, dst = self._width[i], self._args[i]
            dst[:k * w] = args[i][a * w:(a + k) * w]
            if k < C:      # (broadcast: np.tile is slower)
                dst[k * w:].reshape(C - k, w)[:] = args[i][(a + k - 1) * w:(a + k) * w]


class PointEvaluator:
    """Numbers of a per-point SX function ``f`` at any number of points, in calls of :data:`CHUNK`.

    Input 0 of ``f`` is the point (a scalar); the others are given once for all
    points.  One compiled evaluator per function, whatever the sizes asked for
    (:class:`ChunkedMap`): an evaluator per size would cost every new mesh size
    its build, and a cache of them would make a session's second solve of a
    size cheaper than its first; the calls in chunks cost warm re-solves next to
    nothing.
    """

    def __init__(self, f: ca.Function):
        shared = tuple(range(1, f.n_in()))
        self._map = ChunkedMap(point_map_function(f, CHUNK, shared=shared), CHUNK, shared)
        self._rows = [f.size1_out(i) for i in range(f.n_out())]
        self._inputs = f.n_in()

    def __call__(self, points, *shared) -> list:
        """Each output at ``points`` (flattened), as a (rows × n) array."""
        points = np.asarray(points, dtype=float).ravel()
        if len(shared) != self._inputs - 1:
            raise TypeError(f"{self._inputs - 1} shared inputs expected, got {len(shared)}")
        outs = self._map(len(points), points, *shared)
        return [out.reshape(len(points), rows).T for out, rows in zip(outs, self._rows)]


def block_function(f: ca.Function, name: str) -> ca.Function:
    """``f`` mapped over :data:`BLOCK` points, as one Function named ``name`` (to compile)."""
    mapped = f.map(BLOCK)
    args = mapped.mx_in()
    return ca.Function(name, args, mapped.call(args), f.name_in(), f.name_out())


def block_map(block: ca.Function | None, f: ca.Function, n: int, args):
    """``f.map(n)(*args)`` by ``block`` (``f`` over :data:`BLOCK` points), called once per block.

    Mapped inputs (n times f's columns) are padded to whole blocks by
    repeating their last point, whose values are dropped; inputs of one
    point's size are shared.  ``f.map(n)`` itself if ``block`` is None or
    n < :data:`BLOCKED_POINTS`.
    """
    for i, a in enumerate(args):
        if a.shape[1] not in (f.size2_in(i), f.size2_in(i) * n):
            raise ValueError(f"input {i} of {f.name()} has {a.shape[1]} columns; "
                             f"expected {f.size2_in(i)} or {f.size2_in(i) * n}")
    if block is None or n < BLOCKED_POINTS:
        return f.map(n)(*args)
    blocks = -(-n // BLOCK)
    pad = blocks * BLOCK - n
    padded = []
    for i, a in enumerate(args):
        a, cols = ca.MX(a), f.size2_in(i)
        if pad and a.size2() == cols * n:
            a = ca.horzcat(a, ca.repmat(a[:, a.size2() - cols:], 1, pad))
        padded.append(a)
    out = block.map(blocks)(*padded)
    out = [out] if block.n_out() == 1 else out
    if pad:   # (horzsplit: far cheaper than slicing, for thousands of points)
        out = [ca.horzsplit(o, [0, f.size2_out(i) * n, o.size2()])[0] for i, o in enumerate(out)]
    return out[0] if len(out) == 1 else tuple(out)


def _compiled_block(serialised: str, optimisation: str) -> ca.Function | None:
    """The block Function (:func:`block_function`) of the SX function ``serialised``, compiled."""
    return _compiled(serialised, optimisation, "morphoshell_blk_", block_function)


def _compiled_point(serialised: str, optimisation: str) -> ca.Function | None:
    """The SX function ``serialised`` compiled."""
    return _compiled(serialised, optimisation, "morphoshell_", renamed)


@lru_cache(maxsize=64)
def _compiled(serialised: str, optimisation: str, prefix: str, wrap) -> ca.Function | None:
    """``wrap(f, name)`` of the SX function ``serialised``, compiled; None if not possible."""
    compiler = shutil.which(os.environ.get("CC", "cc"))
    if compiler is None:
        return None
    f = ca.Function.deserialize(serialised)
    try:
        # the symbol names the expression: structures never clash in one process
        name = prefix + blake2b(serialised.encode(), digest_size=8).hexdigest()
        return ca.external(name, str(compiled_library(name, [wrap(f, name)], compiler,
                                                        optimisation)))
    except Exception as exc:     # no working compiler, read-only cache, ...: stay in CasADi
        _log.debug("%s not compiled (%s: %s); using CasADi's virtual machine", f.name(),
                   type(exc).__name__, exc)
        return None


def renamed(f: ca.Function, name: str) -> ca.Function:
    """The SX Function ``f`` under another name (the symbol of its generated C code)."""
    return ca.Function(name, f.sx_in(), f.call(f.sx_in()), f.name_in(), f.name_out())
