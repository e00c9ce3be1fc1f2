"""Property-based tests of the input boundary: mutated CSV text, manifests, machine YAML and
bag bytes never make a command crash.

Each example runs a real command in-process and checks only the outcome (exit 0 with finite
output, or exit 1 with clear ``error:`` lines, never a traceback). Examples are derived from
a fixed seed (``derandomize=True``, no example database), so CI sees the same cases every
run; the example counts keep the whole module well under a minute.
"""
import json
from pathlib import Path
import shutil
import tempfile

from hostile_inputs import (bag_campaign, check_outcome, csv_campaign, csv_text, MACHINE,
                            manifest_text, mcap_file, run_cli, SHORT_PROGRAM)
from hypothesis import given, HealthCheck, settings, strategies as st
import yaml

FUZZ = settings(derandomize=True, database=None, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

# characters that matter to CSV, YAML and number syntax, plus some that must be refused
_ALPHABET = list('0123456789.eE+-, \n\t:[]{}&*#"\'') + [
    '\x00', '\xe9', 'nan', 'inf', '1e308', '1e300', '-', 'mm', 'kW', 'null']


def edits(max_edits: int = 6) -> st.SearchStrategy:
    """A few edits: ``(operation, where as a fraction of the text, piece)``."""
    return st.lists(st.tuples(st.sampled_from(['replace', 'insert', 'delete', 'cut']),
                              st.floats(0.0, 1.0), st.sampled_from(_ALPHABET)),
                    min_size=1, max_size=max_edits)


def apply_edits(text: str, changes: list) -> str:
    """``text`` with characters replaced, inserted or deleted, or cut short."""
    for op, where, piece in changes:
        i = min(int(where * len(text)), max(len(text) - 1, 0))
        if op == 'replace':
            text = text[:i] + piece + text[i + 1:]
        elif op == 'insert':
            text = text[:i] + piece + text[i:]
        elif op == 'delete':
            text = text[:i] + text[i + 1:]
        else:
            text = text[:i]
    return text


def mutated(text: str, *, max_edits: int = 6) -> st.SearchStrategy:
    """``text`` with a few edits (:func:`apply_edits`)."""
    return edits(max_edits).map(lambda changes: apply_edits(text, changes))


def _workdir() -> Path:
    # hypothesis runs many examples per test function: a fresh directory for each one
    return Path(tempfile.mkdtemp(prefix='fae-fuzz-'))


@settings(FUZZ, max_examples=60)
@given(mutated(csv_text(n=30)))
def test_mutated_csv(text: str) -> None:
    root = _workdir()
    try:
        manifest = csv_campaign(root, runs=1, n=30)
        (root / 'r0.csv').write_text(text, encoding='utf-8', errors='surrogateescape')
        check_outcome(*run_cli(['compare', '--quiet', '--json', str(manifest)]),
                      json_output=True)
        check_outcome(*run_cli(['import', '--quiet', '--json', '--out', str(root / 'o'),
                                str(manifest)]), json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


@settings(FUZZ, max_examples=60)
@given(mutated(manifest_text(['r0']), max_edits=4))
def test_mutated_manifest(text: str) -> None:
    root = _workdir()
    try:
        manifest = csv_campaign(root, runs=1, n=30)
        manifest.write_text(text)
        check_outcome(*run_cli(['compare', '--quiet', '--json', str(manifest)]),
                      json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


@settings(FUZZ, max_examples=60)
@given(mutated(MACHINE.read_text(), max_edits=4))
def test_mutated_machine_yaml(text: str) -> None:
    root = _workdir()
    try:
        (root / 'machine.yaml').write_text(text)
        (root / 'p.nc').write_text(SHORT_PROGRAM)
        check_outcome(*run_cli(['simulate', str(root / 'p.nc'), '--machine',
                                str(root / 'machine.yaml'), '--json', '--rate-hz', '200']),
                      json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


_BAG_TEMPLATE: list[Path] = []


def _bag_template() -> Path:
    """One small valid measured-run bag campaign, built on first use."""
    if not _BAG_TEMPLATE:
        _BAG_TEMPLATE.append(bag_campaign(Path(tempfile.mkdtemp(prefix='fae-bag-')), n=30))
    return _BAG_TEMPLATE[0]


@settings(FUZZ, max_examples=80)
@given(st.one_of(
    st.tuples(st.just('cut'), st.floats(0.0, 1.0), st.just([])),
    st.tuples(st.just('flip'), st.just(0.0),
              st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(1, 255)),
                       min_size=1, max_size=8))))
def test_damaged_bag_bytes(damage: tuple) -> None:
    template = _bag_template()
    root = _workdir()
    try:
        shutil.copytree(template.parent, root / 'c')
        storage = mcap_file(root / 'c' / 'r0')
        data = bytearray(storage.read_bytes())
        kind, where, flips = damage
        if kind == 'cut':
            data = data[:int(where * len(data))]
        for position, mask in flips:
            i = min(int(position * len(data)), len(data) - 1)
            data[i] ^= mask
        storage.write_bytes(bytes(data))
        check_outcome(*run_cli(['compare', '--quiet', '--json',
                                str(root / 'c' / template.name)]), json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


# ----------------------------------------------------------------------------- wrong values

_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-2**70, 2**70)
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=12)
    | st.sampled_from([0, -1, 1e308, -1e-320, 'mm', 'kW', 'X', 'm/s^2', '.inf', '']),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner,
                                                                max_size=3),
    max_leaves=6)


def _paths(doc: object, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _paths(v, prefix + (i,))
    return out


@st.composite
def one_value_replaced(draw: st.DrawFn, text: str) -> str:
    """The YAML document ``text`` with the value at one random key replaced."""
    doc = yaml.safe_load(text)
    path = draw(st.sampled_from(_paths(doc)[1:]))
    value = draw(_VALUES)
    node = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return yaml.safe_dump(doc, allow_unicode=True)


@settings(FUZZ, max_examples=80)
@given(one_value_replaced(MACHINE.read_text()))
def test_machine_with_one_wrong_value(text: str) -> None:
    root = _workdir()
    try:
        (root / 'machine.yaml').write_text(text)
        (root / 'p.nc').write_text(SHORT_PROGRAM)
        check_outcome(*run_cli(['simulate', str(root / 'p.nc'), '--machine',
                                str(root / 'machine.yaml'), '--json', '--rate-hz', '200']),
                      json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


@settings(FUZZ, max_examples=60)
@given(one_value_replaced(manifest_text(['r0', 'r1']) + 'split: {calibrate: [r0]}\n'))
def test_manifest_with_one_wrong_value(text: str) -> None:
    root = _workdir()
    try:
        manifest = csv_campaign(root, runs=2, n=30)
        manifest.write_text(text)
        check_outcome(*run_cli(['compare', '--quiet', '--json', str(manifest)]),
                      json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _number_paths(doc: object) -> list[tuple]:
    return [p for p in _paths(doc)[1:] if _get(doc, p) is not True and _get(doc, p) is not False
            and isinstance(_get(doc, p), (int, float))]


def _get(doc: object, path: tuple) -> object:
    for key in path:
        doc = doc[key]
    return doc


@st.composite
def one_number_replaced(draw: st.DrawFn, text: str) -> str:
    """The YAML document ``text`` with one number replaced by a finite number of any size."""
    doc = yaml.safe_load(text)
    path = draw(st.sampled_from(_number_paths(doc)))
    exponent = draw(st.integers(-320, 308))
    mantissa = draw(st.sampled_from([1.0, 2.5, 9.9, -1.0]))
    value = mantissa * 10.0 ** exponent if exponent > -308 else 5e-324
    _get(doc, path[:-1])[path[-1]] = value
    return yaml.safe_dump(doc)


@settings(FUZZ, max_examples=80)
@given(one_number_replaced(MACHINE.read_text()))
def test_machine_with_one_number_of_any_size(text: str) -> None:
    # numbers that pass validation must not overflow the simulation to inf or NaN
    root = _workdir()
    try:
        (root / 'machine.yaml').write_text(text)
        (root / 'p.nc').write_text(SHORT_PROGRAM)
        check_outcome(*run_cli(['simulate', str(root / 'p.nc'), '--machine',
                                str(root / 'machine.yaml'), '--json', '--rate-hz', '200']),
                      json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


_TRAJECTORY = 'time [s],X [mm],X_vel [mm/s]\n' + ''.join(
    f'{i * 0.01:.2f},{20.0 * (1 - abs(1 - i / 20)):.3f},{(200.0 if i < 20 else -200.0):.1f}\n'
    for i in range(41))


@settings(FUZZ, max_examples=60)
@given(mutated(_TRAJECTORY))
def test_mutated_trajectory_csv(text: str) -> None:
    root = _workdir()
    try:
        (root / 't.csv').write_text(text)
        check_outcome(*run_cli(['simulate', str(root / 't.csv'), '--json']), json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


@st.composite
def numeric_runs(draw: st.DrawFn) -> list[str]:
    """Two CSV runs of well-formed numbers of any size the bound allows, any time step."""
    def number(low: int, high: int) -> float:
        return draw(st.sampled_from([1.0, -1.0, 3.7])) * 10.0 ** draw(st.integers(low, high))
    n = draw(st.sampled_from([2, 3, 7, 30]))
    runs = []
    for _ in range(2):
        step = 10.0 ** draw(st.integers(-9, 5))
        rows = ['t,P,X'] + [f'{i * step!r},{number(-12, 9)!r},{number(-12, 15)!r}'
                            for i in range(n)]
        runs.append('\n'.join(rows) + '\n')
    return runs


@settings(FUZZ, max_examples=25)
@given(numeric_runs())
def test_numeric_runs_of_any_size(runs: list[str]) -> None:
    root = _workdir()
    try:
        for k, text in enumerate(runs):
            (root / f'r{k}.csv').write_text(text)
        (root / 'm.yaml').write_text(manifest_text(['r0', 'r1']))
        for command in (['compare', '--quiet', '--json'], ['analyze', '--quiet', '--json'],
                        ['fit-loss', '--json']):
            check_outcome(*run_cli(command + [str(root / 'm.yaml')]), json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


_JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-2**70, 2**70) | st.floats(allow_nan=False)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(
        st.sampled_from(['t0_s', 'excluded_rows', 'rows', 'name', 'x']), inner, max_size=3),
    max_leaves=8)


@settings(FUZZ, max_examples=60)
@given(st.one_of(edits(5).map(lambda e: ('text', e)), _JSON.map(lambda v: ('custom', v))))
def test_damaged_bag_metadata(damage: tuple) -> None:
    template = _bag_template()
    root = _workdir()
    try:
        shutil.copytree(template.parent, root / 'c')
        meta = root / 'c' / 'r0' / 'metadata.yaml'
        kind, value = damage
        if kind == 'text':
            meta.write_text(apply_edits(meta.read_text(), value))
        else:
            doc = yaml.safe_load(meta.read_text())
            doc['rosbag2_bagfile_information']['custom_data'][
                'feed_axis_energy/measured_run'] = json.dumps(value)
            meta.write_text(yaml.safe_dump(doc))
        check_outcome(*run_cli(['compare', '--quiet', '--json',
                                str(root / 'c' / template.name)]), json_output=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)
