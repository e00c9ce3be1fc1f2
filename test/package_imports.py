"""The package's modules and the targets of its imports, read as text (for the house-rule tests).

Shared by ``test/test_import_graph.py`` (loops of imports) and ``test/test_architecture.py``
(private names, package faces): one reading of what a module is and where an import points.
"""
from __future__ import annotations

import ast
from pathlib import Path

__all__ = ['module_files', 'from_target']


def module_files(root: Path) -> dict[str, Path]:
    """Dotted module name -> its file, for every module below ``root`` (a package folder).

    A package's ``__init__.py`` stands for the package itself (``pkg.sub``, not
    ``pkg.sub.__init__``).
    """
    out = {}
    for path in root.rglob('*.py'):
        parts = list(path.relative_to(root.parent).with_suffix('').parts)
        if parts[-1] == '__init__':
            parts = parts[:-1]
        out['.'.join(parts)] = path
    return out


def from_target(module: str, path: Path, node: ast.ImportFrom) -> str:
    """The dotted module a ``from ... import`` of ``module`` (in ``path``) imports from."""
    if not node.level:
        return node.module or ''
    base = module.split('.')
    if path.name != '__init__.py':
        base = base[:-1]
    base = base[:len(base) - (node.level - 1)]
    return '.'.join(base + ([node.module] if node.module else []))
