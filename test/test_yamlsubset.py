"""The YAML subset read without PyYAML: the same data as PyYAML's safe loader, or nothing.

Differential tests: every text the subset reader accepts must load to exactly what
``yaml.safe_load`` builds (values, types, key order); everything else must be left to PyYAML
(``None``), never raise.
"""
from pathlib import Path

from hypothesis import given, HealthCheck, settings, strategies as st
import pytest
import yaml

from feed_axis_energy.safeyaml import load_yaml_text, MAX_DEPTH
from feed_axis_energy.yamlsubset import parse_subset

ROOT = Path(__file__).resolve().parents[1]
PROPERTY = settings(max_examples=400, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def same(a, b) -> bool:
    """Equal with equal types all the way down (1 != 1.0 != True here), keys in order."""
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return (len(a) == len(b)
                and all(same(ka, kb) and same(a[ka], b[kb]) for ka, kb in zip(a, b)))
    if isinstance(a, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


def pyyaml(text: str):
    try:
        return ('ok', yaml.safe_load(text))
    except (yaml.YAMLError, ValueError, OverflowError, TypeError) as err:
        return ('error', type(err).__name__)


def check(text: str):
    """The property: ``None``, or PyYAML's data."""
    got = parse_subset(text, max_depth=MAX_DEPTH - 1)
    if got is not None:
        status, want = pyyaml(text)
        assert status == 'ok', (text, want)
        assert same(got, want), (text, got, want)
    return got


def yaml_files() -> list[Path]:
    return sorted(p for p in ROOT.rglob('*.yaml')
                  if '.venv' not in p.parts and 'node_modules' not in p.parts)


@pytest.mark.parametrize('path', yaml_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_repository_yaml_files_load_as_pyyaml_loads_them(path: Path) -> None:
    check(path.read_text(encoding='utf-8'))


@pytest.mark.parametrize('name', ['demonstrator.yaml', 'three_axis_mill.yaml',
                                  'umich_mill.yaml'])
def test_shipped_machine_configs_are_inside_the_subset(name: str) -> None:
    # the reason for the subset: simulate's start-up reads these without importing PyYAML
    assert check((ROOT / 'config' / name).read_text(encoding='utf-8')) is not None


@pytest.mark.parametrize('text', [
    'a: 1\nb: -2.5e-3\nc: 1.\nd: +3\ne: -0\nf: 0.0\n',
    'a: true\nb: off\nc: YES\nd: null\ne: ~\nf:\ng: None\nh: nan\n',
    'a: y\nb: n\nc: Y\nd: N\ne: NaN\nf: Inf\ng: nULL\nh: tRUE\n',
    'n: W/(mm/s)\nm: coulomb_viscous\nk: mm/s\nx_1: a.b-c+d\n',
    'a: {X: 0.0, Y: 1, 2: [1, 2.0, t]}\nb: []\nc: {}\nd: [ ]\ne: [[1], {a: []}]\n',
    'top:\n  mid:\n    low: 1\n  other: [1]\nnext: 2\n',
    'a:\n  - 1\n  - x\n  - {a: 1}\n  - [2]\nb: 3\n',
    '# comment only line\na: 1   # trailing comment\n\n   \nb: x\n  # indented comment\n',
    '1: one\n-2: minus_two\n1.5: half\n',
    'a: 1 # caf\u00e9 \u2265 \U0001F600\n',
])
def test_subset_texts_load_as_pyyaml(text: str) -> None:
    assert check(text) is not None


@pytest.mark.parametrize('text', [
    '', '# only a comment\n', 'a', '- 1\n- 2\n', '[1, 2]\n', '  a: 1\n',
    'a: 1e3\n', 'a: 012\n', 'a: 1_000\n', 'a: 0x1F\n', 'a: 1:30\n', 'a: .5\n', 'a: -.5\n',
    'a: .inf\n', 'a: 2024-01-02\n', "a: 'x'\n", 'a: "x"\n', 'a: &x 1\nb: *x\n',
    'a: !!str 1\n', 'a: |\n  text\n', 'a: >\n  text\n', 'a: b c\n', 'a: b: c\n',
    'a:b\n', 'a: 1\na: 2\n', 'true: 1\n', 'null: 1\n', '? a\n: 1\n', 'a: [1, 2,]\n',
    'a: [1, 2\n  , 3]\n', 'a: {b: 1\n', 'a: {b:1}\n', 'a: [a: 1]\n', 'a: 1\n  b: 2\n',
    'a:\n    b: 1\n  c: 2\n', 'a:\n- 1\n', 'a:\n  - b: 1\n', 'a:\n  -\n', '---\na: 1\n',
    'a: 1\n...\n', '%YAML 1.1\n---\na: 1\n', 'a:\t1\n', 'a: 1\r\nb: 2\r\n', '\ufeffa: 1\n',
    'a: 1 # x\x85b: 2\n', 'a: 1\x7f\n', 'a: caf\u00e9\n', 'a: 1\x00\n', 'a: -\n',
    'a: - 1\n', 'a: [-]\n', 'a: [-a]\n', 'a: ,\n', 'a: 1 2\n', 'a: [1 2]\n', '<<: 1\n',
    'a: =\n', 'b: x#y\n', 'a: ' + '9' * 5000 + '\n', 'a: 1.0e+9999\n',
])
def test_texts_outside_the_subset_are_left_to_pyyaml(text: str) -> None:
    check(text)


def test_nesting_deeper_than_the_limit_is_left_to_pyyaml() -> None:
    deep = ''.join('  ' * i + f'k{i}:\n' for i in range(MAX_DEPTH + 5)) + '  ' * 60 + 'v: 1\n'
    assert parse_subset(deep, max_depth=MAX_DEPTH - 1) is None
    flow = 'a: ' + '[' * (MAX_DEPTH + 5) + ']' * (MAX_DEPTH + 5) + '\n'
    assert parse_subset(flow, max_depth=MAX_DEPTH - 1) is None
    with pytest.raises(ValueError, match='nested deeper'):
        load_yaml_text(flow, file='deep.yaml')


_WORDS = st.sampled_from([
    '1', '-1', '+1', '0', '-0', '00', '01', '1.0', '-1.5', '1.', '.5', '1e3', '1.0e-3',
    '1.0e3', '1_0', '0x1', '0b1', '0o7', '1:2', 'yes', 'No', 'y', 'n', 'on', 'OFF', 'true',
    'null', 'Null', '~', 'None', 'nan', '.nan', '.inf', '-.inf', 'a', 'X', 'mm/s', 'a b',
    'a:b', 'a#b', 'a #b', 'W/(mm/s)', '2024-01-02', "'q'", '"q"', '&a', '*a', '!t', '-',
    '- a', '[', ']', '{', '}', ',', '[1, 2]', '{a: 1}', '[]', '{}', '[a: 1]', '{a:1}', '',
    'caf\u00e9', '<<', '=', '?', '|', '>', '%', '@', '`', '\t', '\x85', '#'])
_PLAIN = st.sampled_from([
    '0', '7', '-3', '+12', '1.0', '-0.5', '2.', '1.5e-3', '+4.0E+2', 'x', 'y', 'n', 'Y', 'N',
    'ab_c', 'mm/s', 'W/(mm/s)', 'a.b-c', 'true', 'False', 'on', 'Off', 'yes', 'NO', 'null',
    '~', 'None', 'NaN', 'inf', '[]', '{}', '[1, x]', '{a: 1, b: [y, 2.5]}'])
_KEYS = st.sampled_from(['a', 'b', 'X', 'y_2', '1', '-4', '2.5', 'mm/s'])


@st.composite
def documents(draw, depth: int = 0) -> str:
    """Block mappings (nested by two spaces, or sequences of items) whose keys and values
    are mostly in the subset, with now and then one of the tricky words near it."""
    indent = '  ' * depth
    lines = []
    for key in draw(st.lists(_KEYS, min_size=1, max_size=5, unique=True)):
        kind = draw(st.integers(0, 9))
        if kind < 6:
            lines.append(f'{indent}{key}: {draw(_PLAIN)}')
        elif kind == 6 and depth < 3:
            lines.append(f'{indent}{key}:')
            lines.append(draw(documents(depth + 1)).rstrip('\n'))
        elif kind == 7:
            lines.append(f'{indent}{key}:')
            items = draw(st.lists(_PLAIN, min_size=1, max_size=3))
            lines += [f'{indent}  - {v}' for v in items]
        elif kind == 8:
            lines.append(f'{indent}{key}: {draw(_WORDS)}')
        else:
            lines.append(f'{indent}{key}: [{", ".join(draw(st.lists(_WORDS, max_size=3)))}]')
    return '\n'.join(lines) + '\n'


@st.composite
def near_documents(draw) -> str:
    """Line-shaped texts near the subset: keys, items and flow values from tricky words."""
    lines = []
    for _ in range(draw(st.integers(1, 8))):
        indent = draw(st.sampled_from(['', ' ', '  ', '    ', '      ']))
        shape = draw(st.integers(0, 4))
        key = draw(_WORDS)
        value = draw(_WORDS)
        if shape == 0:
            lines.append(f'{indent}{key}: {value}')
        elif shape == 1:
            lines.append(f'{indent}{key}:')
        elif shape == 2:
            lines.append(f'{indent}- {value}')
        elif shape == 3:
            items = draw(st.lists(_WORDS, max_size=4))
            lines.append(f'{indent}{key}: [{", ".join(items)}]')
        else:
            pairs = draw(st.lists(st.tuples(_WORDS, _WORDS), max_size=3))
            body = ', '.join(f'{k}: {v}' for k, v in pairs)
            lines.append(f'{indent}{key}: {{{body}}}  # {value}')
    return '\n'.join(lines) + draw(st.sampled_from(['', '\n']))


@PROPERTY
@given(documents())
def test_generated_documents_load_as_pyyaml_or_fall_back(text: str) -> None:
    check(text)


@PROPERTY
@given(near_documents())
def test_texts_near_the_subset_load_as_pyyaml_or_fall_back(text: str) -> None:
    check(text)


def test_generated_documents_reach_the_subset() -> None:
    # the properties above would hold vacuously if nothing generated were inside the subset
    @settings(max_examples=200, derandomize=True, database=None, deadline=None)
    @given(documents())
    def count(text: str) -> None:
        inside.append(parse_subset(text, max_depth=MAX_DEPTH - 1) is not None)

    inside: list[bool] = []
    count()
    assert sum(inside) >= len(inside) // 4


_CONFIG = (ROOT / 'config' / 'three_axis_mill.yaml').read_text(encoding='utf-8')


@PROPERTY
@given(st.lists(st.tuples(st.integers(0, len(_CONFIG)), st.integers(0, 3),
                          st.sampled_from(list(' :-#[]{},.\n\t\'"&*!|>0123456789eE_xyz')
                                          + ['  ', '\n  ', 'true', 'null', '\u00e9'])),
                min_size=1, max_size=4))
def test_mutated_config_loads_as_pyyaml_or_falls_back(edits) -> None:
    text = _CONFIG
    for at, cut, insert in edits:
        at = min(at, len(text))
        text = text[:at] + insert + text[at + cut:]
    check(text)
