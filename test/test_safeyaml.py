"""The bounded YAML loader: size, UTF-8, nesting, alias expansion, and bounded messages."""
import os
from pathlib import Path

from hypothesis import given, HealthCheck, settings, strategies as st
import pytest

from feed_axis_energy.errors import ConfigError, DataError, describe, shorten
from feed_axis_energy.safeyaml import load_yaml_file, load_yaml_text, MAX_DEPTH, MAX_EXPANDED_NODES

PROPERTY = settings(max_examples=300, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def laughs(levels: int, *, width: int = 9) -> str:
    """Nested aliases ``a``, ``b``, ...: each level holds ``width`` aliases of the one before,
    so the last one expands to ``width ** (levels + 1)`` values."""
    names = 'abcdefghijklmnop'
    lines = ['a: &a [' + ','.join(['x'] * width) + ']']
    for k in range(1, levels + 1):
        lines.append(f'{names[k]}: &{names[k]} [' + ','.join([f'*{names[k - 1]}'] * width) + ']')
    return '\n'.join(lines) + '\n'


def test_plain_document_and_small_aliases_load() -> None:
    text = 'a: &x {y: 1, z: [1, 2.5, text]}\nb: *x\nc: {<<: *x, w: null}\n'
    data = load_yaml_text(text, file='f.yaml')
    assert data['a'] == data['b'] == {'y': 1, 'z': [1, 2.5, 'text']}
    assert data['c'] == {'y': 1, 'z': [1, 2.5, 'text'], 'w': None}
    assert load_yaml_text('', file='f.yaml') is None


def test_billion_laughs_is_refused_before_expansion() -> None:
    text = laughs(8)  # 9**9 = 387 million values from about 300 bytes
    assert len(text.encode()) < 320
    with pytest.raises(ConfigError, match=f'more than {MAX_EXPANDED_NODES} values') as info:
        load_yaml_text(text, file='bomb.yaml')
    assert len(str(info.value)) < 300
    # the same with merge keys, which copy mappings into each other
    merge = ['m0: &m0 {a: 1, b: 2, c: 3, d: 4, e: 5, f: 6, g: 7, h: 8, i: 9, j: 10}']
    for k in range(1, 9):
        merge.append(f'm{k}: &m{k} {{<<: [' + ', '.join([f'*m{k - 1}'] * 10) + ']}')
    with pytest.raises(ConfigError, match='aliases'):
        load_yaml_text('\n'.join(merge), file='merge.yaml')


def test_expansion_within_the_budget_loads() -> None:
    data = load_yaml_text(laughs(3), file='f.yaml')   # 9**4 = 6561 values
    assert len(data['d']) == 9 and data['d'][0][0][0] == ['x'] * 9


def test_recursive_alias_is_refused() -> None:
    with pytest.raises(ConfigError, match='recursive alias'):
        load_yaml_text('a: &a [1, *a]\n', file='f.yaml')


@pytest.mark.parametrize('text', [
    '[' * 100_000 + ']' * 100_000,
    ''.join('  ' * i + f'k{i}:\n' for i in range(200)) + '  ' * 200 + 'v\n',
    '{a: ' * 5000 + '1' + '}' * 5000,
])
def test_deep_nesting_is_refused_without_recursion_error(text: str) -> None:
    with pytest.raises(ConfigError, match=f'nested deeper than {MAX_DEPTH} levels'):
        load_yaml_text(text, file='deep.yaml')


def test_nesting_at_the_limit_loads() -> None:
    text = '[' * MAX_DEPTH + ']' * MAX_DEPTH
    data = load_yaml_text(text, file='f.yaml')
    depth = 0
    while isinstance(data, list) and data:
        data, depth = data[0], depth + 1
    assert depth == MAX_DEPTH - 1


def test_non_utf8_names_line_and_column(tmp_path: Path) -> None:
    f = tmp_path / 'm.yaml'
    f.write_bytes(b'name: x\nruns:\n  - caf\xe9\n')
    with pytest.raises(ConfigError, match=r'line 3, column 8: byte 0xe9 is not valid UTF-8'):
        load_yaml_file(f, what='manifest')
    f.write_bytes(b'\xef\xbb\xbfa: 1\n')   # a byte-order mark is fine
    assert load_yaml_file(f) == {'a': 1}


def test_size_cap_and_non_regular_files(tmp_path: Path) -> None:
    f = tmp_path / 'big.yaml'
    f.write_text('a: ' + 'x' * 2000 + '\n')
    with pytest.raises(DataError, match='larger than 1000 bytes'):
        load_yaml_file(f, error=DataError, max_bytes=1000)
    with pytest.raises(ConfigError, match='not a regular file'):
        load_yaml_file(tmp_path)
    fifo = tmp_path / 'fifo.yaml'
    os.mkfifo(fifo)
    with pytest.raises(ConfigError, match='not a regular file'):   # and does not block
        load_yaml_file(fifo)
    loop = tmp_path / 'loop.yaml'
    loop.symlink_to(loop)
    with pytest.raises(ConfigError, match='cannot read'):
        load_yaml_file(loop)


@pytest.mark.parametrize('text, words', [
    ('x: 2024-13-45\n', 'cannot be read'),            # a date PyYAML builds with datetime()
    ('x: ' + '9' * 5000 + '\n', 'cannot be read'),    # beyond int() digit limit
    ('x: *' + 'q' * 500 + '\n', 'undefined alias'),
    ('a: 1\n---\nb: 2\n', 'single document'),
    ('x: "\x00"\n', r'U\+0000'),
    ('? [a, b]\n: 1\n', 'unhashable'),
])
def test_other_yaml_failures_are_bounded_config_errors(text: str, words: str) -> None:
    with pytest.raises(ConfigError, match=words) as info:
        load_yaml_text(text, file='f.yaml')
    assert len(str(info.value)) < 250


def test_describe_is_bounded() -> None:
    big = list(range(10**6))
    assert describe(big) == 'a list of 1000000 items'
    assert describe({'a': big}) == 'a mapping of 1 key'
    assert describe(None) == 'nothing' and describe(True) == 'true'
    assert describe('x' * 10_000) == "text '" + 'x' * 60 + "...'"
    assert describe(10 ** 5000).startswith('an integer of ')
    assert describe(1.5) == 'number 1.5'
    assert shorten('abc', limit=2) == 'ab...'


@PROPERTY
@given(st.text(alphabet=st.sampled_from(list('ab:-[]{},&*!|>? \n\t"\'#%@`') + ['\x00', 'é']),
               max_size=80))
def test_any_text_loads_or_raises_config_error(text: str) -> None:
    try:
        load_yaml_text(text, file='fuzz.yaml')
    except ConfigError as err:
        assert str(err).startswith('fuzz.yaml: ')
        assert len(str(err)) < 300
