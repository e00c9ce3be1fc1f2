"""Imports inside the package run one way: no module imports, directly or through others,
a module that imports it back.

Every ``import`` counts, also those inside functions (a lazy import is still a dependency)
and those under ``if TYPE_CHECKING:`` (a reader follows annotations too).
"""
from __future__ import annotations

import ast
from pathlib import Path

from package_imports import from_target, module_files

PACKAGE = Path(__file__).resolve().parents[1] / 'feed_axis_energy'


def _targets(module: str, path: Path, node: ast.AST) -> list[str]:
    """Modules an import statement may load (the module and ``module.name`` per name)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    assert isinstance(node, ast.ImportFrom)
    target = from_target(module, path, node)
    # ``from . import x`` loads the submodule x (its package is the importer's own).
    out = [target] if node.module else []
    out += [f'{target}.{alias.name}' for alias in node.names]
    return out


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the package modules it imports."""
    modules = module_files(root)
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding='utf-8'))
        deps = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                deps.update(t for t in _targets(name, path, node)
                            if t in modules and t != name)
        graph[name] = deps
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_checker_finds_a_cycle() -> None:
    graph = {'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}, 'e': set()}
    assert cycles(graph) == [['a', 'b', 'c']]
    assert cycles({'a': {'b'}, 'b': set()}) == []


def test_the_checker_sees_lazy_and_relative_imports(tmp_path: Path) -> None:
    pkg = tmp_path / 'pkg'
    (pkg / 'sub').mkdir(parents=True)
    (pkg / '__init__.py').write_text('')
    (pkg / 'sub' / '__init__.py').write_text('from . import leaf\n')
    (pkg / 'sub' / 'leaf.py').write_text('def f():\n    from ..top import x\n')
    (pkg / 'top.py').write_text('from typing import TYPE_CHECKING\n'
                                'if TYPE_CHECKING:\n    from .sub.leaf import f\n')
    graph = import_graph(pkg)
    assert graph['pkg.sub'] == {'pkg.sub.leaf'}
    assert graph['pkg.sub.leaf'] == {'pkg.top'}
    assert graph['pkg.top'] == {'pkg.sub.leaf'}     # a type-only import counts
    assert cycles(graph) == [['pkg.sub.leaf', 'pkg.top']]


def test_the_package_has_no_import_cycles() -> None:
    graph = import_graph(PACKAGE)
    assert 'feed_axis_energy.machine.file' in graph
    found = cycles(graph)
    assert not found, 'import cycles: ' + '; '.join(' <-> '.join(c) for c in found)
