"""CSV runs -> measured-run bags -> MeasuredRun again, atomic writes, bag manifests."""
import copy
import hashlib
from pathlib import Path

import must_run
import numpy as np
from numpy.testing import assert_allclose, assert_array_equal
import pytest
import yaml

from feed_axis_energy.record import bagio, StreamBagWriter
from feed_axis_energy.errors import ConfigError, DataError, OutputError
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.bagload import (RUN_KEY, TOPIC_MEASURED_COMMAND,
                                               TOPIC_MEASURED_ELECTRICAL)
from feed_axis_energy.measured.importer import excerpt_run, import_campaign

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / 'test' / 'fixtures' / 'measured'
UMICH = ROOT.parent / 'shared' / 'data' / 'umich-cnc-mill'


def assert_same_run(got, want, *, atol_t=1e-9):
    assert got.name == want.name and got.load_kg == want.load_kg
    assert got.axes == want.axes and got.power_axes == want.power_axes
    assert_allclose(got.t, want.t, rtol=0, atol=atol_t)     # bags keep integer ns
    assert_array_equal(got.power_w, want.power_w)
    for field in ('position_m', 'velocity_m_s', 'acceleration_m_s2', 'command_position_m',
                  'command_velocity_m_s', 'command_acceleration_m_s2'):
        a, b = getattr(got, field), getattr(want, field)
        assert (a is None) == (b is None), field
        if a is not None:
            assert_array_equal(a, b)
    assert_array_equal(got.extra['rows'], want.extra['rows'])
    assert got.extra['excluded_rows'] == want.extra['excluded_rows']
    assert got.extra['t0_s'] == pytest.approx(want.extra['t0_s'], abs=1e-12)
    for key in ('current_a', 'voltage_v'):
        assert set(got.extra.get(key, {})) == set(want.extra.get(key, {}))
        for axis, values in want.extra.get(key, {}).items():
            assert_array_equal(got.extra[key][axis], values)


def test_round_trip_csv_bag_run(tmp_path):
    campaign = load_campaign(FIXTURES / 'campaign.yaml')
    result = import_campaign(campaign, tmp_path / 'out')
    assert [r.name for r in result.runs] == ['a', 'b']
    bags = load_campaign(result.manifest)
    assert [r.data_kind for r in bags.runs] == ['rosbag2', 'rosbag2']
    assert [r.role for r in bags.runs] == ['calibrate', 'validate']
    assert bags.machine == campaign.machine
    for name in ('a', 'b'):
        assert_same_run(load_run(bags.run(name)), load_run(campaign.run(name)))


def test_declared_instrument_is_carried_into_the_bag_manifest(tmp_path):
    from dataclasses import replace
    from feed_axis_energy.measured.campaign import InstrumentSpec
    campaign = load_campaign(FIXTURES / 'campaign.yaml')
    meter = InstrumentSpec(window_s=0.02, stamp='centre')
    campaign = replace(campaign, runs=(replace(campaign.runs[0], instrument=meter),
                                       campaign.runs[1]))
    bags = load_campaign(import_campaign(campaign, tmp_path / 'out').manifest)
    assert bags.run('a').instrument == meter
    assert not bags.run('b').instrument.declared


def test_work_offset_start_and_window_are_carried_into_the_bag_manifest(tmp_path):
    """A declared work offset and the machine's start position reach the bag manifest; a
    run's window is applied at import (its bag holds the window only, time from 0)."""
    from dataclasses import replace
    from feed_axis_energy.measured.campaign import TimeWindow
    campaign = load_campaign(FIXTURES / 'campaign.yaml')
    offset = (('X', -0.0378), ('Y', 0.2693))
    half = TimeWindow(end=0.5, fraction=True)
    first = replace(campaign.runs[0], work_offset_m=offset, window=half)
    campaign = replace(campaign, runs=(first, campaign.runs[1]))
    whole = load_run(replace(first, window=None))
    bags = load_campaign(import_campaign(campaign, tmp_path / 'out').manifest)
    got = bags.run('a')
    assert dict(got.work_offset_m) == pytest.approx(dict(offset))
    assert got.window is None and bags.run('b').work_offset_m == ()
    run = load_run(got)
    assert run.t[0] == pytest.approx(0.0, abs=1e-9)
    assert run.t[-1] < 0.5 * (whole.t[-1] - whole.t[0])
    assert run.t.shape[0] < whole.t.shape[0]
    # motion from a program: where the machine stood when it started goes along
    from feed_axis_energy.measured.importer import bag_manifest
    program = tmp_path / 'p.nc'
    program.write_text('G1 X1 F100\n')
    spec = replace(first, motion_program=program, motion_from_data=None,
                   motion_start_m=(0.1, -0.2, 0.3))
    entry = bag_manifest(campaign, [(spec, whole, tmp_path / 'bag')],
                         out_file=tmp_path / 'm.yaml')['runs'][0]
    assert entry['motion'] == {'program': 'p.nc', 'start_m': {'X': 0.1, 'Y': -0.2, 'Z': 0.3}}


def test_bag_topics_energy_and_metadata(tmp_path):
    campaign = load_campaign(FIXTURES / 'campaign.yaml')
    bag = import_campaign(campaign, tmp_path / 'out', runs=['a']).runs[0].bag
    csv_run = load_run(campaign.run('a'))
    topics = bagio.bag_topics(bag)
    assert set(topics) == {bagio.TOPIC_MEASURED_POWER, bagio.TOPIC_MEASURED_KINEMATICS,
                           TOPIC_MEASURED_ELECTRICAL}     # run a has no commanded columns
    power = bagio.read_series(bag, bagio.TOPIC_MEASURED_POWER)
    assert power.names == ('X', 'Y', 'total')
    assert_allclose(power.velocities[:, 2], csv_run.power_w.sum(axis=1))
    # energy by hand: trapezoids of the total power, 0 J at the first sample
    p, t = csv_run.total_power_w, csv_run.t
    by_hand = np.concatenate(([0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(t))))
    assert_allclose(power.positions[:, 2], by_hand, rtol=1e-12)
    assert_allclose(power.positions[:, 0] + power.positions[:, 1], by_hand, rtol=1e-12)
    kin = bagio.read_series(bag, bagio.TOPIC_MEASURED_KINEMATICS)
    assert kin.names == ('X', 'Y') and kin.accelerations is None
    meta = bagio.read_custom_data(bag, RUN_KEY)
    src = FIXTURES / 'run_a.csv'
    assert meta['source']['file'] == 'run_a.csv'
    assert meta['source']['sha256'] == hashlib.sha256(src.read_bytes()).hexdigest()
    # The data path is kept relative to the manifest, as the manifest wrote it.
    assert meta['source']['path'] == 'run_a.csv'
    assert not meta['source']['manifest'].startswith('/')
    assert meta['columns']['X']['power'] == {'column': 'PX_kW', 'unit': 'kW', 'si_unit': 'W'}
    assert meta['columns']['X']['velocity']['unit'] == 'mm/min'
    assert meta['load_kg'] == 2.5 and meta['excluded_rows'] == 1
    assert meta['rows'] == [[1, 2], [4, 3]]                 # row 3 was filtered out


def test_existing_destination_writes_nothing(tmp_path):
    campaign = load_campaign(FIXTURES / 'campaign.yaml')
    out = tmp_path / 'out'
    (out / 'b').mkdir(parents=True)
    with pytest.raises(OutputError, match='exists already'):
        import_campaign(campaign, out)
    assert sorted(p.name for p in out.iterdir()) == ['b']


def test_bad_csv_stops_before_any_bag_is_written(tmp_path):
    for name in ('run_a.csv', 'run_b.csv', 'machine.yaml'):
        (tmp_path / name).write_bytes((FIXTURES / name).read_bytes())
    doc = yaml.safe_load((FIXTURES / 'campaign.yaml').read_text())
    (tmp_path / 'campaign.yaml').write_text(yaml.safe_dump(doc))
    text = (tmp_path / 'run_b.csv').read_text().splitlines()
    text[2] = text[2].replace(text[2].split(',')[0], 'oops', 1)
    (tmp_path / 'run_b.csv').write_text('\n'.join(text) + '\n')
    with pytest.raises(DataError, match='oops'):
        import_campaign(load_campaign(tmp_path / 'campaign.yaml'), tmp_path / 'out')
    assert not (tmp_path / 'out').exists() or not any((tmp_path / 'out').iterdir())


def test_failure_while_writing_leaves_no_partial_bag(tmp_path, monkeypatch):
    campaign = load_campaign(FIXTURES / 'campaign.yaml')
    calls = []

    def broken(self, topic, series, *, batch=100):
        calls.append(topic)
        if len(calls) == 2:
            raise OSError('disk full (simulated)')
        return 1

    monkeypatch.setattr(StreamBagWriter, 'write_series', broken)
    out = tmp_path / 'out'
    with pytest.raises(OutputError, match='disk full'):
        import_campaign(campaign, out, runs=['a'])
    # no bag, no temporary, no manifest, and the directory this import created is gone too
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_excerpt_restarts_time_and_keeps_source_rows():
    run = load_run(load_campaign(FIXTURES / 'campaign.yaml').run('b'))
    part = excerpt_run(run, start_s=0.05, duration_s=0.05)
    assert_allclose(part.t, [0.0, 0.05])
    assert_array_equal(part.power_w, run.power_w[1:3])
    assert_array_equal(part.extra['rows'], run.extra['rows'][1:3])
    assert part.extra['t0_s'] == pytest.approx(run.extra['t0_s'] + 0.05)
    with pytest.raises(DataError, match='at least 2'):
        excerpt_run(run, start_s=10.0, duration_s=1.0)


def _bag_manifest(tmp_path):
    campaign = load_campaign(FIXTURES / 'campaign.yaml')
    result = import_campaign(campaign, tmp_path / 'out', runs=['b'])
    return yaml.safe_load(result.manifest.read_text()), result.manifest


@pytest.mark.parametrize('change, error, words', [
    (lambda r: r['axes']['X']['power'].update(unit='kW'), ConfigError, "must be 'W'"),
    (lambda r: r['axes']['X']['power'].update(column='PX_kW'), ConfigError, 'names the topic'),
    (lambda r: r.update(rows={'exclude_where': [{'column': 'P', 'equal': 1}]}), ConfigError,
     'CSV input only'),
    (lambda r: r['axes']['X'].update(command_velocity={'column': TOPIC_MEASURED_COMMAND,
                                                       'unit': 'm/s'})
     or r['axes']['Y'].update(command_velocity={'column': TOPIC_MEASURED_COMMAND,
                                                'unit': 'm/s'}), DataError, 'not in the bag'),
    (lambda r: r['axes'].update(Z={'power': {'column': '/measured/power', 'unit': 'W'},
                                   'position': {'column': '/measured/kinematics',
                                                'unit': 'm'}}),
     DataError, "no joint 'Z'"),
])
def test_bag_run_errors(tmp_path, change, error, words):
    doc, manifest = _bag_manifest(tmp_path)
    doc = copy.deepcopy(doc)
    change(doc['runs'][0])
    manifest.write_text(yaml.safe_dump(doc))
    with pytest.raises(error, match=words):
        load_run(load_campaign(manifest).runs[0])


def test_a_gap_is_refused_alike_in_csv_and_bag_runs(tmp_path):
    from dataclasses import replace
    campaign = load_campaign(FIXTURES / 'campaign.yaml')    # run a: a filter leaves a gap
    bags = load_campaign(import_campaign(campaign, tmp_path / 'out', runs=['a']).manifest)
    errors = []
    for spec in (campaign.run('a'), bags.run('a')):
        with pytest.raises(DataError) as info:
            load_run(replace(spec, allow_gaps=False))
        errors.append(info.value)
    csv_err, bag_err = errors
    assert csv_err.reason == bag_err.reason
    assert csv_err.reason.startswith('gap of 0.2 s before this row, more than 1.5 x')
    assert bag_err.column == bagio.TOPIC_MEASURED_POWER
    # the CSV names the data row in the file, the bag the sample; the same sample
    rows = load_run(bags.run('a')).extra['rows']
    assert csv_err.row == rows[bag_err.row - 1]


@must_run.skipif('shared', not (UMICH / 'experiment_08.csv').is_file(), 'UMich data absent')
def test_umich_run_round_trip_and_sample_bags(tmp_path):
    campaign = load_campaign(ROOT / 'config' / 'campaigns' / 'umich_mill.yaml')
    result = import_campaign(campaign, tmp_path / 'out', runs=['exp08'], duration_s=20.0)
    got = load_run(load_campaign(result.manifest).run('exp08'))
    want = excerpt_run(load_run(campaign.run('exp08')), duration_s=20.0)
    assert_same_run(got, want)
    assert got.t.shape[0] == 201
    samples = ROOT / 'bags' / 'umich_samples.yaml'
    if samples.is_file():
        shipped = load_campaign(samples)
        for spec in shipped.runs:
            meta = bagio.read_custom_data(spec.data, RUN_KEY)
            start, duration = meta['excerpt']['start_s'], meta['excerpt']['duration_s']
            source = excerpt_run(load_run(campaign.run(spec.name)), start_s=start,
                                 duration_s=duration)
            assert_same_run(load_run(spec), source)
            assert sum(f.stat().st_size for f in spec.data.iterdir()) < 1_000_000
