"""Campaign manifest: merging defaults, resolving paths, and errors that name file and key."""
import copy
from pathlib import Path

import pytest
import yaml

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.measured.manifest import campaign_from_dict, load_campaign
from feed_axis_energy.measured.campaign import ColumnSpec, RowFilter

FIXTURES = Path(__file__).resolve().parents[1] / 'fixtures' / 'measured'

BASE = {
    'machine': 'machine.yaml',
    'runs': [{
        'name': 'r0', 'load_kg': 0, 'data': 'r0.csv', 'period_s': 0.1,
        'motion': {'from_data': 'actual'},
        'axes': {'X': {'power': {'column': 'P', 'unit': 'W'},
                       'position': {'column': 'X', 'unit': 'mm'}}},
    }],
}


def test_fixture_campaign_loads_with_defaults_merged():
    c = load_campaign(FIXTURES / 'campaign.yaml')
    assert c.name == 'fixture'
    assert c.machine == (FIXTURES / 'machine.yaml').resolve()
    a, b = c.runs
    assert a.data == (FIXTURES / 'run_a.csv').resolve() and a.data_kind == 'csv'
    assert a.load_kg == 2.5 and b.load_kg == 0.0          # run value beats the default
    assert a.axis_names == ('X', 'Y') and a.power_axes == ('X', 'Y')
    # defaults and the run's own columns are merged per axis
    assert a.axes['X']['power'] == ColumnSpec('PX_kW', 'kW')
    assert a.axes['X']['velocity'] == ColumnSpec('VX_mm_min', 'mm/min')
    assert a.time == ColumnSpec('time_ms', 'ms') and a.period_s is None
    assert b.time is None and b.period_s == 0.05
    assert a.exclude == (RowFilter('PROG', 'not_equal', 1.0),)
    assert a.motion_from_data == 'actual' and a.motion_program is None
    assert (a.role, b.role) == ('calibrate', 'validate')
    assert c.runs_with_role('validate') == (b,)
    assert c.run('b') is b
    with pytest.raises(KeyError, match='runs are a, b'):
        c.run('zz')


def test_program_path_is_resolved_relative_to_manifest(tmp_path):
    (tmp_path / 'sub').mkdir()
    for name in ('machine.yaml', 'r0.csv', 'sub/part.nc'):
        (tmp_path / name).write_text('x\n')
    d = copy.deepcopy(BASE)
    d['runs'][0]['motion'] = {'program': 'sub/part.nc'}
    (tmp_path / 'm.yaml').write_text(yaml.safe_dump(d))
    c = load_campaign(tmp_path / 'm.yaml')
    assert c.runs[0].motion_program == (tmp_path / 'sub' / 'part.nc').resolve()
    assert c.runs[0].motion_from_data is None


def _edit(path, value):
    d = copy.deepcopy(BASE)
    node = d
    for part in path[:-1]:
        node = node[part]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return d


@pytest.mark.parametrize('path, value, key, text', [
    (('runs', 0, 'axes', 'X', 'power', 'unit'), 'hp', 'runs[0].axes.X.power.unit',
     'unknown power unit'),
    (('runs', 0, 'axes', 'X', 'position', 'unit'), 'kW', 'runs[0].axes.X.position.unit',
     'unknown length unit'),
    (('runs', 0, 'axes', 'X', 'powr'), {'column': 'P', 'unit': 'W'}, 'runs[0].axes.X.powr',
     "did you mean 'power'"),
    (('runs', 0, 'load_kg'), -1, 'runs[0].load_kg', '>= 0'),
    (('runs', 0, 'load_kg'), 'heavy', 'runs[0].load_kg', 'expected a number'),
    (('runs', 0, 'period_s'), 0, 'runs[0].period_s', 'positive'),
    (('runs', 0, 'period_s'), KeyError, 'runs[0].period_s', 'time column'),
    (('runs', 0, 'motion'), {'from_data': 'guessed'}, 'runs[0].motion.from_data',
     'commanded or actual'),
    (('runs', 0, 'motion'), {'from_data': 'commanded'}, 'runs[0].motion.from_data',
     'command_position'),
    (('runs', 0, 'role'), 'train', 'runs[0].role', 'calibrate or validate'),
    (('runs', 0, 'name'), KeyError, 'runs[0].name', 'required'),
    (('runs', 0, 'time'), {'column': 't', 'unit': 's'}, 'runs[0].time', 'not both'),
    (('runs', 0, 'rows'), {'exclude_where': [{'column': 'A', 'greater': 'x'}]},
     'runs[0].rows.exclude_where[0].greater', 'needs a number'),
    (('runs', 0, 'rows'), {'exclude_where': [{'column': 'A', 'equal': 1, 'less': 2}]},
     'runs[0].rows.exclude_where[0]', 'exactly one'),
    (('runs', 0, 'axes', 'X', 'power'), KeyError, 'runs[0].axes', 'no axis has a power'),
    (('runs',), [], 'runs', 'non-empty list'),
    (('machine',), KeyError, 'machine', 'required'),
    (('split',), {'validate': ['nope']}, 'split.validate[0]', "no run named 'nope'"),
    (('split',), {'test': ['r0']}, 'split.test', 'unknown key'),
    (('runs', 0, 'instrument'), 'average', 'runs[0].instrument', 'expected point or'),
    (('runs', 0, 'motion'), {'from_data': 'actual', 'reconstruct': 'hermite'},
     'runs[0].motion.reconstruct', 'expected one of pulses, samples'),
    (('runs', 0, 'motion'), {'program': 'p.nc', 'reconstruct': 'samples'},
     'runs[0].motion.reconstruct', 'only for motion from_data'),
    (('runs', 0, 'instrument'), {'window_s': -0.1}, 'runs[0].instrument.window_s', '>= 0'),
    (('runs', 0, 'instrument'), {'window_s': 'x' * 500}, 'runs[0].instrument.window_s',
     'expected a number'),
    (('runs', 0, 'instrument'), {'stamp': 'middle'}, 'runs[0].instrument.stamp',
     'end, centre, start'),
    (('runs', 0, 'instrument'), {'windows': 0.1}, 'runs[0].instrument.windows',
     'unknown key'),
    (('runs', 0, 'instrument'), {'filter_s': -0.005}, 'runs[0].instrument.filter_s', '>= 0'),
    (('runs', 0, 'instrument'), {'filter_s': 60}, 'runs[0].instrument.filter_s',
     'lies in [0, 10] s'),
    (('runs', 0, 'instrument'), {'filter_s': 'fast'}, 'runs[0].instrument.filter_s',
     'expected a number'),
])
def test_bad_values_name_file_and_dotted_key(tmp_path, path, value, key, text):
    d = _edit(path, value)
    file = tmp_path / 'camp.yaml'
    with pytest.raises(ConfigError) as info:
        campaign_from_dict(d, file=file, check_files=False)
    err = info.value
    assert err.file == str(file) and err.key == key
    assert text in str(err) and str(file) in str(err)


@pytest.mark.parametrize('value, window, stamp', [
    ('point', 0.0, 'end'),
    ({'window_s': 0.05, 'stamp': 'centre'}, 0.05, 'centre'),
    ({'stamp': 'start'}, None, 'start'),
    ({}, None, 'end'),
])
def test_instrument_declaration(tmp_path, value, window, stamp):
    d = _edit(('runs', 0, 'instrument'), value)
    meter = campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False).runs[0].instrument
    assert (meter.window_s, meter.stamp, meter.declared) == (window, stamp, True)
    assert meter.window_for(0.1) == (0.1 if window is None else window)


def test_motion_reconstruction_choice(tmp_path):
    runs = campaign_from_dict(BASE, file=tmp_path / 'c.yaml', check_files=False).runs
    assert runs[0].motion_reconstruct == 'pulses'
    d = _edit(('runs', 0, 'motion'), {'from_data': 'actual', 'reconstruct': 'samples'})
    run = campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False).runs[0]
    assert (run.motion_from_data, run.motion_reconstruct) == ('actual', 'samples')


def test_instrument_default_depends_on_the_motion_source(tmp_path):
    from feed_axis_energy.measured.campaign import default_instrument
    run = campaign_from_dict(copy.deepcopy(BASE), file=tmp_path / 'c.yaml',
                             check_files=False).runs[0]
    assert not run.instrument.declared
    assert default_instrument('actual').window_for(0.1) == 0.0
    assert default_instrument(None).window_for(0.1) == 0.1
    assert default_instrument(None).describe(0.05) == '50 ms window stamped at its end (default)'


def test_kinematics_must_cover_every_axis_or_none(tmp_path):
    d = copy.deepcopy(BASE)
    d['runs'][0]['axes']['Y'] = {'power': {'column': 'PY', 'unit': 'W'}}
    with pytest.raises(ConfigError) as info:
        campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False)
    assert info.value.key == 'runs[0].axes.Y.position'


def test_error_in_defaults_is_named_there(tmp_path):
    d = copy.deepcopy(BASE)
    d['defaults'] = {'axes': {'X': {'power': {'column': 'P', 'unit': 'kw'}}}}
    with pytest.raises(ConfigError) as info:
        campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False)
    assert info.value.key == 'defaults.axes.X.power.unit'


def test_duplicate_names_and_conflicting_split(tmp_path):
    d = copy.deepcopy(BASE)
    d['runs'].append(copy.deepcopy(d['runs'][0]))
    with pytest.raises(ConfigError, match=r'runs\[1\]\.name: duplicate'):
        campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False)
    d = _edit(('runs', 0, 'role'), 'calibrate')
    d['split'] = {'validate': ['r0']}
    with pytest.raises(ConfigError, match=r'runs\[0\]\.role: .*contradicts'):
        campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False)


def test_missing_files_are_reported_when_checked(tmp_path):
    (tmp_path / 'machine.yaml').write_text('x\n')
    with pytest.raises(ConfigError, match=r'runs\[0\]\.data: no such file'):
        campaign_from_dict(copy.deepcopy(BASE), file=tmp_path / 'c.yaml')
    c = campaign_from_dict(copy.deepcopy(BASE), file=tmp_path / 'c.yaml', check_files=False)
    assert c.runs[0].data == (tmp_path / 'r0.csv').resolve()


def test_unreadable_and_invalid_yaml(tmp_path):
    with pytest.raises(ConfigError, match='cannot read manifest'):
        load_campaign(tmp_path / 'absent.yaml')
    (tmp_path / 'bad.yaml').write_text('runs: [\n')
    with pytest.raises(ConfigError, match='not valid YAML'):
        load_campaign(tmp_path / 'bad.yaml')
    (tmp_path / 'list.yaml').write_text('- 1\n')
    with pytest.raises(ConfigError, match='expected a mapping'):
        load_campaign(tmp_path / 'list.yaml')


def test_instrument_filter_declaration(tmp_path):
    # a meter that smooths: the time constant is kept beside the window, alone it keeps the
    # run's default window and stamp, and it is part of the meter's description
    d = _edit(('runs', 0, 'instrument'), {'window_s': 0.01, 'filter_s': 0.005})
    meter = campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False).runs[0].instrument
    assert (meter.window_s, meter.filter_s, meter.declared) == (0.01, 0.005, True)
    text = '10 ms window stamped at its end after a 5 ms first-order filter'
    assert meter.describe(0.01) == text
    d = _edit(('runs', 0, 'instrument'), {'filter_s': 0.02})
    meter = campaign_from_dict(d, file=tmp_path / 'c.yaml', check_files=False).runs[0].instrument
    assert (meter.filter_s, meter.declared, meter.window_s) == (0.02, False, None)
    run = campaign_from_dict(copy.deepcopy(BASE), file=tmp_path / 'c.yaml',
                             check_files=False).runs[0]
    assert run.instrument.filter_s == 0.0
