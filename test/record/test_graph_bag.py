"""ChunkedBagWriter: readable by rosbags and the mcap library at every moment, SIGKILL included."""
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import time

from mcap.reader import make_reader
import pytest
from rosbags.rosbag2 import Reader
import yaml

from feed_axis_energy.record import bagio
from feed_axis_energy.record.crashsafe import ChunkedBagWriter

ROOT = Path(__file__).resolve().parents[2]
TOPIC = '/power'


def _cdr(stamp_ns, ts=bagio.typestore()):
    cls = ts.types[bagio.JOINT_TRAJECTORY]
    hdr = ts.types['std_msgs/msg/Header']
    tm = ts.types['builtin_interfaces/msg/Time']
    msg = cls(header=hdr(stamp=tm(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
                         frame_id=''), joint_names=['X'], points=[])
    return bytes(ts.serialize_cdr(msg, bagio.JOINT_TRAJECTORY))


def read_rosbags(path):
    """``[(topic, log_ns)]`` through rosbags' multi-file reader."""
    with Reader(path) as reader:
        return [(c.topic, t) for c, t, _ in reader.messages()]


def read_mcap(path):
    """``[(topic, log_ns)]`` through the mcap library, file by file as the metadata lists."""
    meta = yaml.safe_load((Path(path) / 'metadata.yaml').read_text())
    out = []
    for name in meta['rosbag2_bagfile_information']['relative_file_paths']:
        with open(Path(path) / name, 'rb') as fh:
            out += [(ch.topic, m.log_time) for _, ch, m in make_reader(fh).iter_messages()]
    return sorted(out, key=lambda m: m[1])


def test_metadata_exists_from_the_start(tmp_path):
    bag = ChunkedBagWriter(tmp_path / 'b', typestore=bagio.typestore(),
                           topics={TOPIC: bagio.JOINT_TRAJECTORY})
    assert read_rosbags(tmp_path / 'b') == [] and read_mcap(tmp_path / 'b') == []
    assert bagio.bag_topics(tmp_path / 'b') == {TOPIC: (bagio.JOINT_TRAJECTORY, 0)}
    for i in range(3):
        for k in range(5):
            bag.write(TOPIC, (i * 5 + k) * 1000, _cdr((i * 5 + k) * 1000))
        assert len(read_rosbags(tmp_path / 'b')) == 5 * i   # buffered: not yet in the bag
        assert bag.flush() == 5
        want = [(TOPIC, n * 1000) for n in range(5 * (i + 1))]
        assert read_rosbags(tmp_path / 'b') == want == read_mcap(tmp_path / 'b')
    bag.add_topic('/setpoints', bagio.JOINT_TRAJECTORY)   # listed at once, no messages yet
    assert bagio.bag_topics(tmp_path / 'b')['/setpoints'] == (bagio.JOINT_TRAJECTORY, 0)
    bag.set_custom_data('k', 'v')
    bag.close()
    meta = yaml.safe_load((tmp_path / 'b' / 'metadata.yaml').read_text())
    assert meta['rosbag2_bagfile_information']['custom_data'] == {'k': 'v'}
    assert sorted(p.name for p in (tmp_path / 'b').iterdir()) == [
        'b_0.mcap', 'b_1.mcap', 'b_2.mcap', 'b_3.mcap', 'metadata.yaml']


@pytest.mark.parametrize('kind', ['dir', 'file', 'dangling', 'link_to_dir'])
def test_refuses_anything_that_exists(tmp_path, kind):
    target = tmp_path / 'out'
    if kind == 'dir':
        target.mkdir()
    elif kind == 'file':
        target.write_text('keep')
    elif kind == 'dangling':
        target.symlink_to(tmp_path / 'nowhere')
    else:
        (tmp_path / 'elsewhere').mkdir()
        target.symlink_to(tmp_path / 'elsewhere')
    with pytest.raises(FileExistsError, match='out'):
        ChunkedBagWriter(target, typestore=bagio.typestore())
    assert not (tmp_path / 'nowhere').exists()
    if kind == 'link_to_dir':
        assert list((tmp_path / 'elsewhere').iterdir()) == []
    if kind == 'file':
        assert target.read_text() == 'keep'


def test_failed_flush_keeps_the_bag_and_the_messages(tmp_path, monkeypatch):
    bag = ChunkedBagWriter(tmp_path / 'b', typestore=bagio.typestore(),
                           topics={TOPIC: bagio.JOINT_TRAJECTORY})
    bag.write(TOPIC, 1, _cdr(1))
    bag.flush()
    bag.write(TOPIC, 2, _cdr(2))

    def full(*args, **kwargs):
        raise OSError(28, 'No space left on device')
    monkeypatch.setattr(os, 'replace', full)
    with pytest.raises(OSError):
        bag.flush()
    monkeypatch.undo()
    assert read_rosbags(tmp_path / 'b') == [(TOPIC, 1)]   # as of the last good flush
    assert bag.buffered == 1
    assert [p.name for p in (tmp_path / 'b').iterdir() if p.name.startswith('.')] == []
    bag.close()
    assert read_rosbags(tmp_path / 'b') == [(TOPIC, 1), (TOPIC, 2)]


# One process imports once and forks a writer per round (a fresh interpreter per round costs
# seconds of imports on a busy machine); the writer appends its count after every flush.
_FORKER = '''
import os, sys
sys.path.insert(0, sys.argv[1])
from feed_axis_energy.record import bagio
from feed_axis_energy.record.crashsafe import ChunkedBagWriter
from test_graph_bag import _cdr
for line in sys.stdin:
    path, per_flush = line.split()
    pid = os.fork()
    if pid == 0:
        log = os.open(path + '.count', os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        bag = ChunkedBagWriter(path, typestore=bagio.typestore(),
                               topics={'/power': bagio.JOINT_TRAJECTORY})
        n = 0
        while True:
            for _ in range(int(per_flush)):
                bag.write('/power', n * 1000, _cdr(n * 1000))
                n += 1
            bag.flush()
            os.write(log, f'{n}\\n'.encode())
    print(pid, flush=True)
    os.waitpid(pid, 0)
    print('reaped', flush=True)
'''


def test_sigkill_at_random_moments_leaves_a_readable_prefix(tmp_path):
    """A writer process killed at 20 random moments: the bag holds every flushed message.

    The writer appends the message count after each flush; at the kill the bag must hold
    exactly a prefix of what was written, at least up to the last count appended.
    """
    rng = random.Random(20261123)
    env = {**os.environ, 'PYTHONPATH': str(ROOT)}
    forker = subprocess.Popen([sys.executable, '-c', _FORKER, str(Path(__file__).parent)],
                              env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        for k in range(20):
            path = tmp_path / f'bag{k}'
            count = Path(f'{path}.count')
            forker.stdin.write(f'{path} {rng.choice([1, 7, 50])}\n')
            forker.stdin.flush()
            pid = int(forker.stdout.readline())
            deadline = time.monotonic() + 30
            while not count.exists() or not count.read_text():   # one flush at least
                assert time.monotonic() < deadline, 'writer did not flush'
                time.sleep(0.01)
            time.sleep(rng.uniform(0.0, 0.2))
            os.kill(pid, signal.SIGKILL)
            assert forker.stdout.readline().strip() == 'reaped'
            flushed = int(count.read_text().split()[-1])
            got = read_rosbags(path)
            assert got == read_mcap(path)
            assert len(got) >= flushed
            assert got == [(TOPIC, n * 1000) for n in range(len(got))]
    finally:
        forker.kill()
        forker.wait()


def test_metadata_text_equals_the_metadata_dict(tmp_path):
    """The cached text rendering of the file lists parses to the full metadata."""
    bag = ChunkedBagWriter(tmp_path / 'odd: #name', typestore=bagio.typestore(),
                           topics={TOPIC: bagio.JOINT_TRAJECTORY})
    for i in range(4):
        bag.write(TOPIC, 10 + i, _cdr(10 + i))
        bag.flush()
    text = (tmp_path / 'odd: #name' / 'metadata.yaml').read_text()
    assert yaml.safe_load(text) == bag.metadata()
    assert len(read_rosbags(tmp_path / 'odd: #name')) == 4


def _end_marker(end, ts=bagio.typestore()):
    """``/program/end`` CDR as gcode_trajectory publishes it (built with rosbags)."""
    arr = ts.types[bagio.DIAGNOSTIC_ARRAY]
    status = ts.types['diagnostic_msgs/msg/DiagnosticStatus']
    kv = ts.types['diagnostic_msgs/msg/KeyValue']
    hdr = ts.types['std_msgs/msg/Header']
    tm = ts.types['builtin_interfaces/msg/Time']
    msg = arr(header=hdr(stamp=tm(sec=0, nanosec=end.last_ns), frame_id=''), status=[status(
        level=0, name='program_end', message='', hardware_id='',
        values=[kv(key=k, value=v) for k, v in end.to_pairs()])])
    return bytes(ts.serialize_cdr(msg, bagio.DIAGNOSTIC_ARRAY))


@pytest.mark.parametrize('drop', [None, '/power', 'marker'])
def test_recording_gaps_against_the_end_marker(tmp_path, drop):
    from feed_axis_energy.graph.end import ProgramEnd
    from feed_axis_energy.graph.flow import recording_gaps
    streams = ('/setpoints', '/axis_state', '/power')
    topics = {t: bagio.JOINT_TRAJECTORY for t in streams}
    topics['/program/end'] = bagio.DIAGNOSTIC_ARRAY
    bag = ChunkedBagWriter(tmp_path / 'b', typestore=bagio.typestore(), topics=topics)
    stamps = [100, 200, 300]
    for t in streams:
        for s in stamps[:2] if t == drop else stamps:
            bag.write(t, s, _cdr(s))
    if drop != 'marker':
        end = ProgramEnd('p.nc', 300, 3, 100, 300)
        bag.write('/program/end', 300, _end_marker(end))
    bag.close()
    gaps = recording_gaps(tmp_path / 'b')
    if drop is None:
        assert gaps == []
    elif drop == 'marker':
        assert len(gaps) == 1 and 'no /program/end' in gaps[0]
    else:
        assert gaps == ['/power: 2 of 3 batches']
