"""Griffe extension of the API reference: Sphinx roles in docstrings become links.

The docstrings cross-reference in Sphinx style (``:func:`~morphoshell.x.y```),
which Markdown would print literally.  Each role becomes an optional autoref:
a link where the target is documented, plain code where it is not (a private
helper, a module without an API page), never a warning.
"""
from __future__ import annotations

import re

import griffe

_ROLE = re.compile(r":(?:func|class|mod|data|meth|attr|exc|obj|const):`(~?)([^`]+)`")
_FOREIGN = ("np", "numpy", "ca", "casadi", "scipy", "pandas", "xarray", "matplotlib")


class SphinxRoles(griffe.Extension):
    """Convert the roles of every docstring (mkdocs.yml: ``extensions``)."""

    def on_package(self, *, pkg, **kwargs) -> None:      # noqa: D102 - griffe hook
        _convert(pkg)                # the root package gets no on_object call

    def on_object(self, *, obj, **kwargs) -> None:       # noqa: D102 - griffe hook
        _convert(obj)


def _convert(obj) -> None:
    """Replace the Sphinx roles of ``obj``'s docstring by optional autorefs."""
    if obj.docstring is None or "<autoref" in obj.docstring.value:
        return
    module = obj.path if obj.is_module else obj.module.path
    owner = obj if obj.is_class else obj.parent

    def link(match: re.Match) -> str:
        short, target = match.group(1) == "~", match.group(2).strip().rstrip("()")
        first = target.split(".")[0]
        if not target.startswith("morphoshell") and first not in _FOREIGN:
            # relative: a member of the class at hand, else of the module
            in_class = owner is not None and owner.is_class and first in owner.members
            target = f"{owner.path if in_class else module}.{target}"
        shown = target.split(".")[-1] if short else match.group(2)
        return f'<autoref identifier="{target}" optional><code>{shown}</code></autoref>'

    obj.docstring.value = _ROLE.sub(link, obj.docstring.value)
