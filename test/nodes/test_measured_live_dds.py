"""``measured_live`` over loopback DDS: the measured/live contract in, measured/comparison out.

A run without an NC program is streamed as the cell would (``live_motion``): kinematics and
power per axis and stamp, in single and batch messages, with garbage among them; the final
comparison must equal the core's on the same samples, and its keys the documented contract.
"""
import json
import subprocess
import sys
import time

import must_run
import numpy as np

must_run.import_or_skip('rclpy', 'rclpy')
from conftest import child_only, IN_CHILD, ROOT, run_module_in_child  # noqa: E402

T0_NS = 1764280000 * 10 ** 9


def _samples():
    """A smooth 3-axis motion every 100 ms and 1.1 x its predicted X/Y power (no lag)."""
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.measured import predicted_signal
    from feed_axis_energy.measured.motiondata import reconstruct_motion
    from feed_axis_energy.sim import simulate_motion
    machine = load_machine(ROOT / 'config' / 'umich_mill.yaml')
    t = 0.1 * np.arange(300)
    rng = np.random.default_rng(5)
    w = rng.uniform(0.5, 2.0, size=3)
    amp = np.array([0.02, 0.015, 0.01])
    pos = amp * np.sin(w * t[:, None])
    vel = amp * w * np.cos(w * t[:, None])
    acc = -amp * w * w * np.sin(w * t[:, None])
    sim = simulate_motion(reconstruct_motion(t, pos, axes=('X', 'Y', 'Z'), rate_hz=1000.0,
                                             vel=vel, acc=acc), machine, load_kg=0.0)
    p = predicted_signal('shaft', sim, machine, ('X', 'Y'))
    power = 1.1 * np.column_stack([np.interp(t, sim.power.t, p[:, j]) for j in range(2)])
    out = []
    for i in range(t.size):
        stamp = (T0_NS + int(round(t[i] * 1e9))) / 1e9
        row = []
        for j, axis in enumerate('XYZ'):
            row += [(axis, 'position_m', pos[i, j]), (axis, 'velocity_m_s', vel[i, j]),
                    (axis, 'acceleration_m_s2', acc[i, j])]
        row += [('X', 'power_w', power[i, 0]), ('Y', 'power_w', power[i, 1])]
        out.append([{'axis': a, 'stamp': stamp, 'quantity': q, 'value': float(v)}
                    for a, q, v in row])
    return out


@child_only
def test_live_motion_comparison_over_dds(node_env, domain_id, context):
    import rclpy
    from std_msgs.msg import String
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.measured import (COMPARISON_KEYS, LiveMonitor, LiveMotionPredictor,
                                           parse_live)
    from feed_axis_energy.measured.live import ALARM_KEYS
    from feed_axis_energy.nodes.qos import command_qos, latched_qos, measured_live_qos
    from feed_axis_energy.nodes.runner import make_executor
    rows = _samples()
    proc = subprocess.Popen(
        [sys.executable, '-m', 'feed_axis_energy.nodes.measured_live', '--ros-args',
         '-p', 'source:=live_motion', '-p', f'machine:={ROOT / "config" / "umich_mill.yaml"}',
         '-p', 'measured_axes:=X,Y', '-p', 'end_after_s:=2.0', '-p', 'publish_rate_hz:=5.0'],
        env=node_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    node = rclpy.create_node('cell_stream', context=context)
    ex = make_executor(context=context)
    ex.add_node(node)
    got, alarms = [], []
    node.create_subscription(String, 'measured/comparison',
                             lambda m: got.append(json.loads(m.data)), command_qos())
    node.create_subscription(String, 'measured/alarm',
                             lambda m: alarms.append(json.loads(m.data)), latched_qos())
    pub = node.create_publisher(String, 'measured/live', measured_live_qos())

    def spin_until(cond, timeout_s, what):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if cond():
                return
            ex.spin_once(timeout_sec=0.05)
        raise AssertionError(f'timed out waiting for {what}')

    try:
        spin_until(lambda: pub.get_subscription_count() >= 1
                   and node.count_publishers('measured/comparison') >= 1, 60, 'the node')
        time.sleep(0.5)
        messages = []
        for i, row in enumerate(rows):
            if i % 2:
                messages.append(json.dumps({'samples': row}))        # the batch form
            else:
                messages += [json.dumps(s) for s in row]
        messages[10:10] = ['not json', '{"axis": "X", "stamp": 1, "quantity": "power_w"}',
                           json.dumps({'axis': 'Q', 'stamp': 1764280000.0,
                                       'quantity': 'power_w', 'value': 1.0})]
        for text in messages:
            # paced as a cell streams (~500 messages/s): a reliable keep-last writer
            # overwrites what its reader has not taken once it is 1000 messages ahead
            pub.publish(String(data=text))
            time.sleep(0.002)
        spin_until(lambda: any(d['final'] for d in got), 60, 'the final comparison')
    finally:
        proc.terminate()
        out = proc.communicate(timeout=30)[0]
        ex.shutdown()
        node.destroy_node()
    finals = [d for d in got if d['final']]
    assert len(finals) == 1, [d['counters'] for d in finals]
    final = finals[0]
    assert tuple(final) == COMPARISON_KEYS, out
    assert final['counters']['samples'] == sum(len(r) for r in rows) + 1, final['counters']
    # the core on the same samples gives the same figures
    machine = load_machine(ROOT / 'config' / 'umich_mill.yaml')
    monitor = LiveMonitor(('X', 'Y'), source='live_motion', predictor=LiveMotionPredictor(
        machine, axes=('X', 'Y', 'Z'), measured_axes=('X', 'Y')))
    for text in messages:
        for sample in parse_live(text)[0]:
            monitor.add_sample(*sample)
    core = monitor.finish()
    for key in ('measured_energy_j', 'predicted_energy_j', 'energy_error_pct'):
        for axis in ('X', 'Y', 'total'):
            assert abs(final[key][axis] - core[key][axis]) <= 1e-9 * abs(core[key][axis])
    assert abs(final['energy_error_pct']['total'] - 100.0 * (1 / 1.1 - 1)) < 0.5
    counters = final['counters']
    assert counters['measured']['rows'] == len(rows)
    assert counters['rejected'] == {'bad_json': 1, 'bad_sample': 1}
    assert counters['unknown_axis'] == 1
    assert final['alarm']['count'] == 0 and alarms == [] or set(alarms[0]) == set(ALARM_KEYS)
    assert 'comparison final' in out


def _torque_rows():
    """The motion of :func:`_samples` and 1.1 x its predicted X/Y motor torque [N·m]."""
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.measured import predicted_signal
    from feed_axis_energy.measured.motiondata import reconstruct_motion
    from feed_axis_energy.sim import simulate_motion
    machine = load_machine(ROOT / 'config' / 'umich_mill.yaml')
    t = 0.1 * np.arange(250)
    w = np.array([1.1, 0.7, 1.6])
    amp = np.array([0.02, 0.015, 0.01])
    pos = amp * np.sin(w * t[:, None])
    vel = amp * w * np.cos(w * t[:, None])
    acc = -amp * w * w * np.sin(w * t[:, None])
    sim = simulate_motion(reconstruct_motion(t, pos, axes=('X', 'Y', 'Z'), rate_hz=1000.0,
                                             vel=vel, acc=acc), machine, load_kg=0.0)
    q = predicted_signal('torque', sim, machine, ('X', 'Y'), gains=(1.0, 1.0))
    torque = 1.1 * np.column_stack([np.interp(t, sim.power.t, q[:, j]) for j in range(2)])
    out = []
    for i in range(t.size):
        stamp = (T0_NS + int(round(t[i] * 1e9))) / 1e9
        row = [{'axis': a, 'stamp': stamp, 'quantity': qn, 'value': float(v[i, j])}
               for j, a in enumerate('XYZ')
               for qn, v in (('position_m', pos), ('velocity_m_s', vel),
                             ('acceleration_m_s2', acc))]
        row += [{'axis': a, 'stamp': stamp, 'quantity': 'torque_nm',
                 'value': float(torque[i, j])} for j, a in enumerate('XY')]
        out.append({'samples': row})
    # a power sample that names no quantity: power_w by default, unused by a torque comparison
    out[5]['samples'].append({'axis': 'X', 'stamp': out[5]['samples'][0]['stamp'],
                              'value': 12.5})
    return out


@child_only
def test_torque_comparison_over_dds(node_env, domain_id, context):
    """measures:=torque: the drive trace compared in N·m and as M·omega [W], as the core."""
    import rclpy
    from std_msgs.msg import String
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.measured import (COMPARISON_KEYS, LiveMonitor, LiveMotionPredictor,
                                           parse_live)
    from feed_axis_energy.nodes.qos import command_qos, measured_live_qos
    from feed_axis_energy.nodes.runner import make_executor
    batches = [json.dumps(b) for b in _torque_rows()]
    proc = subprocess.Popen(
        [sys.executable, '-m', 'feed_axis_energy.nodes.measured_live', '--ros-args',
         '-p', 'source:=live_motion', '-p', f'machine:={ROOT / "config" / "umich_mill.yaml"}',
         '-p', 'measured_axes:=X,Y', '-p', 'measures:=torque', '-p', 'end_after_s:=2.0',
         '-p', 'publish_rate_hz:=5.0'],
        env=node_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    node = rclpy.create_node('cell_torque', context=context)
    ex = make_executor(context=context)
    ex.add_node(node)
    got = []
    node.create_subscription(String, 'measured/comparison',
                             lambda m: got.append(json.loads(m.data)), command_qos())
    pub = node.create_publisher(String, 'measured/live', measured_live_qos())

    def spin_until(cond, timeout_s, what):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if cond():
                return
            ex.spin_once(timeout_sec=0.05)
        raise AssertionError(f'timed out waiting for {what}')

    try:
        spin_until(lambda: pub.get_subscription_count() >= 1
                   and node.count_publishers('measured/comparison') >= 1, 60, 'the node')
        time.sleep(0.5)
        for text in batches:
            pub.publish(String(data=text))
            time.sleep(0.01)
        spin_until(lambda: any(d['final'] for d in got), 60, 'the final comparison')
    finally:
        proc.terminate()
        out = proc.communicate(timeout=30)[0]
        ex.shutdown()
        node.destroy_node()
    final = [d for d in got if d['final']][0]
    assert tuple(final) == COMPARISON_KEYS, out
    assert final['measures'] == 'torque'
    assert final['signal']['quantity'] == 'torque' and final['signal']['unit'] == 'N·m'
    assert final['counters']['unused_quantity'] == 1        # the power sample
    machine = load_machine(ROOT / 'config' / 'umich_mill.yaml')
    monitor = LiveMonitor(('X', 'Y'), source='live_motion', predictor=LiveMotionPredictor(
        machine, axes=('X', 'Y', 'Z'), measured_axes=('X', 'Y'), measures='torque'))
    for text in batches:
        for sample in parse_live(text)[0]:
            monitor.add_sample(*sample)
    core = monitor.finish()
    for key in ('measured_energy_j', 'predicted_energy_j', 'energy_error_pct'):
        for axis in ('X', 'Y', 'total'):
            assert abs(final[key][axis] - core[key][axis]) <= 1e-9 * abs(core[key][axis])
    for axis in ('X', 'Y'):
        assert abs(final['signal']['residual_rms'][axis]
                   - core['signal']['residual_rms'][axis]) <= 1e-9 * core['signal'][
                       'residual_rms'][axis]
    assert abs(final['energy_error_pct']['total'] - 100.0 * (1 / 1.1 - 1)) < 0.5


def test_in_a_child_process():
    if IN_CHILD:
        return
    run_module_in_child(__file__)
