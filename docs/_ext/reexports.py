"""Griffe extensions for the API reference.

- ``from ._x import Y as Y`` is a public re-export. The package follows the equinox/optimistix
  convention of explicit re-exports in each ``__init__.py`` instead of ``__all__``; griffe
  would otherwise treat every imported name as private and the reference pages would list
  nothing.
- Sphinx roles in docstrings (``:func:`name```, ``:class:`~pkg.Name```) are shown as code:
  the docstrings are written for reading in the source, and Markdown has no roles.
"""

import ast
import re

import griffe

_ROLE = re.compile(r":(?:func|class|meth|mod|attr|data|obj|exc|const):`~?([^`]+)`")


class RedundantAliasesArePublic(griffe.Extension):
    """Mark ``import y as y`` / ``from m import y as y`` aliases public."""

    def on_alias_instance(self, *, node, alias, **kwargs) -> None:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            for name in node.names:
                if name.asname is not None and name.asname == name.name.rsplit(".", 1)[-1] == alias.name:
                    alias.public = True


class SphinxRolesAsCode(griffe.Extension):
    """``:func:`x``` → ``x`` in code font, in every docstring."""

    def on_instance(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _ROLE.sub(r"`\1`", obj.docstring.value)
