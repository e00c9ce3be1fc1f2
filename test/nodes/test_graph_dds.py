"""The node graph over real DDS (loopback), each test in its own ROS domain."""
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import must_run
import numpy as np
import pytest

must_run.import_or_skip('rclpy', 'rclpy')

from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402

from feed_axis_energy import lifeline  # noqa: E402
from feed_axis_energy.record import bagio, StreamBagWriter  # noqa: E402
from feed_axis_energy.physics.energy import energy_by_line  # noqa: E402
from feed_axis_energy.gcode.load import load_gcode  # noqa: E402
from feed_axis_energy.graph.flow import header_stamp_ns, read_raw  # noqa: E402
from feed_axis_energy.graph.end import ProgramEnd  # noqa: E402
from feed_axis_energy.machine.file import load_machine  # noqa: E402
from feed_axis_energy.record.plotread import read_plot_topic  # noqa: E402
from feed_axis_energy.record.plottopics import (TOPIC_PLOT_AXES,  # noqa: E402
                                                TOPIC_PLOT_BLOCK_ENERGY,
                                                TOPIC_PLOT_POWER)
from feed_axis_energy.record.recording import simulation_series  # noqa: E402
from feed_axis_energy.sim.simulate import simulate_program  # noqa: E402
from feed_axis_energy.paths import default_machine  # noqa: E402

PY = sys.executable


def _node(name, params, env, **kw):
    cmd = [PY, '-m', f'feed_axis_energy.nodes.{name}', '--ros-args']
    for k, v in params.items():
        cmd += ['-p', f'{k}:={v}']
    return subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, **kw)


@child_only
def test_launch_recording_equals_offline_simulation(tmp_path, short_program, node_env,
                                                    domain_id):
    bag = tmp_path / 'record.crashsafe'
    out = subprocess.run(
        [PY, '-m', 'feed_axis_energy', 'launch', '--program', str(short_program),
         '--record', str(bag), '--domain-id', str(domain_id), '--load-kg', '5',
         '--timeout', '40'], env=node_env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    assert f'recording: {bag}' in out.stdout
    machine = load_machine(default_machine())
    result = simulate_program(load_gcode(short_program), machine, load_kg=5.0)
    offline = simulation_series(result)
    for topic, ref in offline.items():
        got = bagio.read_series(bag, topic)
        assert got.names == ref.names
        assert got.t.shape == ref.t.shape
        np.testing.assert_allclose(got.t, ref.t, rtol=0, atol=1e-9)
        for field in ('positions', 'velocities', 'accelerations', 'effort'):
            a, b = getattr(ref, field), getattr(got, field)
            assert (a is None) == (b is None), (topic, field)
            if a is not None:
                np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-12)
    power = bagio.read_series(bag, bagio.TOPIC_POWER)
    np.testing.assert_allclose(power.positions[-1, -1], result.power.total_energy_j[-1],
                               rtol=1e-9)
    ref_blocks = energy_by_line(result.power)
    got_blocks = bagio.read_block_energy(bag)
    assert [b[0] for b in got_blocks] == [b[0] for b in ref_blocks]
    np.testing.assert_allclose([b[1] for b in got_blocks], [b[1] for b in ref_blocks],
                               rtol=1e-9, atol=1e-9)
    # the plot topics, read back as a viewer plots them: the simulated power at each
    # stamp, the peaks included (same rule as simulate --out; graph streams standstill at
    # the full rate)
    plot = read_plot_topic(bag, TOPIC_PLOT_POWER)
    t_ref = np.rint(result.power.t * 1e9).astype(np.int64)
    idx = np.searchsorted(t_ref, plot.t_ns)
    np.testing.assert_array_equal(t_ref[idx], plot.t_ns)           # stamps of samples
    simulated = np.column_stack((result.power.power_w, result.power.total_w))
    np.testing.assert_allclose(plot.velocity, simulated[idx], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(plot.velocity.max(axis=0), simulated.max(axis=0), rtol=1e-9)
    np.testing.assert_allclose(plot.velocity.min(axis=0), simulated.min(axis=0), rtol=1e-9,
                               atol=1e-9)
    assert idx.shape[0] < simulated.shape[0] / 5
    axes = read_plot_topic(bag, TOPIC_PLOT_AXES)
    np.testing.assert_allclose(axes.effort.max(axis=0), result.dynamics.torque_nm.max(axis=0),
                               rtol=1e-9)
    blocks = read_plot_topic(bag, TOPIC_PLOT_BLOCK_ENERGY)
    assert [int(n) for n in blocks.names] == [b[0] for b in got_blocks]
    np.testing.assert_array_equal(blocks.position[0], [b[1] for b in got_blocks])


def _measured_bag(path, n=3000, batch=10):
    t = np.arange(n) * 1e-3 + 1.0
    power = bagio.Series(t=t, names=('X', 'total'),
                         positions=np.column_stack((t, t)), velocities=np.ones((n, 2)))
    with StreamBagWriter(path) as w:
        w.write_series(bagio.TOPIC_MEASURED_POWER, power, batch=batch)
    return power


def _collect(domain_id, topic, until_n, timeout_s, started, *, ack_topic=None,
             ack_limit=None, until_exit=False):
    """Subscribe to ``topic``; with ``ack_topic`` acknowledge messages like a consumer.

    With ``ack_limit`` only the first ``ack_limit`` messages are acknowledged (a stuck consumer);
    with ``until_exit`` collection goes on until the started process exits.
    """
    import rclpy
    from rclpy.context import Context
    from std_msgs.msg import Header
    from trajectory_msgs.msg import JointTrajectory
    from feed_axis_energy.graph.flow import header_stamp_ns
    from feed_axis_energy.nodes import convert
    from feed_axis_energy.nodes.qos import stream_qos
    from feed_axis_energy.nodes.runner import make_executor
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    node = rclpy.create_node('collector', context=ctx)
    got = []
    ack = None if ack_topic is None else node.create_publisher(Header, ack_topic, stream_qos())

    def on_message(data):
        got.append((header_stamp_ns(data), time.monotonic(), data))
        if ack is not None and (ack_limit is None or len(got) <= ack_limit):
            ack.publish(convert.stamp_msg(got[-1][0], '/' + topic))
    node.create_subscription(JointTrajectory, topic, on_message, stream_qos(), raw=True)
    ex = make_executor(context=ctx)
    ex.add_node(node)
    proc = started()
    try:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and (
                proc.poll() is None if until_exit else len(got) < until_n):
            ex.spin_once(timeout_sec=0.05)
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    return got, proc


@pytest.mark.parametrize('rate', [0.0, 2.0])
def test_replay_complete_and_in_order(tmp_path, node_env, domain_id, rate):
    from feed_axis_energy.nodes import convert
    n = 3000 if rate == 0 else 1000
    ref = _measured_bag(tmp_path / 'measured', n=n)
    params = {'bag': tmp_path / 'measured', 'rate': rate, 'ack_topic': 'measured/ack',
              'burst': 20}
    t0 = time.monotonic()
    # An acknowledging consumer stays until the replay exits: leaving right after the last
    # message could drop its last acknowledgement, and the replay would rightly keep waiting.
    got, proc = _collect(domain_id, 'measured/power', n // 10, 30, lambda: _node(
        'measured_replay', params, node_env), ack_topic='measured/ack' if rate == 0 else None,
        until_exit=rate == 0)
    try:
        assert proc.wait(timeout=15) == 0
    finally:
        proc.kill()
    stamps = [g[0] for g in got]
    assert len(got) == n // 10
    assert stamps == sorted(stamps)
    t = np.concatenate([convert.cdr_to_series(g[2]).t for g in got])
    np.testing.assert_allclose(t, ref.t, rtol=0, atol=1e-12)
    if rate > 0:   # 1 s of data at twice the speed: about 0.5 s from first to last
        span = got[-1][1] - got[0][1]
        assert 0.4 < span < 1.5
    else:   # paced by acks, not by waits for DDS delivery (that took ~16 s)
        assert time.monotonic() - t0 < 10


def test_fast_replay_waits_for_a_stuck_consumer_then_exits_1(tmp_path, node_env, domain_id):
    _measured_bag(tmp_path / 'measured', n=1000)
    params = {'bag': tmp_path / 'measured', 'rate': 0.0, 'ack_topic': 'measured/ack',
              'burst': 20, 'stall_timeout_s': 1.0}
    got, proc = _collect(domain_id, 'measured/power', 100, 15, lambda: _node(
        'measured_replay', params, node_env), ack_topic='measured/ack', ack_limit=30,
        until_exit=True)
    try:
        out, _ = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert len(got) == 30 + 20   # acknowledged plus one window in flight, nothing more
    assert proc.returncode == 1
    assert 'no acknowledgement on /measured/ack' in out and 'Traceback' not in out


def _replay_into_recorder(tmp_path, node_env, streams, *, burst, extra=None):
    """Replay ``tmp_path/measured`` at full speed into an ``exit_at_end`` recorder."""
    bag = tmp_path / 'rec'
    listed = ', '.join(streams)
    rec = _node('mcap_recorder', {'output': bag, 'topics': f'[{listed}, program/end]',
                                  'end_streams': f'[{listed}]', 'end_extra': '[""]',
                                  'exit_at_end': True, **(extra or {})}, node_env)
    replay = _node('measured_replay', {'bag': tmp_path / 'measured', 'rate': 0.0,
                                       'burst': burst}, node_env)
    try:
        assert replay.wait(timeout=30) == 0, replay.communicate()[0]
        out, _ = rec.communicate(timeout=15)
        assert rec.returncode == 0, out
    finally:
        replay.kill()
        rec.kill()
    return bag


def test_fast_replay_into_recorder_is_lossless(tmp_path, node_env, domain_id):
    """rate 0 paced by the recorder's per-stream acks; a tiny depth-sized burst is enough."""
    ref = _measured_bag(tmp_path / 'measured', n=5000, batch=5)
    bag = _replay_into_recorder(tmp_path, node_env, ['measured/power'], burst=5)
    got = bagio.read_series(bag, bagio.TOPIC_MEASURED_POWER)
    np.testing.assert_array_equal(got.stamps_ns(), ref.stamps_ns())
    np.testing.assert_allclose(got.positions, ref.positions, rtol=0, atol=0)


def test_recorder_start_time_stamps_in_wall_clock_time(tmp_path, node_env, domain_id):
    ref = _measured_bag(tmp_path / 'measured', n=500, batch=10)
    start = 1_795_442_400 * 1_000_000_000               # 2026-11-23T14:00:00Z
    bag = _replay_into_recorder(tmp_path, node_env, ['measured/power'], burst=20,
                                extra={'start_time': '2026-11-23T14:00:00Z'})
    got = bagio.read_raw_messages(bag, [bagio.TOPIC_MEASURED_POWER])
    want = np.rint(ref.t[::10] * 1e9).astype(np.int64) + start
    assert [m[1] for m in got] == want.tolist()                      # log times
    assert [header_stamp_ns(m[2]) for m in got] == want.tolist()     # header stamps
    assert bagio.read_metadata(bag)['starting_time']['nanoseconds_since_epoch'] == want[0]
    # the end marker's stamps (values and header) are in the recording's wall-clock time too
    ((_, log_ns, cdr),) = read_raw(bag, ['/program/end'])
    marker = bagio.typestore().deserialize_cdr(cdr, bagio.DIAGNOSTIC_ARRAY)
    end = ProgramEnd.from_pairs((kv.key, kv.value) for st in marker.status for kv in st.values)
    assert end.first_ns == want[0]
    assert end.last_ns_of('measured/power') == want[-1] == header_stamp_ns(cdr) == log_ns


def test_replay_of_two_topics_into_recorder_exits_at_end(tmp_path, node_env, domain_id):
    """Power ends later than kinematics; the recorder must still see the end of both."""
    n_power, n_kin = 1000, 600
    t = np.arange(n_power) * 1e-3 + 1.0
    power = bagio.Series(t=t, names=('X', 'total'), positions=np.column_stack((t, t)),
                         velocities=np.ones((n_power, 2)))
    tk = t[:n_kin]
    kin = bagio.Series(t=tk, names=('X',), positions=tk[:, None], velocities=np.ones((n_kin, 1)))
    with StreamBagWriter(tmp_path / 'measured') as w:
        w.write_series(bagio.TOPIC_MEASURED_POWER, power, batch=10)
        w.write_series(bagio.TOPIC_MEASURED_KINEMATICS, kin, batch=10)
    bag = _replay_into_recorder(tmp_path, node_env, ['measured/power', 'measured/kinematics'],
                                burst=20)
    for topic, ref in ((bagio.TOPIC_MEASURED_POWER, power),
                       (bagio.TOPIC_MEASURED_KINEMATICS, kin)):
        got = bagio.read_series(bag, topic)
        np.testing.assert_array_equal(got.stamps_ns(), ref.stamps_ns())
        np.testing.assert_allclose(got.positions, ref.positions, rtol=0, atol=0)
    assert bagio.bag_topics(bag)['/program/end'][1] == 1


@child_only
def test_recorder_survives_sigkill(tmp_path, node_env, domain_id):
    import rclpy
    from rclpy.context import Context
    from trajectory_msgs.msg import JointTrajectory
    from feed_axis_energy.nodes import convert
    from feed_axis_energy.nodes.qos import stream_qos
    bag = tmp_path / 'rec'
    rec = _node('mcap_recorder', {'output': bag, 'topics': '[power]', 'chunk_period_s': 0.2},
                node_env, start_new_session=True)
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    node = rclpy.create_node('writer', context=ctx)
    pub = node.create_publisher(JointTrajectory, 'power', stream_qos())
    sent = []
    try:
        deadline = time.monotonic() + 20
        while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.3)
        for i in range(150):   # 1.5 s of 10-sample batches
            s = bagio.Series(t=(i * 10 + np.arange(10)) * 1e-3, names=('X', 'total'),
                             positions=np.ones((10, 2)), velocities=np.ones((10, 2)))
            ((stamp, cdr),) = convert.series_to_cdr(s, batch=10)
            pub.publish(cdr)
            sent.append(stamp)
            time.sleep(0.01)
        time.sleep(0.1)
        os.kill(rec.pid, signal.SIGKILL)
        rec.wait(timeout=5)
    finally:
        rec.kill()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    got = bagio.read_series(bag, bagio.TOPIC_POWER)   # readable without a clean close
    n = got.t.shape[0] // 10
    assert 10 <= n <= len(sent)
    np.testing.assert_array_equal(got.stamps_ns()[::10], sent[:n])


@pytest.mark.parametrize('name,params,expect', [
    ('gcode_trajectory', {'program': '/nonexistent/prog.nc'}, 'prog.nc'),
    ('gcode_trajectory', {'program': 'x.nc', 'mode': 'warp'}, 'mode'),
    ('axis_dynamics', {'load_kg': -1.0}, 'load_kg'),
    ('axis_dynamics', {'load_kg': 'heavy'}, 'load_kg'),
    ('mcap_recorder', {}, 'output'),
    ('mcap_recorder', {'output': '/nonexistent/rec', 'start_time': 'yesterday'}, 'start_time'),
    ('mcap_recorder', {'output': '/nonexistent/rec', 'plot_rate_hz': -1.0}, 'plot_rate_hz'),
])
def test_bad_parameters_exit_nonzero_with_a_clear_line(name, params, expect, node_env):
    proc = _node(name, params, node_env)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 1, out
    assert 'Traceback' not in out
    assert expect in out and 'cannot start' in out


def test_bad_machine_config_exits_nonzero(tmp_path, node_env):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: bad\naxes: {X: {table_mass_kg: -3}}\n')
    proc = _node('energy_estimator', {'machine': bad}, node_env)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 1 and 'Traceback' not in out and 'bad.yaml' in out


def test_launcher_stops_everything_when_a_node_dies(tmp_path, node_env, domain_id):
    prog = tmp_path / 'long.nc'
    prog.write_text('G21 G90 G94 G61\nG0 X0\nG1 X300 F600\n')   # 30 s in real time
    launcher = subprocess.Popen(
        [PY, '-m', 'feed_axis_energy', 'launch', '--program', str(prog), '--mode', 'realtime',
         '--domain-id', str(domain_id), '--timeout', '60'], env=node_env,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 20
        kids = []
        while time.monotonic() < deadline:
            kids = lifeline.child_processes(launcher.pid)
            if len(kids) == 3:
                break
            time.sleep(0.2)
        assert len(kids) == 3
        time.sleep(2.0)
        victim = next(pid for pid, cmd in kids if 'nodes.axis_dynamics' in cmd)
        os.kill(victim, signal.SIGKILL)
        out, _ = launcher.communicate(timeout=20)
    finally:
        launcher.kill()
    assert launcher.returncode == 1
    assert 'axis_dynamics exited with code' in out
    for pid, _ in kids:
        assert not Path(f'/proc/{pid}').exists() or 'Z' in Path(
            f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The tests above that create rclpy contexts in the test process, in their own
    interpreter (see conftest.run_module_in_child: a crash there fails this test, not the
    whole suite)."""
    run_module_in_child(__file__, ('test_launch_recording_equals_offline_simulation',
                                   'test_recorder_survives_sigkill'))
