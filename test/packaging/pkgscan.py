"""Facts about the package read from its source files with ast (no ROS 2 install needed).

Shared by the tests of the launch file, the node parameters and README's ROS 2 section.
"""
from __future__ import annotations

import ast
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
LAUNCH_FILE = ROOT / 'launch' / 'feed_axis_energy.launch.py'
NODES_DIR = ROOT / 'feed_axis_energy' / 'nodes'
GRAPH_YAML = ROOT / 'config' / 'graph.yaml'


def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding='utf-8'), filename=str(path))


def _callee(node: ast.Call) -> str:
    func = node.func
    if isinstance(func, ast.Name):
        return func.id
    if isinstance(func, ast.Attribute):
        return func.attr
    return ''


def console_scripts() -> dict[str, str]:
    """``{executable: 'module:function'}`` from ``entry_points`` in setup.py."""
    for node in ast.walk(_tree(ROOT / 'setup.py')):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if isinstance(key, ast.Constant) and key.value == 'console_scripts':
                    entries = ast.literal_eval(value)
                    return {name.strip(): target.strip() for name, target in
                            (entry.split('=', 1) for entry in entries)}
    raise AssertionError('setup.py has no console_scripts')


def launch_arguments(path: Path = LAUNCH_FILE) -> dict[str, str]:
    """``{name: default}`` of the launch file's ``ARGUMENTS`` table."""
    for node in _tree(path).body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == 'ARGUMENTS' for t in node.targets):
            return {name: default for name, default, _ in ast.literal_eval(node.value)}
    raise AssertionError(f'{path.name} has no ARGUMENTS table')


def launch_actions(path: Path = LAUNCH_FILE) -> list[tuple[str, str, set[str]]]:
    """``(action class, executable, parameter keys given in dict literals)`` per node action."""
    found = []
    for node in ast.walk(_tree(path)):
        if not isinstance(node, ast.Call) or _callee(node) not in ('Node', 'LifecycleNode'):
            continue
        kw = {k.arg: k.value for k in node.keywords if k.arg}
        executable = kw.get('executable')
        if not isinstance(executable, ast.Constant):
            continue
        keys: set[str] = set()
        for sub in ast.walk(kw.get('parameters', ast.List(elts=[]))):
            if isinstance(sub, ast.Dict):
                keys |= {k.value for k in sub.keys if isinstance(k, ast.Constant)}
        found.append((_callee(node), executable.value, keys))
    return found


def declared_parameters() -> dict[str, list[str]]:
    """``{node executable: [parameter names]}`` from ``declare(self, NAME, ...)`` calls."""
    found: dict[str, list[str]] = {}
    for path in sorted(NODES_DIR.glob('*.py')):
        names = []
        for node in ast.walk(_tree(path)):
            if (isinstance(node, ast.Call) and _callee(node) in ('declare', 'declare_parameter')
                    and node.args):
                first = node.args[1] if _callee(node) == 'declare' else node.args[0]
                if isinstance(first, ast.Constant) and isinstance(first.value, str):
                    names.append(first.value)
        if names:
            found[path.stem] = names
    return found


def graph_parameters() -> dict[str, dict]:
    """``{node: ros__parameters}`` of config/graph.yaml."""
    data = yaml.safe_load(GRAPH_YAML.read_text(encoding='utf-8'))
    return {node: body.get('ros__parameters', {}) for node, body in data.items()}
