"""``morphoshell example``: print a packaged example problem file to start from."""
from __future__ import annotations

import sys

from ._commands import help_of

__all__ = ["register"]


def register(sub) -> None:
    """Add ``morphoshell example`` to the subcommands ``sub``."""
    from ..io.example_problems import examples

    names = ", ".join(examples())
    p = sub.add_parser(
        "example", help=help_of("example"),
        description="Print the packaged example problem NAME to standard output, e.g. "
                    "`morphoshell example toy2_ablation > my.toml && morphoshell solve my.toml`. "
                    f"Examples: {names}. --list describes them.")
    p.add_argument("name", nargs="?", metavar="NAME", help=f"one of: {names}")
    p.add_argument("--list", action="store_true", help="list the examples with a description")
    p.set_defaults(run=_example)


def _example(args) -> int:
    import textwrap

    from ..io.example_problems import example_text, examples

    if args.list or args.name is None:
        if args.name is not None:
            raise ValueError("give either NAME or --list, not both")
        for name, what in examples().items():
            print(name)
            print(textwrap.indent(textwrap.fill(what, 76), "    "))
        return 0
    sys.stdout.write(example_text(args.name))
    return 0
