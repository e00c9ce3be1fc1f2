"""``measured_live`` in a job graph (``launch --program-root --mode realtime --measured-live``):
a cell client echoes each ``job/live`` prediction back as measured data, 1.1 times the
predicted power, on ``measured/live``; the job's final comparison names the job and shows the
-9.1 % error (1 / 1.1 - 1), with the rows echoed (those of the job's last moments too: the
comparison is final ``final_after_s`` after the job ends)."""
import json
import subprocess
import sys
import time

import must_run

must_run.import_or_skip('rclpy', 'rclpy')
from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402

PROGRAM = 'G21 G90 G94 G61\nG0 X0\n' + 'G1 X100 F3000\nG1 X0 F6000\n' * 2


@child_only
def test_job_comparison_over_dds(tmp_path, node_env, domain_id, context):
    import rclpy
    from std_msgs.msg import String
    from feed_axis_energy.nodes.qos import command_qos, job_qos, measured_live_qos
    from feed_axis_energy.nodes.runner import make_executor
    root = tmp_path / 'programs'
    root.mkdir()
    (root / 'p.nc').write_text(PROGRAM)
    launcher = subprocess.Popen(
        [sys.executable, '-m', 'feed_axis_energy', 'launch', '--program-root', str(root),
         '--mode', 'realtime', '--measured-live', '--domain-id', str(domain_id),
         '--timeout', '200'], env=node_env, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True)
    node = rclpy.create_node('cell_client', context=context)
    ex = make_executor(context=context)
    ex.add_node(node)
    states, replies, comparisons, echoed = [], {}, [], [0]
    measured = node.create_publisher(String, 'measured/live', measured_live_qos())

    def on_live(msg):
        d = json.loads(msg.data)
        samples = [{'axis': a, 'stamp': d['stamp_ns'] / 1e9, 'quantity': 'power_w',
                    'value': 1.1 * p} for a, p in d['power_w'].items() if a != 'total']
        measured.publish(String(data=json.dumps({'samples': samples})))
        echoed[0] += 1

    node.create_subscription(String, 'job/live', on_live, command_qos())
    node.create_subscription(String, 'job/state', lambda m: states.append(json.loads(m.data)),
                             job_qos())
    node.create_subscription(String, 'job/reply',
                             lambda m: replies.update({json.loads(m.data)['request_id']:
                                                       json.loads(m.data)}), command_qos())
    node.create_subscription(String, 'measured/comparison',
                             lambda m: comparisons.append(json.loads(m.data)), command_qos())
    command = node.create_publisher(String, 'job/command', command_qos())

    def spin_until(cond, timeout_s, what):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if cond():
                return
            ex.spin_once(timeout_sec=0.05)
        raise AssertionError(f'timed out waiting for {what}; states {states[-3:]}')

    try:
        spin_until(lambda: states and states[-1]['state'] == 'idle', 60, 'state idle')
        spin_until(lambda: node.count_publishers('job/live') >= 1
                   and measured.get_subscription_count() >= 1
                   and node.count_publishers('measured/comparison') >= 1
                   and command.get_subscription_count() >= 1, 60, 'the graph')
        settle = time.monotonic() + 1.0
        spin_until(lambda: time.monotonic() > settle, 5, 'settle')
        command.publish(String(data=json.dumps({'command': 'start', 'request_id': 'r1',
                                                'job_id': 'j1', 'program': 'p.nc'})))
        spin_until(lambda: 'r1' in replies, 30, 'reply')
        assert replies['r1']['accepted'], replies['r1']
        spin_until(lambda: any(c['final'] and c['job_id'] == 'j1' for c in comparisons), 90,
                   'the final comparison of j1')
    finally:
        ex.shutdown()
        node.destroy_node()
        launcher.send_signal(2)
        try:
            out = launcher.communicate(timeout=20)[0]
        except subprocess.TimeoutExpired:
            launcher.kill()
            out = launcher.communicate(timeout=5)[0]
        print(out)
    assert 'Traceback' not in out
    final = [c for c in comparisons if c['final']][-1]
    assert final['job_id'] == 'j1' and final['source'] == 'job_live'
    assert [s['state'] for s in states if s['job_id'] == 'j1'][-1] == 'ended'
    counters = final['counters']
    assert counters['prediction_clock'] == 0          # real-time mode: wall-clock stamps
    assert counters['measured']['rows'] >= 0.9 * echoed[0] > 0, (counters, echoed)
    assert abs(final['energy_error_pct']['total'] - 100.0 * (1 / 1.1 - 1)) < 1.0, final
    assert 'comparison final' in out


def test_in_a_child_process():
    if IN_CHILD:
        return
    run_module_in_child(__file__)
