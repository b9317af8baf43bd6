"""Command line: ``morphoshell COMMAND ...``.

Exit status: 0 on success; 2 for bad input (one line naming the option, key,
value or file, before any work starts, and no output written); 3 when a
solver fails (Ipopt's or the BVP solver's status in the message); 1 only for
a bug in morphoshell (the message says where to report it); 130 when
interrupted.  Every output is validated before any work and written all or
nothing (:mod:`morphoshell.cli._outputs`).
"""
from __future__ import annotations

import argparse
import os
import sys
from typing import Sequence

from .. import __version__

__all__ = ["main", "build_parser", "ISSUES_URL"]

#: Where bugs are reported (printed with exit status 1).
ISSUES_URL = "https://github.com/morphoshell/morphoshell/issues"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``morphoshell solve: error: ...``, exit status 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from . import analytic, estimate, fit, solve

    parser = _Parser(
        prog="morphoshell",
        description="Equilibria of axisymmetric morphoelastic shells by direct energy "
                    "minimisation (CasADi + Ipopt), with a boundary-value reference. Lengths "
                    "are in units of the undeformed radius R, energies in units of C R^2.")
    parser.add_argument("--version", action="version", version=f"morphoshell {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                parser_class=_Parser)
    for module in (solve, analytic, estimate, fit):
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    from ..io import ProblemFileError
    from ..results import SolverError

    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:   # argparse: --help, --version, or a bad argument (2)
        return int(exc.code or 0)
    try:
        return args.run(args)
    except (ProblemFileError, ValueError) as exc:
        print(f"morphoshell: error: {exc}", file=sys.stderr)
        return 2
    except SolverError as exc:
        status = f" (status {exc.status})" if exc.status and exc.status not in str(exc) else ""
        print(f"morphoshell: solver failed{status}: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print("morphoshell: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug: say so, and where to report it
        if os.environ.get("MORPHOSHELL_DEBUG"):
            raise
        print(f"morphoshell: internal error (a bug in morphoshell {__version__}): "
              f"{type(exc).__name__}: {exc}. Please report it with the command line at "
              f"{ISSUES_URL} (set MORPHOSHELL_DEBUG=1 for the traceback)", file=sys.stderr)
        return 1
