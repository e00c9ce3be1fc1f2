"""``--start-time`` (wall-clock stamps) and the QoS profiles stored in recordings."""
from pathlib import Path

from mcap.reader import make_reader
import must_run
import numpy as np
import pytest
from rosbags.interfaces import QosDurability, QosHistory, QosReliability
from rosbags.rosbag2 import Reader

from feed_axis_energy.cli import main
from feed_axis_energy.record import bagio
from feed_axis_energy.record.qos import qos_yaml, topic_qos
from feed_axis_energy.graph.flow import header_stamp_ns
from feed_axis_energy.record.plotread import read_plot_topic
from feed_axis_energy.record.plottopics import TOPIC_PLOT_BLOCK_ENERGY, TOPIC_PLOT_POWER
from feed_axis_energy.record.starttime import check_end, MAX_STAMP_NS, parse_start_time

REPO = Path(__file__).resolve().parents[2]
PROGRAM = REPO / 'config' / 'programs' / 'demonstrator_f500.nc'
_NS = 1_000_000_000
# 2026-11-23 by hand: 56 years from 1970 with 14 leap days, then 304 days to November 1st
# and 22 more: 20 780 days; + 14 h
NOV23_14H = (20_780 * 86_400 + 14 * 3600) * _NS


@pytest.mark.parametrize('text, want', [
    ('2026-11-23T14:00:00Z', NOV23_14H),
    ('2026-11-23T14:00:00', NOV23_14H),                      # no offset: UTC
    ('2026-11-23 15:30:00+01:30', NOV23_14H),
    ('2026-11-23T14:00:00.000000250+00:00'[:26] + '+00:00', NOV23_14H),
    ('2026-11-23', NOV23_14H - 14 * 3600 * _NS),
    ('1970-01-01T00:00:00Z', 0),
    ('now', 123_456_789),
    (' NOW ', 123_456_789),
])
def test_parse_start_time(text, want):
    assert parse_start_time(text, now_ns=123_456_789) == want


@pytest.mark.parametrize('text', ['yesterday', '', '2026-13-01', '1969-12-31T23:59:59Z',
                                  '2038-01-19T03:14:08Z', 'x' * 1000])
def test_parse_start_time_refuses(text):
    with pytest.raises(ValueError) as err:
        parse_start_time(text)
    assert len(str(err.value)) < 200                         # the input is shortened


def test_check_end():
    assert check_end(0, 3600.0) is None
    assert check_end(MAX_STAMP_NS - 10 * _NS, 10.0) is None
    assert '2038' in check_end(MAX_STAMP_NS - 10 * _NS, 10.5)
    assert 'not finite' in check_end(0, float('inf'))


def test_simulate_start_time_stamps_every_topic(tmp_path):
    out = tmp_path / 'rec'
    assert main(['simulate', str(PROGRAM), '--out', str(out), '--quiet',
                 '--start-time', '2026-11-23T14:00:00Z']) == 0
    meta = bagio.read_metadata(out)
    assert meta['starting_time']['nanoseconds_since_epoch'] == NOV23_14H
    ref = tmp_path / 'ref'
    assert main(['simulate', str(PROGRAM), '--out', str(ref), '--quiet']) == 0
    # the same samples, shifted by the start: header stamps and log times alike
    # (integer nanoseconds: float seconds since 1970 keep only ~0.2 us)
    for topic in (bagio.TOPIC_POWER, bagio.TOPIC_SETPOINTS, bagio.TOPIC_AXIS_STATE):
        shifted = bagio.read_raw_messages(out, [topic])
        plain = bagio.read_raw_messages(ref, [topic])
        assert [m[1] for m in shifted] == [m[1] + NOV23_14H for m in plain]     # log times
        assert [header_stamp_ns(m[2]) for m in shifted] == [m[1] for m in shifted]
        assert [m[2][12:] for m in shifted] == [m[2][12:] for m in plain]       # the rest
        # read back as a series: the same times bit for bit, the start kept apart
        wall, sim = bagio.read_series(out, topic), bagio.read_series(ref, topic)
        assert (wall.t0_ns, sim.t0_ns) == (NOV23_14H, 0)
        np.testing.assert_array_equal(wall.t, sim.t)
        np.testing.assert_array_equal(wall.stamps_ns(), sim.stamps_ns() + NOV23_14H)
    plot, plain = read_plot_topic(out, TOPIC_PLOT_POWER), read_plot_topic(ref, TOPIC_PLOT_POWER)
    np.testing.assert_array_equal(plot.t_ns, plain.t_ns + NOV23_14H)   # log time = stamp
    assert bagio.read_block_energy(out) == bagio.read_block_energy(ref)
    (end,) = read_plot_topic(out, TOPIC_PLOT_BLOCK_ENERGY).t_ns
    assert end == NOV23_14H + int(round(13.3 * _NS))


@pytest.mark.parametrize('value, code', [('not a time', 2), ('2038-01-19T03:14:00Z', 1)])
def test_simulate_start_time_refused(tmp_path, capsys, value, code):
    out = tmp_path / 'rec'
    with pytest.raises(SystemExit) if code == 2 else _nothing() as exc:
        rc = main(['simulate', str(PROGRAM), '--out', str(out), '--quiet',
                   '--start-time', value])
    rc = exc.value.code if code == 2 else rc
    assert rc == code
    assert 'start-time' in capsys.readouterr().err
    assert not out.exists() and list(tmp_path.iterdir()) == []


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def test_qos_in_metadata_and_channels(tmp_path):
    out = tmp_path / 'rec'
    assert main(['simulate', str(PROGRAM), '--out', str(out), '--quiet']) == 0
    info = bagio.read_metadata(out)
    profiles = {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles']
                for t in info['topics_with_message_count']}
    assert profiles['/block_energy'][0]['durability'] == 'transient_local'
    assert profiles['/block_energy'][0]['depth'] == 1
    assert profiles['/power'][0]['depth'] == 100
    assert all(p == topic_qos(t) for t, p in profiles.items())
    # rosbags parses them (metadata.yaml) as rosbag2 would
    with Reader(out) as reader:
        conns = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    (latched,) = conns['/plot/block_energy']
    assert latched.durability == QosDurability.TRANSIENT_LOCAL
    assert latched.reliability == QosReliability.RELIABLE
    assert latched.history == QosHistory.KEEP_LAST and latched.depth == 1
    assert conns['/plot/power'][0].depth == 100
    # and the MCAP channels carry the same profiles as YAML text
    (path,) = out.glob('*.mcap')
    with open(path, 'rb') as fh:
        channels = make_reader(fh).get_summary().channels.values()
    for channel in channels:
        assert channel.metadata['offered_qos_profiles'] == qos_yaml(topic_qos(channel.topic))


def test_profiles_match_the_node_graph():
    qos = must_run.import_or_skip('rclpy.qos', 'rclpy')
    from feed_axis_energy.nodes.qos import clock_qos, latched_qos, stream_qos
    for topic, profile in (('/power', stream_qos()), ('/block_energy', latched_qos()),
                           ('/program/end', latched_qos()), ('/clock', clock_qos())):
        (want,) = topic_qos(topic)
        assert profile.depth == want['depth']
        assert profile.history == qos.HistoryPolicy.KEEP_LAST
        assert profile.reliability == qos.ReliabilityPolicy.RELIABLE
        assert profile.durability.name.lower() == want['durability']
        assert profile.liveliness.name.lower() == want['liveliness']
        assert profile.deadline.nanoseconds == 0 and profile.lifespan.nanoseconds == 0


def _marker_cdr(end, *, name='program_end') -> bytes:
    ts = bagio.typestore()
    t = ts.types
    msg = t[bagio.DIAGNOSTIC_ARRAY](
        header=t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](
            sec=end.last_ns // _NS, nanosec=end.last_ns % _NS), frame_id=''),
        status=[t['diagnostic_msgs/msg/DiagnosticStatus'](
            level=0, name=name, message='program streamed completely', hardware_id='',
            values=[t['diagnostic_msgs/msg/KeyValue'](key=k, value=v)
                    for k, v in end.to_pairs()])])
    return bytes(ts.serialize_cdr(msg, bagio.DIAGNOSTIC_ARRAY))


def _marker(cdr: bytes):
    from feed_axis_energy.graph.end import ProgramEnd
    msg = bagio.typestore().deserialize_cdr(cdr, bagio.DIAGNOSTIC_ARRAY)
    return msg, ProgramEnd.from_pairs((kv.key, kv.value) for s in msg.status
                                      for kv in s.values)


@pytest.mark.parametrize('per_topic', [{}, {'measured/power': 2_500_000_000,
                                            'measured/kinematics': 1_200_000_000}])
def test_end_marker_moves_to_wall_clock_time_with_its_stamps(per_topic):
    # /program/end says up to which stamp each stream runs; in a wall-clock recording those
    # values must be wall-clock stamps too, or they point 56 years before the data.
    from feed_axis_energy.graph.end import ProgramEnd, restamp_end_marker
    end = ProgramEnd('p.nc', samples=300, batches=3, first_ns=1_000_000,
                     last_ns=2_500_000_000, topic_last_ns=per_topic)
    moved = restamp_end_marker(_marker_cdr(end), NOV23_14H)
    assert header_stamp_ns(moved) == NOV23_14H + end.last_ns
    msg, got = _marker(moved)
    assert got == ProgramEnd('p.nc', samples=300, batches=3, first_ns=NOV23_14H + 1_000_000,
                             last_ns=NOV23_14H + 2_500_000_000,
                             topic_last_ns={k: NOV23_14H + v for k, v in per_topic.items()})
    (status,) = msg.status
    assert (status.name, status.message) == ('program_end', 'program streamed completely')
    assert restamp_end_marker(_marker_cdr(end), 0) == _marker_cdr(end)


def test_end_marker_that_is_not_one_is_a_clear_error():
    from feed_axis_energy.errors import DataError
    from feed_axis_energy.graph.end import ProgramEnd, restamp_end_marker
    end = ProgramEnd('p.nc', samples=3, batches=1, first_ns=0, last_ns=2)
    with pytest.raises(DataError, match='no status named program_end'):
        restamp_end_marker(_marker_cdr(end, name='other'), NOV23_14H)
    with pytest.raises(DataError, match='program/end'):
        restamp_end_marker(b'\x00\x01\x00\x00' + b'\xff' * 9, NOV23_14H)
    with pytest.raises(DataError, match='time range'):
        restamp_end_marker(_marker_cdr(end), MAX_STAMP_NS)
