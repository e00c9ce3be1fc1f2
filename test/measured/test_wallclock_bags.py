"""Measured-run bags stamped in wall-clock time read, import and compare as stamped from 0.

A bag recorded from a live machine (or by the graph with ``start_time``) carries stamps near
1.8e18 ns. Float seconds since 1970 resolve only about 0.24 us there, so sample times must
be counted from the first stamp in integer nanoseconds (``bagio.Series.t0_ns``).
"""
import importlib.util
import json
from pathlib import Path
import shutil

import numpy as np
from numpy.testing import assert_array_equal
from rosbags.rosbag2 import Reader

from feed_axis_energy.cli import main
from feed_axis_energy.record import bagio, StreamBagWriter
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.importer import import_campaign

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / 'test' / 'fixtures' / 'measured'
# 2026-11-23T14:00:00.000000123Z: an odd nanosecond, so no sample time is a round number
WALL_START_NS = 1_795_356_000_000_000_123
_NS = 1_000_000_000


def wall_clock_copy(src: Path, dst: Path, start_ns: int, *, custom: bool = True) -> None:
    """Copy a bag with every log time and header stamp moved later by ``start_ns``
    (``custom``: with its ``custom_data``)."""
    ts = bagio.typestore()
    time_cls = ts.types['builtin_interfaces/msg/Time']
    custom_data = bagio.read_metadata(src).get('custom_data') or {}
    with Reader(src) as reader, StreamBagWriter(dst) as writer:
        for conn, log_ns, raw in reader.messages():
            msg = ts.deserialize_cdr(raw, conn.msgtype)
            stamp = msg.header.stamp.sec * _NS + msg.header.stamp.nanosec + start_ns
            msg.header.stamp = time_cls(sec=stamp // _NS, nanosec=stamp % _NS)
            writer.write_message(conn.topic, conn.msgtype, log_ns + start_ns, msg)
        for key, text in (custom_data if custom else {}).items():
            writer.set_custom_data(key, json.loads(text))


def wall_clock_campaign(imported: Path, out: Path, *, custom: bool = True) -> Path:
    """A copy of an imported campaign directory whose bags are stamped in wall-clock time."""
    shutil.copytree(imported, out)
    for bag in sorted(p.parent for p in out.glob('*/metadata.yaml')):
        shutil.rmtree(bag)
        wall_clock_copy(imported / bag.name, bag, WALL_START_NS, custom=custom)
    return out / 'campaign.yaml'


def test_wall_clock_copy_is_stamped_in_wall_clock_time(tmp_path):
    bags = import_campaign(load_campaign(FIXTURES / 'campaign.yaml'), tmp_path / 'sim')
    manifest = wall_clock_campaign(tmp_path / 'sim', tmp_path / 'wall')
    bag = manifest.parent / 'a'
    raw = bagio.read_raw_messages(bag, [bagio.TOPIC_MEASURED_POWER])
    assert raw[0][1] == WALL_START_NS          # the fixture's stamps start at 0
    assert bagio.read_series(bag, bagio.TOPIC_MEASURED_POWER).t0_ns == WALL_START_NS
    assert bags.runs[0].name == 'a'


def test_wall_clock_run_loads_the_same_to_the_nanosecond(tmp_path):
    import_campaign(load_campaign(FIXTURES / 'campaign.yaml'), tmp_path / 'sim')
    sim = load_campaign(tmp_path / 'sim' / 'campaign.yaml')
    wall = load_campaign(wall_clock_campaign(tmp_path / 'sim', tmp_path / 'wall'))
    for name in ('a', 'b'):
        want, got = load_run(sim.run(name)), load_run(wall.run(name))
        assert_array_equal(got.t, want.t)      # not rounded to 0.24 us steps
        assert_array_equal(got.power_w, want.power_w)
        assert_array_equal(got.position_m, want.position_m)
        assert got.extra['t0_s'] == want.extra['t0_s']      # from the run's metadata


def test_wall_clock_bag_without_run_metadata_starts_at_its_first_stamp(tmp_path):
    # a bag recorded live has no import metadata: t0_s is then where its stamps start
    import_campaign(load_campaign(FIXTURES / 'campaign.yaml'), tmp_path / 'sim')
    wall = load_campaign(wall_clock_campaign(tmp_path / 'sim', tmp_path / 'wall',
                                             custom=False))
    sim = load_campaign(tmp_path / 'sim' / 'campaign.yaml')
    got, want = load_run(wall.run('a')), load_run(sim.run('a'))
    assert_array_equal(got.t, want.t)
    assert got.extra['t0_s'] == WALL_START_NS / 1e9
    assert got.extra['excluded_rows'] == 0 and want.extra['excluded_rows'] == 1


def _synthetic_manifest(root: Path) -> Path:
    spec = importlib.util.spec_from_file_location(
        '_synthetic_campaign', ROOT / 'test' / 'measured' / 'test_compare.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.write_campaign(root, [
        {'name': 'a', 'load_kg': 0.0, 'offset_ms': 300, 'noise_w': 0.2, 'role': 'calibrate'},
        {'name': 'b', 'load_kg': 17.336, 'offset_ms': 150, 'factor': 1.1, 'noise_w': 0.2,
         'role': 'validate'},
    ])


def test_compare_and_import_of_wall_clock_bags_match_the_sim_time_bags(tmp_path, capsys):
    csv_manifest = _synthetic_manifest(tmp_path / 'csv')
    assert main(['import', str(csv_manifest), '--out', str(tmp_path / 'sim'), '--quiet']) == 0
    wall = wall_clock_campaign(tmp_path / 'sim', tmp_path / 'wall')
    capsys.readouterr()
    outputs = []
    for manifest in (tmp_path / 'sim' / 'campaign.yaml', wall):
        assert main(['compare', str(manifest), '--json', '--quiet', '--max-lag-s', '1']) == 0
        out = json.loads(capsys.readouterr().out)
        for key in ('manifest',):
            out.pop(key)
        for run in out['runs']:
            run.pop('data_file')
        outputs.append(out)
    assert outputs[0] == outputs[1]
    # importing the wall-clock bags again gives the sim-time bags' data
    assert main(['import', str(wall), '--out', str(tmp_path / 'again'), '--quiet']) == 0
    for name in ('a', 'b'):
        want = bagio.read_series(tmp_path / 'sim' / name, bagio.TOPIC_MEASURED_POWER)
        got = bagio.read_series(tmp_path / 'again' / name, bagio.TOPIC_MEASURED_POWER)
        assert_array_equal(got.t, want.t)
        assert_array_equal(got.velocities, want.velocities)
        np.testing.assert_allclose(got.positions, want.positions, rtol=1e-12, atol=1e-9)
