"""Shipped configs answered from exact snapshots of PyYAML's data, without importing PyYAML."""
import datetime
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.core.safeyaml import (load_yaml_file, load_yaml_text, MAX_DEPTH,
                                            MAX_EXPANDED_NODES, read_text_file)
from feed_axis_energy.core.yamlparse import parse_yaml
from feed_axis_energy.core.yamlsnap import (known_document, NOT_KNOWN, same_data,
                                            snapshot_literal)

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = sorted((ROOT / 'config').glob('*.yaml'))


def _pyyaml(text: str):
    return parse_yaml(text, max_depth=MAX_DEPTH, max_nodes=MAX_EXPANDED_NODES)


def test_snapshot_module_is_current() -> None:
    sys.path.insert(0, str(ROOT / 'scripts'))
    try:
        import yaml_snapshots
    finally:
        sys.path.pop(0)
    have = (ROOT / 'feed_axis_energy' / 'core' / 'yaml_snapshots.py').read_text()
    assert yaml_snapshots.current_source() == have, (
        'a shipped config changed: run `python scripts/yaml_snapshots.py`')


@pytest.mark.parametrize('path', CONFIGS, ids=lambda p: p.name)
def test_every_shipped_config_is_known_and_equals_pyyaml(path: Path) -> None:
    text = read_text_file(path)
    known = known_document(text)
    assert known is not NOT_KNOWN
    assert same_data(known, _pyyaml(text))
    assert same_data(load_yaml_file(path), _pyyaml(text))


def test_known_document_is_a_fresh_copy() -> None:
    text = read_text_file(CONFIGS[0])
    first = known_document(text)
    first['name'] = 'changed'
    assert known_document(text)['name'] != 'changed'


def test_any_other_text_goes_to_pyyaml_with_its_limits() -> None:
    text = read_text_file(CONFIGS[0])
    edited = text.replace('name:', 'name: ', 1)          # one character more
    assert known_document(edited) is NOT_KNOWN
    assert same_data(load_yaml_text(edited, file='m.yaml'), _pyyaml(text))
    deep = '[' * (MAX_DEPTH + 5) + ']' * (MAX_DEPTH + 5)
    with pytest.raises(ValueError, match='m.yaml: line 1, column 51: nested deeper'):
        load_yaml_text(deep, file='m.yaml')


@pytest.mark.parametrize('data', [
    {'a': datetime.date(2024, 1, 1)}, {(1, 2): 'tuple key'}, {'x': float('nan')},
    {'x': float('inf')}, {'t': (1, 2)}, {'s': {1, 2}}, b'bytes'])
def test_data_a_literal_cannot_carry_exactly_is_not_snapshotted(data) -> None:
    assert snapshot_literal(data) is None


def test_shared_values_from_aliases_are_not_snapshotted() -> None:
    data = _pyyaml('a: &x [1, 2]\nb: *x\n')
    assert data['a'] is data['b']
    assert snapshot_literal(data) is None


def test_types_and_order_survive_the_snapshot() -> None:
    data = _pyyaml('b: 1\na: 1.0\nc: true\nd: null\ne: [-0.0, 1.0e+300, "1"]\n3: x\n')
    text = snapshot_literal(data)
    assert text is not None
    assert not same_data({'a': 1, 'b': 1.0}, {'a': 1.0, 'b': 1})
    assert not same_data({'a': 1, 'b': 2}, {'b': 2, 'a': 1})
    assert not same_data([0.0], [-0.0]) and not same_data([1], [True])
    import ast
    assert same_data(ast.literal_eval(text), data)
    assert [type(v) for v in data.values()][:4] == [int, float, bool, type(None)]


def test_default_machine_loads_without_importing_pyyaml() -> None:
    code = ('import sys\n'
            'from feed_axis_energy.core.machine import load_machine\n'
            'from feed_axis_energy.paths import default_machine\n'
            'm = load_machine(default_machine())\n'
            'print(m.name, "yaml" in sys.modules)\n')
    out = subprocess.run([sys.executable, '-c', code], cwd=ROOT, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out == ['demonstrator', 'False']
