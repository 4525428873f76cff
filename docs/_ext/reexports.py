"""Griffe extension for the API reference: ``from ._x import Y as Y`` is a public re-export.

The package follows the equinox/optimistix convention of explicit re-exports in each
``__init__.py`` instead of ``__all__``; griffe would otherwise treat every imported name as
private and the reference pages would list nothing.
"""

import ast

import griffe


class RedundantAliasesArePublic(griffe.Extension):
    """Mark ``import y as y`` / ``from m import y as y`` aliases public."""

    def on_alias_instance(self, *, node, alias, **kwargs) -> None:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            for name in node.names:
                if name.asname is not None and name.asname == name.name.rsplit(".", 1)[-1] == alias.name:
                    alias.public = True
