"""The house rules of ``docs/ARCHITECTURE.md``, checked on the code itself.

* the layers and their directions (``.importlinter``, run with import-linter; a planted
  violation must make it fail);
* no ``_private`` name is imported from another module;
* what one package takes from another is public: listed in that package's ``__all__`` (its
  ``__init__``), never reached through one of its modules;
* no folder holds more than 15 modules;
* every module path that README and docs name exists.
"""
from __future__ import annotations

import ast
from pathlib import Path
import re
import shutil
import subprocess
import sys

from package_imports import from_target, module_files
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / 'feed_axis_energy'
MAX_MODULES_PER_FOLDER = 15


def _imports(root: Path):
    """(importer, its file, line, target module, imported name) of every ``from`` import."""
    for module, path in sorted(module_files(root).items()):
        tree = ast.parse(path.read_text(encoding='utf-8'))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = from_target(module, path, node)
                for alias in node.names:
                    yield module, path, node.lineno, target, alias.name


def private_imports(root: Path) -> list[str]:
    """``file:line: name`` of every private name imported from a module of ``root``."""
    top = root.name
    return [f'{path.relative_to(root.parent)}:{line}: {target}.{name}'
            for _, path, line, target, name in _imports(root)
            if (target == top or target.startswith(top + '.'))
            and name.startswith('_') and not name.startswith('__')]


def _package_of(module: str) -> str | None:
    """The top-level package a module belongs to (``None`` for the ground modules)."""
    parts = module.split('.')
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and _is_package(parts[1])) else None


def _is_package(name: str) -> bool:
    return (PACKAGE / name / '__init__.py').is_file()


def _public_names(package: str) -> set[str]:
    tree = ast.parse((PACKAGE / package / '__init__.py').read_text(encoding='utf-8'))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, 'id', '') == '__all__'
                                                for t in node.targets):
            return {elt.value for elt in node.value.elts}
    return set()


def border_crossings(root: Path) -> list[str]:
    """Imports from another package that bypass its ``__init__`` or take an unlisted name."""
    modules = module_files(root)
    bad = []
    for importer, path, line, target, name in _imports(root):
        if not target.startswith(root.name + '.'):
            continue
        theirs, mine = _package_of(target), _package_of(importer)
        if theirs is None or theirs == mine:
            continue
        where = f'{path.relative_to(root.parent)}:{line}'
        face = f'{root.name}.{theirs}'
        if target != face:
            bad.append(f'{where}: {target}.{name} (import it from {face})')
        elif f'{face}.{name}' not in modules and name not in _public_names(theirs):
            bad.append(f'{where}: {face}.{name} is not listed in {face}.__all__')
    return bad


def test_the_private_import_check_finds_one(tmp_path: Path) -> None:
    pkg = tmp_path / 'pkg'
    pkg.mkdir()
    (pkg / '__init__.py').write_text('')
    (pkg / 'a.py').write_text('_hidden = 1\n__version__ = 2\n')
    (pkg / 'b.py').write_text('from .a import _hidden, __version__\n')
    assert private_imports(pkg) == ['pkg/b.py:1: pkg.a._hidden']


def test_no_private_name_crosses_a_module_border() -> None:
    assert private_imports(PACKAGE) == []


def test_packages_meet_only_through_their_public_faces() -> None:
    assert border_crossings(PACKAGE) == []


def test_every_package_lists_its_public_names() -> None:
    for init in sorted(PACKAGE.glob('*/__init__.py')):
        tree = ast.parse(init.read_text(encoding='utf-8'))
        assert ast.get_docstring(tree), f'{init.relative_to(ROOT)} says what it owns'
        names = _public_names(init.parent.name)
        if init.parent.name in ('cli', 'nodes'):
            continue                     # shells: entry points, not libraries
        assert names, f'{init.relative_to(ROOT)} lists its public names in __all__'


def test_no_folder_holds_more_than_fifteen_modules() -> None:
    for folder in sorted({p.parent for p in PACKAGE.rglob('*.py')}):
        count = len([p for p in folder.glob('*.py') if p.name != '__init__.py'])
        assert count <= MAX_MODULES_PER_FOLDER, f'{folder.relative_to(ROOT)}: {count} modules'


def _lint_imports(cwd: Path, env_path: Path) -> subprocess.CompletedProcess:
    exe = shutil.which('lint-imports', path=str(Path(sys.executable).parent))
    assert exe, 'import-linter is a test dependency (requirements-dev.txt)'
    return subprocess.run([exe, '--no-cache'], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env={'PYTHONPATH': str(env_path), 'PATH': '/usr/bin:/bin'})


def test_the_layer_contract_holds() -> None:
    out = _lint_imports(ROOT, ROOT)
    assert out.returncode == 0, out.stdout + out.stderr


@pytest.mark.parametrize('module, line', [
    ('machine/spec.py', 'from ..sim import simulate_program\n'),       # a lower layer climbs
    ('gcode/program.py', 'from ..physics import energy\n'),
])
def test_the_layer_contract_fails_on_a_planted_violation(tmp_path: Path, module: str,
                                                         line: str) -> None:
    shutil.copytree(PACKAGE, tmp_path / PACKAGE.name,
                    ignore=shutil.ignore_patterns('__pycache__'))
    shutil.copy(ROOT / '.importlinter', tmp_path / '.importlinter')
    planted = tmp_path / PACKAGE.name / module
    text = planted.read_text(encoding='utf-8')
    # after the module docstring and ``from __future__`` (an import-only change)
    anchor = 'from __future__ import annotations\n'
    assert anchor in text
    planted.write_text(text.replace(anchor, anchor + 'if False:\n    ' + line, 1),
                       encoding='utf-8')
    out = _lint_imports(tmp_path, tmp_path)
    assert out.returncode != 0
    assert 'BROKEN' in out.stdout


# Module paths as README and docs write them: ``feed_axis_energy/x/y.py``, a folder
# ``feed_axis_energy/x/``, or a dotted ``feed_axis_energy.x.y``.
# Not a module path: an install location (``share/feed_axis_energy/``), a bag metadata key
# (``feed_axis_energy/measured_run``) or the launch file ``feed_axis_energy.launch.py``.
_PATH = re.compile(r'(?<![\w/])feed_axis_energy/(?:[\w]+/)*(?:[\w]+\.py|[\w]+/)')
_DOTTED = re.compile(r'(?<![\w/])feed_axis_energy(?:\.[A-Za-z_]\w*)+')


# A short path in backticks (`plan/stream.py`) names a file of the package or the repository.
_SHORT = re.compile(r'`((?:\w+/)+\w+\.py)`')


def _short_paths(text: str) -> set[str]:
    return {p for p in _SHORT.findall(text) if not p.startswith('shared/')}


def _named_paths(text: str) -> set[str]:
    return set(_PATH.findall(text)) | {d for d in _DOTTED.findall(text) if not d.endswith('.py')}


def _exists(ref: str) -> bool:
    if '/' in ref:
        return (ROOT / ref.rstrip('/')).exists()
    parts = ref.split('.')
    for k in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:k])
        if base.with_suffix('.py').is_file() or (base / '__init__.py').is_file():
            rest = parts[k:]
            if not rest:
                return True
            path = base.with_suffix('.py') if base.with_suffix('.py').is_file() \
                else base / '__init__.py'
            tree = ast.parse(path.read_text(encoding='utf-8'))
            names = {getattr(n, 'name', None) for n in tree.body} | {
                t.id for n in tree.body if isinstance(n, ast.Assign)
                for t in n.targets if isinstance(t, ast.Name)} | {
                (a.asname or a.name) for n in tree.body
                if isinstance(n, ast.ImportFrom) for a in n.names}
            return rest[0] in names
    return False


def test_the_doc_path_check_finds_a_missing_module() -> None:
    assert _exists('feed_axis_energy/plan/stream.py')
    assert _exists('feed_axis_energy.plan.stream.iter_motion')
    assert not _exists('feed_axis_energy/core/trajectory.py')
    assert _named_paths('see `feed_axis_energy/plan/`, share/feed_axis_energy/x/ and '
                        'feed_axis_energy.launch.py') == {'feed_axis_energy/plan/'}
    assert not _exists('feed_axis_energy.plan.stream.no_such_name')
    assert _short_paths('in `plan/stream.py` and `shared/tools/x.py`') == {'plan/stream.py'}


@pytest.mark.parametrize('doc', ['README.md', 'bench/README.md', 'bags/README.md',
                                 *sorted(p.relative_to(ROOT).as_posix()
                                         for p in (ROOT / 'docs').glob('*.md'))])
def test_every_module_path_named_in_the_docs_exists(doc: str) -> None:
    text = (ROOT / doc).read_text(encoding='utf-8')
    missing = sorted(r for r in _named_paths(text) if not _exists(r))
    missing += sorted(p for p in _short_paths(text)
                      if not (ROOT / p).is_file() and not (PACKAGE / p).is_file())
    assert missing == []
