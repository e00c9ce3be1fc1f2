"""One recording per job over loopback DDS: ``launch --program-root DIR --record OUT``.

Four jobs in one graph (one aborted) and one that fails while planning, each recorded to
``OUT/<job_id>/``, complete (the failed one empty), marked with its status, readable by the
tools that read a one-program recording, its ``/power`` totals equal to the job's result
(and, for a finished job, to offline ``simulate``); a job id whose recording exists is
refused and the existing directory is left alone.
"""
import json
import os
from pathlib import Path
import subprocess
import sys
import time

from mcap.reader import make_reader
import must_run
import pytest
import yaml

must_run.import_or_skip('rclpy', 'rclpy')
from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402

from feed_axis_energy.graph import JOB_KEY, recording_gaps  # noqa: E402
from feed_axis_energy.record import bagio, TOPIC_PLOT_POWER  # noqa: E402
from feed_axis_energy.record.plotread import read_plot_topic  # noqa: E402

PY = sys.executable
SHORT = 'G21 G90 G94 G61\nG0 X0\nG1 X100 F3000\nG4 P0.2\nG1 X80 F3000\n'
XYZ = 'G21 G90 G94 G61\nG1 X120 Y40 Z-20 F6000\nG4 P0.1\nG1 X0 Y0 Z0 F9000\n'
LONG = 'G21 G90 G94 G61\n' + 'G1 X100 F3000\nG1 X0 F3000\n' * 15
BAD = 'G21 G90 G94\nG1 X10 F3000\nG1 X@5\n'


class _Client:
    """Commands, replies, results and the setpoints of each job, over DDS."""

    def __init__(self, context):
        import rclpy
        from std_msgs.msg import String
        from trajectory_msgs.msg import JointTrajectory
        from feed_axis_energy.nodes.qos import command_qos, job_qos, stream_qos
        from feed_axis_energy.nodes.runner import make_executor
        self.String = String
        self.node = rclpy.create_node('record_client', context=context)
        self.ex = make_executor(context=context)
        self.ex.add_node(self.node)
        self.replies, self.results, self.states, self.samples = {}, {}, [], {}
        self.pub = self.node.create_publisher(String, 'job/command', command_qos())
        self.node.create_subscription(String, 'job/reply', lambda m: self.replies.__setitem__(
            json.loads(m.data)['request_id'], json.loads(m.data)), command_qos())
        self.node.create_subscription(String, 'job/result', lambda m: self.results.__setitem__(
            json.loads(m.data)['job_id'], json.loads(m.data)), job_qos())
        self.node.create_subscription(String, 'job/state', lambda m: self.states.append(
            json.loads(m.data)), job_qos())
        self.node.create_subscription(JointTrajectory, 'setpoints', self._on_setpoints,
                                      stream_qos(), raw=True)

    def _on_setpoints(self, data):
        from feed_axis_energy.graph import header_frame_id
        from feed_axis_energy.nodes import convert
        job = header_frame_id(data)
        self.samples[job] = self.samples.get(job, 0) + convert.decode_trajectory(
            data).t_ns.shape[0]

    def spin_until(self, cond, timeout_s, what):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if cond():
                return
            self.ex.spin_once(timeout_sec=0.05)
        raise AssertionError(f'timed out waiting for {what}; states {self.states[-3:]}')

    def command(self, request_id, **body):
        self.spin_until(lambda: self.pub.get_subscription_count() >= 1
                        and self.node.count_publishers('job/reply') >= 1, 30, 'the graph')
        self.pub.publish(self.String(data=json.dumps({'request_id': request_id, **body})))
        self.spin_until(lambda: request_id in self.replies, 30, f'reply {request_id}')
        return self.replies[request_id]

    def result(self, job_id, timeout_s=60):
        self.spin_until(lambda: job_id in self.results, timeout_s, f'result of {job_id}')
        return self.results[job_id]

    def close(self):
        self.ex.shutdown()
        self.node.destroy_node()


def _offline(program, env, *args):
    # --method samples: the graph integrates the samples it streams, as this does (the
    # default summary by phase differs from them by their discretization error)
    out = subprocess.run([PY, '-m', 'feed_axis_energy', 'simulate', str(program), '--json',
                          '--method', 'samples', *args], env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def _mcap_counts(path):
    """Messages per topic through the mcap library, file by file as the metadata lists."""
    meta = yaml.safe_load((Path(path) / 'metadata.yaml').read_text())
    counts = {}
    for name in meta['rosbag2_bagfile_information']['relative_file_paths']:
        with open(Path(path) / name, 'rb') as fh:
            for _, channel, _ in make_reader(fh).iter_messages():
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def _wait_for_file(path, timeout_s=30):
    end = time.monotonic() + timeout_s
    while not path.exists():
        assert time.monotonic() < end, f'{path} did not appear'
        time.sleep(0.05)


@child_only
def test_jobs_one_aborted_one_failed_each_recorded(tmp_path, node_env, domain_id, context):
    from feed_axis_energy.paths import config_dir
    root = tmp_path / 'programs'
    root.mkdir()
    for name, text in (('short.nc', SHORT), ('xyz.nc', XYZ), ('long.nc', LONG),
                       ('bad.nc', BAD)):
        (root / name).write_text(text)
    out = tmp_path / 'rec'
    (out / 'taken').mkdir(parents=True)           # an earlier recording: never overwritten
    (out / 'taken' / 'note.txt').write_text('earlier')
    launcher = subprocess.Popen(
        [PY, '-m', 'feed_axis_energy', 'launch', '--program-root', str(root), '--machine-root',
         str(config_dir()), '--record', str(out), '--domain-id', str(domain_id),
         '--timeout', '200'], env=node_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True)
    client = _Client(context)
    try:
        client.spin_until(lambda: client.states and client.states[-1]['state'] == 'idle', 60,
                          'state idle')
        taken = client.command('r0', command='start', job_id='taken', program='short.nc')
        assert not taken['accepted'] and taken['field'] == 'job_id', taken
        assert 'exists already' in taken['message'] and taken['state'] == 'idle'

        assert client.command('r1', command='start', job_id='j1', program='short.nc',
                              load_kg=5.0)['accepted']
        res1 = client.result('j1')
        assert client.command('r2', command='start', job_id='j2', program='xyz.nc',
                              load_kg=20.0, machine='three_axis_mill_drives.yaml')['accepted']
        res2 = client.result('j2')
        assert client.command('r3', command='start', job_id='j3', program='long.nc')['accepted']
        client.spin_until(lambda: client.samples.get('j3', 0) >= 500, 30, 'job 3 streaming')
        assert client.command('r4', command='abort', job_id='j3')['accepted']
        res3 = client.result('j3')
        for job in ('j1', 'j2', 'j3'):        # closed by the recorder once complete
            _wait_for_file(out / job / 'metadata.yaml')
        # a job that fails while planning (a G-code error): recorded empty, marked failed
        assert client.command('r6', command='start', job_id='bad', program='bad.nc')['accepted']
        bad = client.result('bad')
        again = client.command('r5', command='start', job_id='j4', program='short.nc')
        assert again['accepted']              # the graph goes on after the recordings closed
        res4 = client.result('j4')
        _wait_for_file(out / 'j4' / 'metadata.yaml')
        _wait_for_file(out / 'bad' / 'metadata.yaml')
    finally:
        client.close()
        launcher.send_signal(2)
        try:
            log, _ = launcher.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            launcher.kill()
            log, _ = launcher.communicate(timeout=5)
        print(log)
    assert launcher.returncode == 130 and 'Traceback' not in log, log

    # nothing hidden left
    assert sorted(os.listdir(out)) == ['bad', 'j1', 'j2', 'j3', 'j4', 'taken']
    assert bad['status'] == 'failed' and 'bad.nc:3:5' in bad['message'], bad
    mark = bagio.read_custom_data(out / 'bad', JOB_KEY)
    assert mark['status'] == 'failed' and mark['result'] == bad and not mark['complete']
    assert 'bad.nc:3:5' in mark['message']
    assert all(n == 0 for _, n in bagio.bag_topics(out / 'bad').values())
    assert os.listdir(out / 'taken') == ['note.txt']
    assert (out / 'taken' / 'note.txt').read_text() == 'earlier'
    assert (res1['status'], res2['status'], res3['status'], res4['status']) == (
        'ended', 'ended', 'aborted', 'ended')
    for res in (res1, res2, res3, res4):
        bag = out / res['job_id']
        mark = bagio.read_custom_data(bag, JOB_KEY)
        assert mark['job_id'] == res['job_id'] and mark['status'] == res['status']
        assert mark['complete'] and mark['gaps'] == [] and mark['result'] == res
        assert mark['spec']['program_sha256'] == res['program_sha256']
        assert mark['spec']['load_kg'] == res['load_kg']
        # the checks and readers of a one-program recording, unchanged
        assert recording_gaps(bag) == []
        topics = bagio.bag_topics(bag)
        assert {t: n for t, (_, n) in topics.items()} == _mcap_counts(bag)
        assert topics['/program/end'][1] == 1 and topics['/block_energy'][1] == 1
        power = bagio.read_series(bag, bagio.TOPIC_POWER)
        assert power.t.shape[0] == res['samples'] and power.t[0] == 0.0
        totals = dict(zip(power.names, power.positions[-1].tolist()))
        assert totals.keys() == res['energy_j'].keys()
        for name, value in res['energy_j'].items():
            assert totals[name] == pytest.approx(value, rel=1e-12, abs=1e-12), name
        setpoints = bagio.read_series(bag, bagio.TOPIC_SETPOINTS)
        assert setpoints.t.shape[0] == res['samples'] == client.samples[res['job_id']]
        blocks = bagio.read_block_energy(bag)
        assert sum(e for _, e, _ in blocks) == pytest.approx(res['energy_j']['total'],
                                                             rel=1e-9)
        plot = read_plot_topic(bag, TOPIC_PLOT_POWER)
        # the display-rate samples are samples of /power, as in a one-program recording
        at = {int(t): i for i, t in enumerate(power.stamps_ns())}
        rows = [at[int(t)] for t in plot.t_ns]
        assert rows[0] == 0 and len(rows) > 10
        assert plot.position.tolist() == power.positions[rows].tolist()
    assert 500 <= res3['samples'] < res1['samples'] * 30
    # ... and a finished job's recording equals offline simulate of the same program
    ref = _offline(root / 'xyz.nc', node_env, '--load-kg', '20', '--machine',
                   str(config_dir() / 'three_axis_mill_drives.yaml'))
    power = bagio.read_series(out / 'j2', bagio.TOPIC_POWER)
    for name, value in ref['energy_j'].items():
        got = power.positions[-1][list(power.names).index(name)]
        assert got == pytest.approx(value, rel=1e-9, abs=1e-9), name


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The tests above, in their own interpreter (see conftest.run_module_in_child)."""
    run_module_in_child(__file__)
