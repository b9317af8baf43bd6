"""Command line: ``morphoshell COMMAND ...``.

Exit status: 0 on success; 2 for bad input (one line naming the option, key,
value or file, before any work starts, and no output written) or a file that
cannot be written (named); 3 when a
solver fails (``solver failed (status NAME): ...``, its advice in the command
line's terms: :data:`~morphoshell.cli._args.SOLVER_OPTIONS`); 1 only for
a bug in morphoshell (the message says where to report it); 130 when
interrupted (Ctrl-C), 143 when terminated (SIGTERM, handled as Ctrl-C: one line,
workers stopped).  Every output is validated before any work and written all or
nothing (:mod:`morphoshell.cli._outputs`).

``-v``/``--verbose`` (twice: debugging detail) and ``-q``/``--quiet`` (errors
and results only: no warnings, ``note:`` lines or progress bars) set the level
of the standard ``logging`` logger ``"morphoshell"``; they go before or after
the command.
"""
from __future__ import annotations

import argparse
import os
import re
import sys
from typing import Sequence

from .. import __version__
from ._commands import COMMANDS

__all__ = ["main", "build_parser", "listing_parser", "ISSUES_URL"]

#: A negative number, exponent form and -inf included: a value on the command line, not an
#: option (so that a bad one is refused as a number, not as "expected one argument").
_NEGATIVE_NUMBER = re.compile(r"^-((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|inf|infinity)$",
                              re.IGNORECASE)
#: Where bugs are reported (printed with exit status 1).
ISSUES_URL = "https://github.com/morphoshell/morphoshell/issues"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``morphoshell solve: error: ...``, exit status 2.

    A negative number in exponent form (``--k-range -1e9 1``), or ``-inf``, is a value, not an
    option: argparse's own pattern knows only ``-1`` and ``-1.5``.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _add_verbosity(p: argparse.ArgumentParser, top: bool) -> None:
    """-v/--verbose and -q/--quiet (a command's own copies do not reset the top level's)."""
    default = {} if top else {"default": argparse.SUPPRESS}
    group = p.add_mutually_exclusive_group()
    group.add_argument("-v", "--verbose", action="count", help="show progress notes "
                       "(twice: debugging detail, e.g. every continuation step)",
                       **({"default": 0} if top else default))
    group.add_argument("-q", "--quiet", action="store_true", help="show errors and results "
                       "only: no warnings, notes or progress bars", **default)


def _command(argv: Sequence[str]) -> str | None:
    """The command of ``argv``: its first word not an option (-v/-q take no value)."""
    return next((a for a in argv if not a.startswith("-")), None)


def _top_level() -> tuple[argparse.ArgumentParser, argparse._SubParsersAction]:
    """The parser of ``morphoshell`` and its (still empty) subcommands."""
    parser = _Parser(
        prog="morphoshell",
        description="Equilibria of axisymmetric morphoelastic shells by direct energy "
                    "minimisation (CasADi + Ipopt), with a boundary-value reference. Lengths "
                    "are in units of the undeformed radius R, energies in units of C R^2.")
    parser.add_argument("--version", action="version", version=f"morphoshell {__version__}")
    _add_verbosity(parser, top=True)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                parser_class=_Parser)
    return parser, sub


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of ``morphoshell COMMAND ...`` with every command registered.

    With a known ``command``, only the module that registers it is imported
    (the others pull in fitting, midlines and their dependencies: most of a
    fresh process's start-up).
    """
    import importlib

    names = dict.fromkeys(module for module, _ in COMMANDS.values())
    if command in COMMANDS:
        names = (COMMANDS[command][0],)
    modules = [importlib.import_module(f".{n}", __name__) for n in names]
    parser, sub = _top_level()
    for module in modules:
        module.register(sub)
    for command in sub.choices.values():
        _add_verbosity(command, top=False)
    return parser


def listing_parser() -> argparse.ArgumentParser:
    """The parser of ``morphoshell`` with each command's name and one-line help only.

    Enough for ``morphoshell --help``, ``--version`` and a missing or unknown command
    (the same texts as :func:`build_parser`'s), without importing any command module.
    """
    parser, sub = _top_level()
    for command, (_, text) in COMMANDS.items():
        sub.add_parser(command, help=text)
    return parser


def _plugin_of(exc: BaseException) -> str:
    """The plugin family in whose code ``exc`` was raised (its innermost frame of a module
    that an entry point of ``morphoshell.families`` names), or ""."""
    import traceback

    from ..model.profiles import ENTRY_POINT_GROUP, family_entry_points

    packages = {ep.value.split(":")[0].split(".")[0]: (name, ep.value)
                for name, ep in family_entry_points().items()}
    for frame, _ in reversed(list(traceback.walk_tb(exc.__traceback__))):
        top = str(frame.f_globals.get("__name__", "")).split(".")[0]
        if top in packages:
            name, value = packages[top]
            return f"the plugin family {name!r} (entry point {value!r} of {ENTRY_POINT_GROUP!r})"
    return ""


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line on ``argv`` (default ``sys.argv[1:]``); return the exit status.

    0 success, 2 bad input, 3 solver failure, 1 a bug, 130 interrupted, 143
    terminated (see the module's docstring); messages go to standard error.
    """
    from .._runtime.console import configure, reader_may_leave
    from .._runtime.interrupts import check, exit_status, interrupted, noted, reason
    # (from its light home: solvers.results would import NumPy and CasADi before a --help)
    from ..numerics.status import SolverError
    from ._args import SOLVER_OPTIONS, reworded

    try:
        argv = sys.argv[1:] if argv is None else list(argv)
        command = _command(argv)
        parser = build_parser(command) if command in COMMANDS else listing_parser()
        args = parser.parse_args(argv)
    except SystemExit as exc:   # argparse: --help, --version, or a bad argument (2)
        return int(exc.code or 0)
    restore = configure(-1 if args.quiet else args.verbose)
    from .._runtime.allocator import keep_large_blocks
    keep_large_blocks()     # big meshes: large arrays reused, not page-faulted anew (linear in N)
    try:
        with noted(), reader_may_leave():      # (noted: Ctrl-C within Ipopt, numerics.ipopt)
            status = args.run(args)
            if status == 0:     # (a Ctrl-C CasADi dropped in a command that writes nothing;
                check()         # one that reported its interruption returned 130)
            return status
    except ValueError as exc:     # (a ProblemFileError too)
        print(f"morphoshell: error: {exc}", file=sys.stderr)
        return 2
    except SolverError as exc:
        # the status first, always: one inside the message came after 300 characters of a
        # thin shell's advice (audit 26); the advice in the command line's terms
        print(f"morphoshell: solver failed (status {exc.status}): "
              f"{reworded(str(exc), SOLVER_OPTIONS)}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(f"morphoshell: {reason()}", file=sys.stderr)
        return exit_status()
    except BrokenPipeError:   # the reader left, written past reader_may_leave: not a bug
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as exc:     # a file or folder that cannot be read or written, named
        print(f"morphoshell: error: {exc.strerror or exc} ({exc.filename})" if exc.filename
              else f"morphoshell: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug: say so, and where to report it
        if interrupted(exc):      # Ctrl-C within CasADi: a SystemError caused by it
            print(f"morphoshell: {reason()}", file=sys.stderr)
            return exit_status()
        if os.environ.get("MORPHOSHELL_DEBUG"):
            raise
        plugin = _plugin_of(exc)
        if plugin:      # not ours to fix: say whose it is
            print(f"morphoshell: internal error in {plugin}: {type(exc).__name__}: {exc}. "
                  f"Please report it to the plugin's authors (set MORPHOSHELL_DEBUG=1 for the "
                  f"traceback)", file=sys.stderr)
            return 1
        print(f"morphoshell: internal error (a bug in morphoshell {__version__}): "
              f"{type(exc).__name__}: {exc}. Please report it with the command line at "
              f"{ISSUES_URL} (set MORPHOSHELL_DEBUG=1 for the traceback)", file=sys.stderr)
        return 1
    finally:
        restore()
