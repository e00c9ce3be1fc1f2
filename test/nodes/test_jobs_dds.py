"""Jobs in one running graph over loopback DDS: two jobs in a row, a refused second start,
an abort; each result against offline ``simulate --json`` of the same program."""
import json
import subprocess
import sys
import time

import must_run
import pytest

must_run.import_or_skip('rclpy', 'rclpy')
from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402

PY = sys.executable
SHORT = 'G21 G90 G94 G61\nG0 X0\nG1 X100 F3000\nG4 P0.2\nG1 X80 F3000\n'
XYZ = 'G21 G90 G94 G61\nG1 X120 Y40 Z-20 F6000\nG4 P0.1\nG1 X0 Y0 Z0 F9000\n'
LONG = 'G21 G90 G94 G61\n' + 'G1 X100 F3000\nG1 X0 F3000\n' * 15


def _offline(program, env, *args):
    # --method samples: the graph integrates the samples it streams, as this does (the
    # default summary by phase differs from them by their discretization error)
    out = subprocess.run([PY, '-m', 'feed_axis_energy', 'simulate', str(program), '--json',
                          '--method', 'samples', *args], env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


class _Client:
    """A cell controller on the ROS interface: commands, replies, state, results."""

    def __init__(self, context):
        from std_msgs.msg import String
        from trajectory_msgs.msg import JointTrajectory
        from feed_axis_energy.nodes.qos import command_qos, job_qos, stream_qos
        from feed_axis_energy.nodes.runner import make_executor
        import rclpy
        self.String = String
        self.node = rclpy.create_node('cell_client', context=context)
        self.ex = make_executor(context=context)
        self.ex.add_node(self.node)
        self.replies, self.states, self.results, self.frames = {}, [], {}, []
        self.pub = self.node.create_publisher(String, 'job/command', command_qos())
        self.node.create_subscription(String, 'job/reply', self._on_reply, command_qos())
        self.node.create_subscription(String, 'job/state',
                                      lambda m: self.states.append(json.loads(m.data)),
                                      job_qos())
        self.node.create_subscription(String, 'job/result', self._on_result, job_qos())
        self.node.create_subscription(JointTrajectory, 'setpoints', self._on_setpoints,
                                      stream_qos(), raw=True)
        self.live_sub = self.node.create_subscription(String, 'job/live', self._on_live,
                                                      command_qos())
        self.setpoint_samples = {}
        self.live = {}

    def wait_for_live(self):
        """Until the estimator's job/live writer is matched (seen from here, then 0.5 s for
        the other direction of discovery)."""
        self.spin_until(lambda: self.live_sub.get_publisher_count() > 0, 30,
                        'job/live publisher matched')
        settle = time.monotonic() + 0.5
        self.spin_until(lambda: time.monotonic() > settle, 5, 'settle')

    def _on_live(self, msg):
        d = json.loads(msg.data)
        self.live.setdefault(d['job_id'], []).append(d)

    def _on_reply(self, msg):
        d = json.loads(msg.data)
        self.replies[d['request_id']] = d

    def _on_result(self, msg):
        d = json.loads(msg.data)
        self.results[d['job_id']] = d

    def _on_setpoints(self, data):
        from feed_axis_energy.graph import header_frame_id
        from feed_axis_energy.nodes import convert
        job = header_frame_id(data)
        n = convert.decode_trajectory(data).t_ns.shape[0]
        self.setpoint_samples[job] = self.setpoint_samples.get(job, 0) + n

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


@child_only
def test_two_jobs_a_refused_start_and_an_abort_in_one_graph_launch(tmp_path, node_env,
                                                                   domain_id, context):
    root = tmp_path / 'programs'
    root.mkdir()
    (root / 'short.nc').write_text(SHORT)
    (root / 'xyz.nc').write_text(XYZ)
    (root / 'long.nc').write_text(LONG)
    (tmp_path / 'secret.nc').write_text(SHORT)
    # one graph launch for all jobs: the launcher's job mode
    launcher = subprocess.Popen(
        [PY, '-m', 'feed_axis_energy', 'launch', '--program-root', str(root),
         '--machine-root', str(_shipped('.')), '--domain-id', str(domain_id),
         '--timeout', '200'], env=node_env, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True)
    procs = [launcher]
    client = _Client(context)
    try:
        client.spin_until(lambda: client.states and client.states[-1]['state'] == 'idle', 30,
                          'state idle')
        # a hostile request is refused with the field and the reason; nothing starts
        bad = client.command('r0', command='start', job_id='j0', program='../secret.nc')
        assert not bad['accepted'] and bad['field'] == 'program' and '".."' in bad['message']
        assert bad['state'] == 'idle'

        # text that is not a command is answered (request_id '') and changes nothing
        client.pub.publish(client.String(data='{"command": "start", "load_kg": NaN'))
        client.spin_until(lambda: '' in client.replies, 30, 'reply to garbage')
        assert not client.replies['']['accepted'] and client.replies['']['field'] == 'request'
        nan = client.command('rn', command='start', job_id='jn', program='short.nc',
                             load_kg=1e30)
        assert not nan['accepted'] and nan['field'] == 'load_kg', nan

        # job/live is volatile and sent only while someone is subscribed: the estimator
        # must have matched this client before job 1 (discovery is per pair of nodes; the
        # job/state writer above is another node), else a 0.1 s job passes unseen
        client.wait_for_live()
        # job 1: the default machine, 5 kg
        r1 = client.command('r1', command='start', job_id='j1', program='short.nc',
                            load_kg=5.0)
        assert r1['accepted'] and r1['job_id'] == 'j1', r1
        res1 = client.result('j1')
        # job 2 in the same graph: another program, a machine preset with drives, 20 kg
        r2 = client.command('r2', command='start', job_id='j2', program='xyz.nc',
                            load_kg=20.0, machine='three_axis_mill_drives.yaml')
        assert r2['accepted'], r2
        res2 = client.result('j2')

        # job 3: aborted while it streams; a second start meanwhile is refused
        r3 = client.command('r3', command='start', job_id='j3', program='long.nc')
        assert r3['accepted'], r3
        client.spin_until(lambda: client.setpoint_samples.get('j3', 0) >= 500, 30,
                          'job 3 streaming')
        again = client.command('r4', command='start', job_id='j4', program='short.nc')
        assert not again['accepted'] and again['field'] == 'state', again
        assert "job 'j3' is running" in again['message'] and again['state'] == 'running'
        ab = client.command('r5', command='abort', job_id='j3')
        assert ab['accepted'], ab
        res3 = client.result('j3')
        by_id = client.command('r6', command='result', job_id='j1')
        assert by_id['accepted'] and by_id['result'] == res1
        unknown = client.command('r7', command='result', job_id='nope')
        assert not unknown['accepted'] and 'no result' in unknown['message']
        client.spin_until(lambda: client.states[-1]['state'] == 'aborted', 10, 'aborted')
    finally:
        client.close()
        for proc in procs:
            proc.send_signal(2)
        outs = []
        for proc in procs:
            try:
                out, _ = proc.communicate(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                out, _ = proc.communicate(timeout=5)
            outs.append(out)
            print(f'--- launch (exit {proc.returncode}) ---\n{out or ""}')
    for out in outs:
        assert 'Traceback' not in out, out
    assert launcher.returncode == 130, outs[0]        # stopped by SIGINT, as documented
    assert 'stopped by SIGINT; all nodes shut down' in outs[0]
    assert outs[0].count('[energy_estimator]') >= 3   # the same estimator for every job

    states = [(s['job_id'], s['state']) for s in client.states]
    for job, final in (('j1', 'ended'), ('j2', 'ended'), ('j3', 'aborted')):
        seq = [st for j, st in states if j == job]
        assert seq[-3:] == ['planning', 'running', final], (job, states)

    # results against offline simulate --json of the same program
    ref1 = _offline(root / 'short.nc', node_env, '--load-kg', '5')
    ref2 = _offline(root / 'xyz.nc', node_env, '--load-kg', '20', '--machine',
                    str(_shipped('three_axis_mill_drives.yaml')))
    for res, ref in ((res1, ref1), (res2, ref2)):
        assert res['status'] == 'ended' and res['lost_samples'] == 0, res
        assert res['samples'] == ref['samples']
        assert res['energy_j'].keys() == ref['energy_j'].keys()
        for axis, value in ref['energy_j'].items():
            assert res['energy_j'][axis] == pytest.approx(value, rel=1e-9, abs=1e-9), axis
        for axis, value in ref['peak_power_w'].items():
            assert res['peak_power_w'][axis] == pytest.approx(value, rel=1e-9, abs=1e-9)
        assert res['braking_returned_j'] == pytest.approx(ref['regenerated_energy_j'],
                                                          rel=1e-9, abs=1e-9)
        # the graph's sample times are integer ns on the wire: 1 ns of rounding
        assert res['duration_s'] == pytest.approx(ref['duration_s'], rel=0, abs=1e-9)
        print(f"{res['job_id']}: energy_j.total graph {res['energy_j']['total']!r} offline "
              f"{ref['energy_j']['total']!r} relative difference "
              f"{abs(res['energy_j']['total'] / ref['energy_j']['total'] - 1):.2e}")
        assert len(res['program_sha256']) == 64
    assert res1['load_kg'] == 5.0 and res1['electrical'] is None
    assert res2['machine'].endswith('three_axis_mill_drives.yaml')
    for key in ('motor_energy_j', 'supply_energy_j'):
        for name, value in ref2['electrical'][key].items():
            assert res2['electrical'][key][name] == pytest.approx(value, rel=1e-9, abs=1e-9)
    assert res2['electrical']['returned_j'] == pytest.approx(
        ref2['electrical']['returned_j'], rel=1e-9, abs=1e-9)

    # the live stream: simulation-time stamps in fast mode; its last message per job holds
    # the result's energies (the electrical side included where the machine has drives)
    for res in (res1, res2, res3):
        live = client.live[res['job_id']]
        assert all(m['clock'] == 'simulation' for m in live)
        assert [m['samples'] for m in live] == sorted(m['samples'] for m in live)
        assert live[-1]['samples'] == res['samples']
        assert live[-1]['energy_j'] == res['energy_j']
        assert live[-1]['stamp_ns'] == round(live[-1]['time_s'] * 1e9)
    assert client.live['j1'][-1]['electrical'] is None
    last2 = client.live['j2'][-1]['electrical']
    assert last2['supply_energy_j'] == res2['electrical']['supply_energy_j']
    assert set(last2['motor_w']) == {'X', 'Y', 'Z', 'total'}

    # the abort: the stream stopped where the abort found it, nothing lost, nothing after
    assert res3['status'] == 'aborted' and res3['lost_samples'] == 0, res3
    full = _offline(root / 'long.nc', node_env)
    assert 500 <= res3['samples'] < full['samples']
    assert res3['samples'] == client.setpoint_samples['j3']
    assert f"after {res3['samples']} of" in res3['message']
    assert 0 < res3['energy_j']['total'] < full['energy_j']['total']
    assert 'j4' not in client.setpoint_samples and 'j0' not in client.setpoint_samples


@child_only
def test_live_stream_is_stamped_in_wall_clock_time_in_realtime_mode(tmp_path, node_env,
                                                                    domain_id, context):
    root = tmp_path / 'programs'
    root.mkdir()
    (root / 'xyz.nc').write_text(XYZ)
    launcher = subprocess.Popen(
        [PY, '-m', 'feed_axis_energy', 'launch', '--program-root', str(root),
         '--machine', str(_shipped('three_axis_mill_drives.yaml')), '--mode', 'realtime',
         '--domain-id', str(domain_id), '--timeout', '120'], env=node_env,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    client = _Client(context)
    try:
        client.wait_for_live()
        r = client.command('r1', command='start', job_id='rt1', program='xyz.nc', load_kg=3)
        assert r['accepted'], r
        t_start_ns = time.time_ns()
        res = client.result('rt1', timeout_s=60)
        t_end_ns = time.time_ns()
    finally:
        client.close()
        launcher.send_signal(2)
        out, _ = launcher.communicate(timeout=20)
        print(out)
    assert res['status'] == 'ended' and res['lost_samples'] == 0, res
    live = client.live['rt1']
    assert all(m['clock'] == 'wall' for m in live) and len(live) >= 20
    stamps = [m['stamp_ns'] for m in live]
    # wall-clock stamps within the run (not 1970), spaced as the samples are
    assert t_start_ns - 1e9 < stamps[0] and stamps[-1] < t_end_ns + 1e9
    spacing = [b - a for a, b in zip(stamps, stamps[1:])]
    sim = [round((b['time_s'] - a['time_s']) * 1e9) for a, b in zip(live, live[1:])]
    assert max(abs(x - y) for x, y in zip(spacing, sim)) <= 1
    assert live[-1]['electrical']['supply_energy_j'] == res['electrical']['supply_energy_j']
    # real time: the job took about as long as its program
    assert (t_end_ns - t_start_ns) / 1e9 > 0.9 * res['duration_s']


def _shipped(name):
    from feed_axis_energy.paths import config_dir
    return config_dir() / name


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The tests above, in their own interpreter (see conftest.run_module_in_child)."""
    run_module_in_child(__file__)
