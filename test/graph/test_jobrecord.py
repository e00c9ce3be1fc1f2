"""One recording per job (graph.JobRecorder): staged, marked, renamed, never overwritten."""
import os
from pathlib import Path
import subprocess
import sys

import pytest

from feed_axis_energy.errors import OutputError
from feed_axis_energy.graph import (BagSink, EndTracker, JOB_KEY, JobRecorder, ProgramEnd,
                                    read_back, recording_gaps)
from feed_axis_energy.record import bagio, ChunkedBagWriter

STREAMS = ('setpoints', 'axis_state', 'power')


class Clock:
    """A monotonic clock the test moves."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def _cdr(stamp_ns, frame_id='', ts=bagio.typestore()):
    cls = ts.types[bagio.JOINT_TRAJECTORY]
    hdr = ts.types['std_msgs/msg/Header']
    tm = ts.types['builtin_interfaces/msg/Time']
    msg = cls(header=hdr(stamp=tm(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
                         frame_id=frame_id), joint_names=['X'], points=[])
    return bytes(ts.serialize_cdr(msg, bagio.JOINT_TRAJECTORY))


def _end_cdr(end, ts=bagio.typestore()):
    t = ts.types
    status = t['diagnostic_msgs/msg/DiagnosticStatus'](
        level=0, name='program_end', message='', hardware_id='',
        values=[t['diagnostic_msgs/msg/KeyValue'](key=k, value=v) for k, v in end.to_pairs()])
    hdr = t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](
        sec=end.last_ns // 10**9, nanosec=end.last_ns % 10**9), frame_id=end.job_id)
    msg = t[bagio.DIAGNOSTIC_ARRAY](header=hdr, status=[status])
    return bytes(ts.serialize_cdr(msg, bagio.DIAGNOSTIC_ARRAY))


def _new_sink(path):
    topics = {f'/{s}': bagio.JOINT_TRAJECTORY for s in STREAMS}
    topics['/program/end'] = bagio.DIAGNOSTIC_ARRAY
    bag = ChunkedBagWriter(path, typestore=bagio.typestore(), topics=topics)
    return BagSink(bag=bag, tracker=EndTracker(STREAMS))


def _stream(rec, batches, *, end=True):
    """``batches`` batches on every stream (stamps 0, 1 ms, ...), then the end marker."""
    for i in range(batches):
        for s in STREAMS:
            rec.sink.bag.write(f'/{s}', i * 10**6, _cdr(i * 10**6, rec.job_id))
            rec.sink.tracker.seen(s, i * 10**6)
            rec.sink.newest[s] = i * 10**6
    if end:
        _end(rec, batches)


def _end(rec, batches):
    end = ProgramEnd(program='p.nc', samples=batches * 100, batches=batches, first_ns=0,
                     last_ns=(batches - 1) * 10**6, job_id=rec.job_id)
    rec.sink.bag.write('/program/end', end.last_ns, _end_cdr(end))
    rec.sink.tracker.end = end


def _hidden(root):
    return sorted(p.name for p in Path(root).iterdir() if p.name.startswith('.'))


def test_a_job_is_built_hidden_and_renamed_into_place_when_closed(tmp_path):
    clock = Clock()
    jobs = JobRecorder(tmp_path / 'out', new_sink=_new_sink, clock=clock)
    jobs.note_state('planning', 'j1', {'job_id': 'j1', 'load_kg': 2.0})
    rec = jobs.open['j1']
    assert not (tmp_path / 'out' / 'j1').exists()              # not in place while open
    assert _hidden(tmp_path / 'out') == [f'.j1.tmp-{os.getpid()}']
    _stream(rec, 3)
    assert jobs.due() == []                                    # no result yet
    jobs.note_result({'job_id': 'j1', 'status': 'ended', 'message': 'program completed',
                      'samples': 300})
    assert jobs.due() == [rec]                                 # complete: closes at once
    path = jobs.close(rec)
    assert path == tmp_path / 'out' / 'j1' and _hidden(tmp_path / 'out') == []
    mark = bagio.read_custom_data(path, JOB_KEY)
    assert mark['job_id'] == 'j1' and mark['status'] == 'ended' and mark['complete']
    assert mark['gaps'] == [] and mark['spec'] == {'job_id': 'j1', 'load_kg': 2.0}
    assert mark['result']['samples'] == 300
    assert recording_gaps(path) == []           # the launcher's rule reads the same
    assert bagio.bag_topics(path)['/power'] == (bagio.JOINT_TRAJECTORY, 3)
    # later messages of the closed job (duplicates) are ignored, nothing reopens it
    assert jobs.recording('j1') is None and jobs.ignored == 1
    assert sorted(os.listdir(tmp_path / 'out')) == ['j1']


def test_an_incomplete_job_waits_for_the_grace_then_is_marked(tmp_path):
    clock = Clock()
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=clock, grace_s=5.0)
    rec = jobs.recording('j2')            # opened by a message before its state
    _stream(rec, 2, end=False)
    _end(rec, 3)
    jobs.note_result({'job_id': 'j2', 'status': 'failed', 'message': 'stall', 'samples': 200})
    assert jobs.due() == []
    clock.now += 5.0
    assert jobs.due() == [rec]
    path = jobs.close(rec)
    mark = bagio.read_custom_data(path, JOB_KEY)
    assert mark['status'] == 'failed' and not mark['complete']
    assert mark['gaps'] == [f'/{s}: 2 of 3 batches' for s in STREAMS]
    assert recording_gaps(path) == mark['gaps']


def test_a_job_failed_before_streaming_closes_at_once_and_empty(tmp_path):
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=Clock())
    jobs.note_state('planning', 'bad', None)
    jobs.note_result({'job_id': 'bad', 'status': 'failed', 'message': 'bad.nc:3:1: ...',
                      'samples': 0})
    (rec,) = jobs.due()
    mark = bagio.read_custom_data(jobs.close(rec), JOB_KEY)
    assert mark['status'] == 'failed' and not mark['complete'] and mark['result']['samples'] == 0


def test_shutdown_closes_open_jobs_as_interrupted(tmp_path):
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=Clock())
    _stream(jobs.recording('j3'), 2, end=False)
    assert jobs.close_all(note='the recorder stopped') == []
    mark = bagio.read_custom_data(tmp_path / 'j3', JOB_KEY)
    assert mark['status'] == 'interrupted' and mark['result'] is None and not mark['complete']
    assert 'the recorder stopped' in mark['message']
    assert bagio.bag_topics(tmp_path / 'j3')['/power'][1] == 2     # what arrived is kept


@pytest.mark.parametrize('kind', ['dir', 'file', 'dangling link', 'link to dir'])
def test_an_existing_recording_is_never_overwritten(tmp_path, kind):
    target = tmp_path / 'j1'
    if kind == 'dir':
        target.mkdir()
        (target / 'keep.txt').write_text('earlier')
    elif kind == 'file':
        target.write_text('earlier')
    elif kind == 'dangling link':
        target.symlink_to(tmp_path / 'nowhere')
    else:
        (tmp_path / 'elsewhere').mkdir()
        target.symlink_to(tmp_path / 'elsewhere')
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=Clock())
    before = sorted(os.listdir(tmp_path))
    with pytest.raises(OutputError, match='exists already|symbolic link'):
        jobs.note_state('planning', 'j1', None)
    assert sorted(os.listdir(tmp_path)) == before          # nothing created, nothing touched
    assert jobs.recording('j1') is None                    # refused once, then ignored
    if kind == 'dir':
        assert (target / 'keep.txt').read_text() == 'earlier'
    if kind == 'link to dir':
        assert os.listdir(tmp_path / 'elsewhere') == []    # nothing written through the link


def test_a_place_taken_while_the_job_ran_is_not_overwritten(tmp_path):
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=Clock())
    rec = jobs.recording('j1')
    _stream(rec, 1)
    (tmp_path / 'j1').mkdir()            # someone else made it meanwhile (empty: a rename
    jobs.note_result({'job_id': 'j1', 'status': 'ended', 'samples': 100})   # would replace it)
    with pytest.raises(OutputError, match='exists already'):
        jobs.close(rec)
    assert sorted(os.listdir(tmp_path)) == ['j1'] and os.listdir(tmp_path / 'j1') == []


@pytest.mark.parametrize('job_id', ['../x', 'a/b', '.hidden', '', 'x' * 65, 'sp ace', '..'])
def test_bad_job_ids_are_refused_and_nothing_is_created(tmp_path, job_id):
    jobs = JobRecorder(tmp_path / 'out', new_sink=_new_sink, clock=Clock())
    with pytest.raises(OutputError, match='job_id'):
        jobs.recording(job_id)
    assert os.listdir(tmp_path / 'out') == [] and sorted(os.listdir(tmp_path)) == ['out']


def test_the_root_must_be_a_directory_and_not_a_link(tmp_path):
    (tmp_path / 'real').mkdir()
    (tmp_path / 'link').symlink_to(tmp_path / 'real')
    (tmp_path / 'file').write_text('x')
    with pytest.raises(OutputError, match='symbolic link'):
        JobRecorder(tmp_path / 'link', new_sink=_new_sink)
    with pytest.raises(OutputError, match='not a directory'):
        JobRecorder(tmp_path / 'file', new_sink=_new_sink)


def test_a_writer_error_leaves_nothing(tmp_path):
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=Clock())
    rec = jobs.recording('j1')
    _stream(rec, 1)
    jobs.discard(rec, OSError(28, 'No space left on device'))
    assert os.listdir(tmp_path) == []
    assert jobs.recording('j1') is None        # its later messages are not recorded

    def broken(path):
        raise OSError(13, 'Permission denied')
    jobs = JobRecorder(tmp_path, new_sink=broken, clock=Clock())
    with pytest.raises(OSError):
        jobs.recording('j2')
    assert os.listdir(tmp_path) == []


def test_the_temporary_of_a_killed_recorder_is_removed_at_the_next_start(tmp_path):
    dead = subprocess.run([sys.executable, '-c', 'import os; print(os.getpid())'],
                          capture_output=True, text=True, check=True)
    stale = tmp_path / f'.j1.tmp-{int(dead.stdout)}'
    (stale / 'j1').mkdir(parents=True)
    alive = tmp_path / f'.j9.tmp-{os.getppid()}'     # a running process's: left alone
    alive.mkdir()
    JobRecorder(tmp_path, new_sink=_new_sink)
    assert not stale.exists() and alive.exists()


def test_open_recordings_are_bounded(tmp_path):
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=Clock(), max_open=2)
    for job_id in ('a', 'b', 'c'):
        jobs.recording(job_id)
    assert list(jobs.open) == ['b', 'c']
    mark = bagio.read_custom_data(tmp_path / 'a', JOB_KEY)
    assert mark['status'] == 'interrupted' and 'closed early' in mark['message']


def test_read_back_finds_a_damaged_or_miscounted_bag(tmp_path):
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=Clock())
    rec = jobs.recording('j1')
    _stream(rec, 3)
    jobs.note_result({'job_id': 'j1', 'status': 'ended', 'samples': 300})
    path = jobs.close(rec)
    counts = dict(rec.sink.bag.counts)
    assert read_back(path, counts) == []
    assert read_back(path, {**counts, '/power': 4}) == ['/power: 3 messages listed, 4 written']
    last = sorted(path.glob('*.mcap'))[-1]
    last.write_bytes(last.read_bytes()[:-20])          # the footer cut off
    assert len(read_back(path, counts)) == 1            # that file, named in the message
    (path / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    assert read_back(path, counts)[0].startswith('metadata.yaml')


def test_a_result_taken_before_the_job_was_opened_is_kept(tmp_path):
    clock = Clock()
    jobs = JobRecorder(tmp_path, new_sink=_new_sink, clock=clock)
    jobs.note_result({'job_id': 'j1', 'status': 'ended', 'samples': 200})   # DDS: any order
    assert jobs.open == {} and os.listdir(tmp_path) == []
    rec = jobs.recording('j1')
    _stream(rec, 2)
    assert jobs.due() == [rec]
    assert bagio.read_custom_data(jobs.close(rec), JOB_KEY)['status'] == 'ended'
