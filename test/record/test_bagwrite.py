"""The bag writer (mcapstream, bagwrite, SimulationBagWriter): what rosbags would have written.

Round trips through every reader we promise (our bagio readers, rosbags' AnyReader, the mcap
library with CRC checks), the same messages and metadata as rosbags' own Writer, chunk
boundaries anywhere, and nothing left on failure.
"""
import json
from pathlib import Path

from mcap.reader import make_reader
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                QosTime)
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

from feed_axis_energy.record import bagio
from feed_axis_energy.record.bagwrite import StreamBagWriter
from feed_axis_energy.record.cdr import block_energy_cdr, joint_trajectory_cdr
from feed_axis_energy.record.qos import topic_qos
from feed_axis_energy.gcode.load import load_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.record.recording import SimulationBagWriter, simulation_series
from feed_axis_energy.sim.stream import simulate_stream
from feed_axis_energy.sim.simulate import simulate_program

REPO = Path(__file__).resolve().parents[2]
SERIES_TOPICS = (bagio.TOPIC_SETPOINTS, bagio.TOPIC_AXIS_STATE, bagio.TOPIC_POWER)


def _rosbags_qos(profile: dict) -> Qos:
    """A :mod:`.qos` profile as rosbags' ``Qos``."""
    def time(key: str) -> QosTime:
        return QosTime(profile[key]['sec'], profile[key]['nsec'])
    return Qos(QosHistory[profile['history'].upper()], profile['depth'],
               QosReliability[profile['reliability'].upper()],
               QosDurability[profile['durability'].upper()], time('deadline'), time('lifespan'),
               QosLiveliness[profile['liveliness'].upper()], time('liveliness_lease_duration'),
               profile['avoid_ros_namespace_conventions'])


class RosbagsWriter:
    """The reference: rosbags' own ``Writer`` (MCAP storage) with the same API as ours."""

    def __init__(self, path: Path, *, compression: str = 'none') -> None:
        self._writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        if compression == 'zstd':
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._conns: dict[str, object] = {}

    def __enter__(self) -> 'RosbagsWriter':
        self._writer.open()
        return self

    def __exit__(self, *exc) -> None:
        self._writer.close()

    def _conn(self, topic: str, msgtype: str):
        if topic not in self._conns:
            self._conns[topic] = self._writer.add_connection(
                topic, msgtype, typestore=bagio.typestore(),
                offered_qos_profiles=[_rosbags_qos(q) for q in topic_qos(topic)])
        return self._conns[topic]

    def write_series(self, topic: str, series: bagio.Series, *, batch: int = 100) -> int:
        fields = [series.positions, series.velocities, series.accelerations, series.effort]
        raw = joint_trajectory_cdr(series.stamps_ns(), series.names, fields, batch=batch)
        conn = self._conn(topic, bagio.JOINT_TRAJECTORY)
        for stamp, data in raw:
            self._writer.write(conn, stamp, data)
        return len(raw)

    def write_block_energy(self, blocks, *, stamp_s: float, program: str = '') -> None:
        conn = self._conn(bagio.TOPIC_BLOCK_ENERGY, bagio.DIAGNOSTIC_ARRAY)
        for stamp, data in block_energy_cdr(blocks, stamp_s=stamp_s, program=program):
            self._writer.write(conn, stamp, data)

    def set_custom_data(self, key: str, value: object) -> None:
        self._writer.set_custom_data(key, json.dumps(value))


def _mcap_messages(bag: Path) -> list[tuple[str, int, int, bytes]]:
    """``(topic, log time, sequence, data)`` of every message, CRCs checked, file order."""
    (path,) = bag.glob('*.mcap')
    with open(path, 'rb') as fh:
        reader = make_reader(fh, validate_crcs=True)
        return [(channel.topic, m.log_time, m.sequence, m.data)
                for _, channel, m in reader.iter_messages(log_time_order=False)]


def _contour():
    machine = load_machine(REPO / 'config' / 'three_axis_mill.yaml')
    prog = load_gcode(REPO / 'config' / 'programs' / 'three_axis_contour.nc',
                      home=machine.home_point())
    return machine, prog


def _record(out: Path, machine, prog, *, chunk_samples: int, compression: str,
            chunk_bytes: int | None = None):
    with SimulationBagWriter(out, compression=compression) as writer:
        if chunk_bytes is not None:
            writer._bag.chunk_bytes = chunk_bytes        # many MCAP chunks in a small bag
        summary, blocks = simulate_stream(prog.moves, machine, file=prog.file,
                                          chunk_samples=chunk_samples, on_chunk=writer.write)
        writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
    return summary, blocks


@pytest.mark.parametrize('compression', ['zstd', 'lz4', 'none'])
@pytest.mark.parametrize('chunk_samples', [37, 1234, 65536])
def test_simulation_bag_round_trip(tmp_path, compression, chunk_samples):
    machine, prog = _contour()
    whole = simulate_program(prog, machine)
    out = tmp_path / 'rec'
    summary, blocks = _record(out, machine, prog, chunk_samples=chunk_samples,
                              compression=compression, chunk_bytes=50_000)
    # every series equals the whole-program one, sample for sample, bit for bit
    for topic, ref in simulation_series(whole).items():
        got = bagio.read_series(out, topic)
        assert got.names == ref.names
        np.testing.assert_array_equal(got.t, np.rint(ref.t * 1e9) / 1e9)
        for field in ('positions', 'velocities', 'accelerations', 'effort'):
            a, b = getattr(got, field), getattr(ref, field)
            assert (a is None) == (b is None)
            if a is not None:
                np.testing.assert_array_equal(a, b)
    assert bagio.read_block_energy(out) == list(blocks)
    assert bagio.read_custom_data(out, 'feed_axis_energy/summary') == summary
    # the mcap library: CRCs valid, per topic sequence 0, 1, 2, ... and stamps increasing
    msgs = _mcap_messages(out)
    for topic in SERIES_TOPICS:
        mine = [m for m in msgs if m[0] == topic]
        assert [m[2] for m in mine] == list(range(len(mine)))
        assert all(a[1] < b[1] for a, b in zip(mine, mine[1:]))
        assert len(mine) == -(-whole.power.t.shape[0] // 100)
    # rosbags' AnyReader decodes every message with the bag's own type definitions
    with AnyReader([out]) as reader:
        count = sum(1 for c, _, raw in reader.messages()
                    if reader.deserialize(raw, c.msgtype) is not None)
    assert count == len(msgs) == sum(n for _, n in bagio.bag_topics(out).values())


def test_chunks_hold_one_stretch_of_time_on_every_topic(tmp_path):
    machine, prog = _contour()
    out = tmp_path / 'rec'
    _record(out, machine, prog, chunk_samples=3000, compression='none', chunk_bytes=100_000)
    (path,) = out.glob('*.mcap')
    with open(path, 'rb') as fh:
        summary = make_reader(fh).get_summary()
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) > 10
    # a chunk starts where the previous one ended (the last messages may share a stamp)
    for a, b in zip(chunks, chunks[1:]):
        assert b.message_start_time > a.message_start_time
        assert b.message_start_time >= a.message_end_time
    assert set(summary.statistics.channel_message_counts.values()) >= {98}


def test_plot_topics_do_not_split_chunks(tmp_path):
    """With the plot topics (default 20 Hz) a slice of time still makes one chunk, not a full
    one and a small remainder: only the end of each write and of the bag leaves a small one."""
    machine, prog = _contour()
    out = tmp_path / 'rec'
    calls = []
    with SimulationBagWriter(out, compression='none') as writer:
        writer._bag.chunk_bytes = 100_000

        def write(chunk):
            calls.append(1)
            writer.write(chunk)
        summary, blocks = simulate_stream(prog.moves, machine, file=prog.file,
                                          chunk_samples=20_000, on_chunk=write)
        writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
    (path,) = out.glob('*.mcap')
    with open(path, 'rb') as fh:
        summary = make_reader(fh).get_summary()
    sizes = [c.uncompressed_size for c in summary.chunk_indexes]
    assert len(sizes) > 20
    assert max(sizes) < 100_000 + 20_000          # a slice ends near the limit, not far over
    small = sum(1 for s in sizes if s < 25_000)
    assert small <= len(calls) + 2, (small, len(calls), sorted(sizes)[:10])


def test_same_messages_and_metadata_as_rosbags_writer(tmp_path):
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(1e-4, 2e-3, 1234))
    series = bagio.Series(t=t, names=('X', 'Y'), positions=rng.normal(size=(1234, 2)),
                          velocities=rng.normal(size=(1234, 2)))
    blocks = [(3, 1.5, 0.25), (7, -2.0, 1e-3)]
    outs = {}
    for name, cls in (('rosbags', RosbagsWriter), ('mine', StreamBagWriter)):
        out = outs[name] = tmp_path / name
        with cls(out, compression='zstd') as writer:
            assert writer.write_series('/s', series, batch=100) == 13
            empty = bagio.Series(t=np.zeros(0), names=('X',), positions=np.zeros((0, 1)))
            assert writer.write_series('/empty', empty) == 0      # listed, no messages
            writer.write_block_energy(blocks, stamp_s=2.5, program='p.nc')
            writer.set_custom_data('k', {'a': [1, 2.5]})
    ref, got = (_mcap_messages(outs[n]) for n in ('rosbags', 'mine'))
    assert sorted((m[0], m[1], m[3]) for m in got) == sorted((m[0], m[1], m[3]) for m in ref)
    meta = {n: bagio.read_metadata(o) for n, o in outs.items()}
    for info, name in ((meta['rosbags'], 'rosbags'), (meta['mine'], 'mine')):
        assert info['relative_file_paths'] == [f'{name}.mcap']
        info.pop('relative_file_paths')
        info['files'][0].pop('path')
    assert meta['mine'] == meta['rosbags']
    assert [t['message_count'] for t in meta['mine']['topics_with_message_count']] == [
        13, 0, 1]
    # the channels' metadata (offered QoS profiles as YAML text) too
    channels = {}
    for name, out in outs.items():
        with open(next(out.glob('*.mcap')), 'rb') as fh:
            channels[name] = {c.topic: c.metadata
                              for c in make_reader(fh).get_summary().channels.values()}
    assert channels['mine'] == channels['rosbags']
    assert 'transient_local' in channels['mine']['/block_energy']['offered_qos_profiles']


def test_refuses_an_existing_directory_and_leaves_nothing_on_failure(tmp_path):
    (tmp_path / 'there').mkdir()
    with pytest.raises(FileExistsError):
        with StreamBagWriter(tmp_path / 'there'):
            pass
    assert list((tmp_path / 'there').iterdir()) == []
    series = bagio.Series(t=np.arange(500) * 1e-3, names=('X',),
                          positions=np.zeros((500, 1)))
    with pytest.raises(OSError, match='simulated'):
        with StreamBagWriter(tmp_path / 'b') as writer:
            writer.write_series('/s', series)
            raise OSError(28, 'No space left on device (simulated)')
    assert sorted(p.name for p in tmp_path.iterdir()) == ['there']


def test_negative_times_are_refused(tmp_path):
    series = bagio.Series(t=np.array([-1e-3, 0.0]), names=('X',), positions=np.zeros((2, 1)))
    with pytest.raises(ValueError, match='negative'):
        with StreamBagWriter(tmp_path / 'b') as writer:
            writer.write_series('/s', series)
    assert not (tmp_path / 'b').exists()


def test_a_damaged_compressed_chunk_is_detected(tmp_path):
    from feed_axis_energy.errors import DataError
    rng = np.random.default_rng(3)
    series = bagio.Series(t=np.arange(20_000) * 1e-3, names=('X',),
                          positions=np.cumsum(rng.normal(size=(20_000, 1)), axis=0))
    out = tmp_path / 'b'
    with StreamBagWriter(out, compression='zstd') as writer:
        writer.write_series('/s', series)
    (path,) = out.glob('*.mcap')
    with open(path, 'rb') as fh:
        chunk = make_reader(fh).get_summary().chunk_indexes[0]
    raw = bytearray(path.read_bytes())
    raw[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0x5A   # inside its zstd data
    path.write_bytes(bytes(raw))
    with pytest.raises(DataError, match=str(out)):
        bagio.read_series(out, '/s')
    with open(path, 'rb') as fh, pytest.raises(Exception):
        list(make_reader(fh).iter_messages())


def test_writer_thread_gives_the_same_file(tmp_path):
    machine, prog = _contour()
    files = []
    for background in (False, True):
        out = tmp_path / f'bg{int(background)}' / 'rec'
        with SimulationBagWriter(out, compression='zstd', background=background) as writer:
            writer._bag.chunk_bytes = 30_000
            summary, blocks = simulate_stream(prog.moves, machine, file=prog.file,
                                              chunk_samples=2000, on_chunk=writer.write)
            writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
        files.append(((out / 'rec.mcap').read_bytes(), (out / 'metadata.yaml').read_text()))
    assert files[0] == files[1]


def test_writer_thread_error_reaches_the_caller_and_nothing_is_left(tmp_path, monkeypatch):
    from feed_axis_energy.record import mcapstream
    real = mcapstream.McapStream._write_chunk
    calls = []

    def full_disk(self, *args):
        calls.append(1)
        if len(calls) == 3:
            raise OSError(28, 'No space left on device (simulated)')
        return real(self, *args)

    monkeypatch.setattr(mcapstream.McapStream, '_write_chunk', full_disk)
    machine, prog = _contour()
    with pytest.raises(OSError, match='simulated'):
        with SimulationBagWriter(tmp_path / 'rec', compression='zstd',
                                 background=True) as writer:
            writer._bag.chunk_bytes = 30_000
            summary, blocks = simulate_stream(prog.moves, machine, file=prog.file,
                                              chunk_samples=2000, on_chunk=writer.write)
            writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
    assert list(tmp_path.iterdir()) == []


def test_write_series_keeps_a_wall_clock_start(tmp_path):
    """A series read from a wall-clock bag (``t0_ns``) is written back at its stamps."""
    t0 = 1_790_000_000_123_456_789
    t = np.arange(250) * 1e-3
    series = bagio.Series(t=t, names=('X',), positions=np.sin(t)[:, None], t0_ns=t0)
    for name, cls in (('rosbags', RosbagsWriter), ('mine', StreamBagWriter)):
        out = tmp_path / name
        with cls(out, compression='none') as writer:
            writer.write_series('/s', series, batch=100)
        back = bagio.read_series(out, '/s')
        assert back.t0_ns == t0
        np.testing.assert_array_equal(back.stamps_ns(), series.stamps_ns())
        np.testing.assert_array_equal(back.positions, series.positions)
