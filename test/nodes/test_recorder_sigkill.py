"""SIGKILL of mcap_recorder at random moments, fast and real-time publishing.

The bound checked is the one docs/nodes.md states: the bag (read with rosbags and with the
mcap library) holds an unbroken prefix of what was sent; every message the recorder had
acknowledged more than ``chunk_period_s + 0.1 s`` before the kill is in it; and fewer than
``chunk_messages + ack_every`` acknowledged messages are missing.
"""
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import time

import must_run
import numpy as np
import pytest

must_run.import_or_skip('rclpy', 'rclpy')

from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402

from feed_axis_energy.record import bagio  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'record'))
from test_graph_bag import read_mcap, read_rosbags  # noqa: E402

PERIOD_S = 0.5
CHUNK_MESSAGES = 200
ACK_EVERY = 10
SLACK_S = 0.1   # the documented margin on top of chunk_period_s


def _record_and_kill(bag, node_env, domain_id, *, mode, kill_after_s):
    """Publish ``power`` batches to a recorder, SIGKILL it; ``(sent, acks, t_kill)``.

    ``sent`` are the stamps in order, ``acks`` ``(wall time, stamp)`` of every per-stream
    acknowledgement received (the recorder acknowledges only what it has taken).
    """
    import rclpy
    from rclpy.context import Context
    from std_msgs.msg import Header
    from trajectory_msgs.msg import JointTrajectory
    from feed_axis_energy.graph.flow import FlowWindow
    from feed_axis_energy.nodes import convert
    from feed_axis_energy.nodes.qos import stream_qos
    from feed_axis_energy.nodes.runner import make_executor
    rec = subprocess.Popen(
        [sys.executable, '-m', 'feed_axis_energy.nodes.mcap_recorder', '--ros-args',
         '-p', f'output:={bag}', '-p', 'topics:=[power]', '-p', 'end_streams:=[power]',
         '-p', f'chunk_period_s:={PERIOD_S}', '-p', f'chunk_messages:={CHUNK_MESSAGES}',
         '-p', f'ack_every:={ACK_EVERY}'],
        env=node_env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    node = rclpy.create_node('writer', context=ctx)
    acks = []
    flow = FlowWindow(50, ['recorder'])

    def on_ack(msg):
        stamp = convert.time_to_ns(msg.stamp)
        acks.append((time.monotonic(), stamp))
        flow.ack('recorder', stamp)
    node.create_subscription(Header, 'recorder/stream_progress', on_ack, stream_qos())
    pub = node.create_publisher(JointTrajectory, 'power', stream_qos())
    ex = make_executor(context=ctx)
    ex.add_node(node)
    sent = []
    try:
        deadline = time.monotonic() + 30
        while pub.get_subscription_count() < 1 or node.count_publishers(
                '/recorder/stream_progress') < 1:
            assert time.monotonic() < deadline, 'recorder did not come up'
            ex.spin_once(timeout_sec=0.05)
        ex.spin_once(timeout_sec=0.3)
        t0 = time.monotonic()
        i = 0
        while time.monotonic() - t0 < kill_after_s:
            if mode == 'realtime' and time.monotonic() - t0 < i * 0.01:   # 100 batches/s
                ex.spin_once(timeout_sec=0.002)
                continue
            if not flow.can_send():
                ex.spin_once(timeout_sec=0.01)
                continue
            s = bagio.Series(t=(i * 10 + np.arange(10)) * 1e-3 + 1.0, names=('X', 'total'),
                             positions=np.ones((10, 2)), velocities=np.ones((10, 2)))
            ((stamp, cdr),) = convert.series_to_cdr(s, batch=10)
            pub.publish(cdr)
            flow.sent(stamp)
            sent.append(stamp)
            i += 1
            ex.spin_once(timeout_sec=0.0)
        t_kill = time.monotonic()
        os.kill(rec.pid, signal.SIGKILL)
        rec.wait(timeout=10)
    finally:
        rec.kill()
        rec.wait()
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    return sent, acks, t_kill


@child_only
@pytest.mark.parametrize('mode', ['fast', 'realtime'])
def test_sigkill_loses_at_most_the_documented_bound(tmp_path, node_env, domain_id, mode):
    rng = random.Random({'fast': 11, 'realtime': 12}[mode])
    # One kill before the first flush is due (the bag must already be readable, if empty),
    # one later.
    for k, (lo, hi) in enumerate([(0.05, PERIOD_S - 0.1), (0.8, 2.5)]):
        bag = tmp_path / f'rec{k}'
        sent, acks, t_kill = _record_and_kill(bag, node_env, domain_id, mode=mode,
                                              kill_after_s=rng.uniform(lo, hi))
        everything = read_rosbags(bag)
        assert sorted(everything) == sorted(read_mcap(bag))
        # the recorded stream; the plot topic the recorder adds (feed_axis_energy.graph.plots)
        # is checked
        # by the graph tests
        got = [m for m in everything if m[0] == '/power']
        assert got == [m for m in read_mcap(bag) if m[0] == '/power']
        stamps = [t for _, t in got]
        assert stamps == sent[:len(stamps)], 'not an unbroken prefix of what was sent'
        acked = max((s for _, s in acks), default=-1)
        n_acked = sum(1 for s in sent if s <= acked)
        old = max((s for t, s in acks if t <= t_kill - PERIOD_S - SLACK_S), default=-1)
        n_old = sum(1 for s in sent if s <= old)
        assert len(stamps) >= n_old, (mode, len(stamps), n_old)
        lost = n_acked - len(stamps)
        assert lost < CHUNK_MESSAGES + ACK_EVERY, (mode, n_acked, len(stamps))


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The tests above that create rclpy contexts in the test process, in their own
    interpreter (see conftest.run_module_in_child: a crash there fails this test, not the
    whole suite)."""
    run_module_in_child(__file__)
