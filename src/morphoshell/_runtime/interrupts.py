"""Ctrl-C, however it arrives: through CasADi it may not arrive as a ``KeyboardInterrupt``.

Ctrl-C inside a CasADi function (a compiled kernel, a Newton step) reaches
Python as ``SystemError: <built-in function ...> returned a result with an
exception set``, its cause the ``KeyboardInterrupt`` (:func:`interrupted`
says so); reported as such, the user's Ctrl-C read as a bug (exit status 1).
Inside an Ipopt solve CasADi swallows it: it prints a warning and Ipopt
returns ``NonIpopt_Exception_Thrown``, which a fit took for a failed solve
and went on (a serial campaign ran 90 s more).  And CasADi's wrappers try a
conversion's overloads in turn, dropping a ``KeyboardInterrupt`` raised inside
one: ``ca.DM(list)`` during a Ctrl-C returned normally, and a serial campaign
ran to its end (exit 3, not 130).  While :func:`noted` is in force, Python's
Ctrl-C handler also counts the interrupts, so that :func:`swallowed` can tell
such a return from a failure and :func:`check` can raise one that was lost.

SIGTERM (a batch system's stop, ``kill``) is handled the same way under
:func:`noted`: it raises :class:`Terminated`, a ``KeyboardInterrupt``, so that
the work stops as on Ctrl-C (a campaign's workers killed, its one-line message)
and the command line ends with exit status 143 (:func:`exit_status`).  Before,
the process died at once with Python's ``resource_tracker`` warning of leaked
semaphores and no word of what was done.

CasADi also says so itself when Ipopt swallows a Ctrl-C: ``CasADi - <date>
WARNING("KeyboardInterruptException") [.../ipopt_nlp.cpp:132]`` on standard error, a line
above the command's own one-line message that reads like a fault.  Under :func:`noted`
that line is dropped (:class:`_QuietStderr`); CasADi's other messages pass.
"""
from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager
from typing import Callable, Iterator

__all__ = ["interrupted", "noted", "deferred", "swallowed", "check", "Terminated", "exit_status",
           "reason", "worker_start"]

#: Ctrl-Cs (and SIGTERMs) received under :func:`noted` and not yet claimed by :func:`swallowed`.
_received = [0]
#: Whether a SIGTERM arrived under the last :func:`noted` (kept after it: the command line
#: reads it once the work has unwound).
_terminated = [False]


#: What CasADi writes when Ctrl-C reaches it within Ipopt (the line :func:`noted` drops).
CASADI_NOTE = 'WARNING("KeyboardInterruptException")'
#: How CasADi's lines on standard error begin.
_CASADI = "CasADi - "


class _QuietStderr:
    """Standard error without CasADi's line of a Ctrl-C it swallowed (:data:`CASADI_NOTE`).

    CasADi writes through Python's ``sys.stderr`` in pieces (``"CasADi - <date>
    WARNING(\""``, ``"KeyboardInterruptException"``, ...); a line that begins
    ``"CasADi - "`` (or a write that may begin one) is held to its end and dropped if it
    is that note.  Everything else passes at once (a progress bar's ``\\r`` updates are
    not delayed).
    """

    def __init__(self, stream):
        self._stream = stream
        self._held = ""

    def write(self, text: str) -> int:
        n, text, self._held = len(text), self._held + text, ""
        if not (text.startswith(_CASADI) or _CASADI.startswith(text)):
            self._stream.write(text)
            return n
        line, newline, rest = text.partition("\n")
        if not newline:
            self._held = line
        elif CASADI_NOTE not in line:
            self._stream.write(line + newline)
        if rest:
            self.write(rest)
        return n

    def release(self):
        """The stream, with a line held unfinished written out."""
        if self._held:
            self._stream.write(self._held)
            self._held = ""
        return self._stream

    def __getattr__(self, name):
        return getattr(self._stream, name)


class Terminated(KeyboardInterrupt):
    """SIGTERM received under :func:`noted`: stops the work as a Ctrl-C does."""


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is a ``KeyboardInterrupt`` or was caused by one (its ``__cause__`` or
    ``__context__`` chain).

    Parameters
    ----------
    exc : BaseException
        The exception caught.

    Returns
    -------
    bool
    """
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:       # (a chain can loop)
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _count_and_raise(signum, frame):
    """Python's default Ctrl-C handler (raise KeyboardInterrupt), counting the interrupt;
    :class:`Terminated` for SIGTERM."""
    _received[0] += 1
    if signum == signal.SIGTERM:
        _terminated[0] = True
        raise Terminated
    raise KeyboardInterrupt


def exit_status() -> int:
    """The command line's exit status after an interruption: 143 (128 + 15) after a
    SIGTERM under the last :func:`noted`, else 130 (128 + 2, Ctrl-C)."""
    return 143 if _terminated[0] else 130


def reason() -> str:
    """"interrupted", or "terminated (SIGTERM)" after a SIGTERM under the last :func:`noted`."""
    return "terminated (SIGTERM)" if _terminated[0] else "interrupted"


@contextmanager
def noted() -> Iterator[None]:
    """Count the Ctrl-Cs in the block (for :func:`swallowed`); they still raise
    ``KeyboardInterrupt``, and a SIGTERM raises :class:`Terminated`; CasADi's own line of
    a Ctrl-C is dropped from ``sys.stderr`` (:class:`_QuietStderr`).  Only in the main
    thread, and each signal only where it has its default: Python's handler for Ctrl-C (a
    notebook's kernel, or a program's own handler, keeps its own; an ignored Ctrl-C stays
    ignored), the default action for SIGTERM.

    The two are decided apart: a job started in a script's background (``cmd &``) or by
    a ``nohup``-style launcher has Ctrl-C ignored, and a SIGTERM to it must still stop the
    work and keep what was done (it died at once, exit 143 and no word, nothing written).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    sigint = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    # (only where SIGTERM kills at once: a program's own handler stays)
    sigterm = hasattr(signal, "SIGTERM") and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    if not (sigint or sigterm):
        yield
        return
    _terminated[0] = False
    if sigint:
        signal.signal(signal.SIGINT, _count_and_raise)
    if sigterm:
        signal.signal(signal.SIGTERM, _count_and_raise)
    quiet = sys.stderr = _QuietStderr(sys.stderr)
    try:
        yield
    finally:
        if sys.stderr is quiet:     # (else replaced in the block: left as it is)
            sys.stderr = quiet.release()
        if sigint:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        if sigterm:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _received[0] = 0


@contextmanager
def deferred() -> Iterator[Callable[[], None]]:
    """Ctrl-C and SIGTERM held back within the block, for work that an exception would
    leave half done and that ends soon (the start of a Dask cluster, whose own code
    cancels what it waits for).

    Yields ``deliver``: it ends the holding and delivers the first signal held, as if it
    arrived then (the handler in force raises it: under :func:`noted`, a
    ``KeyboardInterrupt`` or :class:`Terminated`, counted); leaving the block calls it.
    A second signal while one is held is raised at once: a start that hangs can still
    be stopped.  Only in the main thread, and only signals with a Python handler (an
    ignored Ctrl-C stays ignored; a SIGTERM with its default action ends the process at
    once, and nothing is printed).
    """
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, getattr(signal, "SIGTERM", None)):
            if sig is not None and callable(signal.getsignal(sig)):
                handlers[sig] = signal.getsignal(sig)
    held: list[int] = []

    def hold(signum, frame):
        if held:
            held.clear()
            handlers[signum](signum, frame)
        held.append(signum)

    def deliver():
        while handlers:
            signal.signal(*handlers.popitem())
        if held:
            signal.raise_signal(held.pop())

    for sig in handlers:
        signal.signal(sig, hold)
    try:
        yield deliver
    finally:
        deliver()


def worker_start() -> None:
    """A pool worker's start (a pool's ``initializer``): Ctrl-C ignored, SIGTERM back to
    its default.

    Ctrl-C (SIGINT to the terminal's process group) is for the process that owns the
    pool, which stops its workers; in a worker it interrupted CasADi mid-message
    ("CasADi - " on the terminal).  A worker forked under :func:`noted` inherits its
    SIGTERM handler, and ``multiprocessing.Pool`` ends its workers with SIGTERM even after
    a successful run: each idle worker raised :class:`Terminated` and printed its
    traceback ("Process ForkPoolWorker-2: ... Terminated", in about half the runs of
    ``morphoshell estimate``, exit 0).  With the default a worker just ends.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGTERM"):
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def swallowed() -> bool:
    """Whether a Ctrl-C arrived under :func:`noted` since the last call (which claims it):
    after a CasADi call that returned, one that CasADi swallowed."""
    received, _received[0] = _received[0], 0
    return received > 0


def check() -> None:
    """Raise ``KeyboardInterrupt`` if a Ctrl-C arrived under :func:`noted` and was not claimed
    (lost on its way through CasADi, say): between the steps of long work.  Claims it."""
    if swallowed():
        raise Terminated if _terminated[0] else KeyboardInterrupt
