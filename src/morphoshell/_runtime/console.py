"""What morphoshell shows on the terminal: log messages and progress bars.

Library modules log through ``logging.getLogger(__name__)`` (loggers under
``"morphoshell"``) and never print: progress and notes at INFO or DEBUG,
deprecations and silently-made choices at WARNING, and at :data:`NOTE` (between the
two: shown by the command line unless ``--quiet``, not a warning) a long wait that is
no error, such as compiling the kernels on a machine's first run.  The command line and the
scripts call :func:`configure` (``--verbose``/``--quiet``); in your own
programs the standard ``logging`` configuration applies, e.g.
``logging.getLogger("morphoshell").setLevel(logging.INFO)``.

Progress bars (:func:`progress` over an iterable, :func:`counter` counted by
hand; tqdm on standard error) are shown for long jobs when standard error is a
terminal, morphoshell's warnings are not silenced (``--quiet``) and the process
is not a worker of another (a campaign's fits draw one bar, in the campaign's
process, not one per worker on the same terminal).
"""
from __future__ import annotations

import logging
import sys
from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator, TypeVar

__all__ = ["configure", "progress", "counter", "LOGGER", "NOTE", "verbosity_level",
           "run_script", "reader_may_leave"]

#: The package's root logger name.
LOGGER = "morphoshell"
#: Logging level of a note the command line shows by default (``morphoshell: note: ...``):
#: above INFO (progress, shown with ``-v``), below WARNING (nothing is wrong).
NOTE = 25
logging.addLevelName(NOTE, "NOTE")

T = TypeVar("T")


def verbosity_level(verbosity: int) -> int:
    """Logging level of a verbosity: −1 (``--quiet``) errors only, 0 warnings and
    :data:`NOTE`, 1 (``-v``) progress and notes, 2 or more (``-vv``) debugging detail."""
    if verbosity < 0:
        return logging.ERROR
    return (NOTE, logging.INFO)[verbosity] if verbosity < 2 else logging.DEBUG


class _Formatter(logging.Formatter):
    """``morphoshell: warning: ...``, ``morphoshell: ...`` (INFO), ``morphoshell [module]: ...``.

    Debugging lines name the module by its last name (``continuation``, not
    ``solvers.continuation``): short, and unique in the package.
    """

    def format(self, record: logging.LogRecord) -> str:
        message = record.getMessage()
        if record.levelno >= NOTE:
            return f"morphoshell: {record.levelname.lower()}: {message}"
        if record.levelno <= logging.DEBUG:
            return f"morphoshell [{record.name.rpartition('.')[2]}]: {message}"
        return f"morphoshell: {message}"


def configure(verbosity: int = 0, stream=None) -> Callable[[], None]:
    """Show morphoshell's log messages of ``verbosity`` (see :func:`verbosity_level`) on
    ``stream`` (standard error by default).

    Returns
    -------
    callable
        Undoes the configuration (the command line calls it when it returns,
        so that calling ``main()`` in a program leaves no handler behind).
    """
    logger = logging.getLogger(LOGGER)
    handler = logging.StreamHandler(sys.stderr if stream is None else stream)
    handler.setFormatter(_Formatter())
    old_level = logger.level
    logger.addHandler(handler)
    logger.setLevel(verbosity_level(verbosity))

    def restore() -> None:
        logger.removeHandler(handler)
        logger.setLevel(old_level)
    return restore


class _LeavingReader:
    """Standard output that a reader may leave (``morphoshell sweep ... | head``): from
    the first write or flush that finds the pipe closed on, output goes to the null
    device, so that the command goes on and writes its files."""

    def __init__(self, stream):
        self._stream = stream

    def _guarded(self, action: Callable[[], Any]) -> Any:
        try:
            return action()
        except BrokenPipeError:
            import os

            os.dup2(os.open(os.devnull, os.O_WRONLY), self._stream.fileno())
            return None

    def write(self, text: str) -> int:
        self._guarded(lambda: self._stream.write(text))
        return len(text)

    def flush(self) -> None:
        self._guarded(self._stream.flush)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


@contextmanager
def reader_may_leave() -> Iterator[None]:
    """Standard output (the real one, with a file descriptor) made :class:`_LeavingReader`
    within: a printed table used to raise BrokenPipeError when the reader of a pipe left,
    and the command stopped before writing the --csv and --json it had solved for."""
    stream = sys.stdout
    try:
        stream.fileno()
    except (AttributeError, OSError, ValueError):     # (captured by a test or a notebook)
        yield
        return
    sys.stdout = _LeavingReader(stream)
    try:
        yield
        sys.stdout.flush()
    finally:
        sys.stdout = stream


def run_script(parser, argv, run: Callable[[Any], int]) -> int:
    """Parse ``argv`` with ``parser`` plus -v/--verbose and -q/--quiet, then ``run(args)``
    with morphoshell's log messages configured (and the configuration undone after)."""
    loud = parser.add_mutually_exclusive_group()
    loud.add_argument("-v", "--verbose", action="count", default=0, help="progress notes")
    loud.add_argument("-q", "--quiet", action="store_true", help="no warnings or progress bars")
    args = parser.parse_args(argv)
    restore = configure(-1 if args.quiet else args.verbose)
    try:
        return run(args)
    finally:
        restore()


def _shown(enabled: bool | None) -> bool:
    """Whether a progress bar is drawn: ``enabled``, or by default when standard error is
    a terminal, the ``morphoshell`` logger shows warnings and this is no worker process."""
    if enabled is not None:
        return enabled
    import multiprocessing

    return (logging.getLogger(LOGGER).isEnabledFor(logging.WARNING)
            and hasattr(sys.stderr, "isatty") and sys.stderr.isatty()
            and multiprocessing.parent_process() is None)


def progress(iterable: Iterable[T], *, total: int | None = None, desc: str = "",
             unit: str = "it", enabled: bool | None = None) -> Iterable[T]:
    """``iterable`` with a progress bar on standard error (tqdm).

    Parameters
    ----------
    iterable : iterable
    total : int, optional
        Number of items, if ``iterable`` has no length.
    desc, unit : str
        Label of the bar and of its items.
    enabled : bool, optional
        Default: when standard error is a terminal, the ``morphoshell``
        logger shows warnings (not ``--quiet``) and this is no worker process.
    """
    if not _shown(enabled):
        return iterable
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, leave=False, file=sys.stderr,
                dynamic_ncols=True)


class _NoBar:
    """What :func:`counter` gives when no bar is shown: its methods do nothing."""

    total = 0

    def update(self, n: int = 1) -> None:
        """Nothing (a bar would count ``n`` more)."""

    def set_description(self, desc: str) -> None:
        """Nothing (a bar would relabel itself)."""

    def refresh(self) -> None:
        """Nothing (a bar would redraw itself)."""


@contextmanager
def counter(total: int | None = None, *, desc: str = "", unit: str = "it",
            enabled: bool | None = None) -> Iterator[Any]:
    """A progress bar counted by hand, ``bar.update(n)``: for work that is no iterable (an
    optimiser's evaluations, made through its callbacks).

    Parameters
    ----------
    total : int, optional
        What the count goes to (the bar may be told a new ``total`` on the way).
    desc, unit : str
        Label of the bar and of what it counts.
    enabled : bool, optional
        As :func:`progress`.

    Yields
    ------
    tqdm or a stand-in
        Its ``update``, ``set_description`` and ``refresh``; without a bar they do
        nothing.  The bar is closed, leaving no line, when the block ends.
    """
    if not _shown(enabled):
        yield _NoBar()
        return
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit=unit, leave=False, file=sys.stderr,
               dynamic_ncols=True)
    try:
        yield bar
    finally:
        bar.close()
