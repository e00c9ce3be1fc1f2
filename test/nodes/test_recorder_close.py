"""mcap_recorder in-process: reaching the end in the middle of a take loop closes cleanly."""
import time

import must_run
import numpy as np
import pytest

rclpy = must_run.import_or_skip('rclpy', 'rclpy')
from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402
from rclpy.duration import Duration  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from feed_axis_energy.record import bagio  # noqa: E402
from feed_axis_energy.graph.end import ProgramEnd  # noqa: E402
from feed_axis_energy.nodes import convert  # noqa: E402
from feed_axis_energy.nodes.mcap_recorder import McapRecorder  # noqa: E402
from feed_axis_energy.nodes.qos import latched_qos, stream_qos  # noqa: E402


def _until(condition, what, timeout_s=30.0):
    """Wait until ``condition()`` is true, failing with ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f'not within {timeout_s:g} s: {what}'
        time.sleep(0.01)


def _batches(n_batches, batch=10):
    out = []
    for i in range(n_batches):
        t = (i * batch + np.arange(batch)) * 1e-3
        s = bagio.Series(t=t, names=('X', 'total'), positions=np.ones((batch, 2)),
                         velocities=np.ones((batch, 2)))
        out += convert.series_to_cdr(s, batch=batch)
    return out


@child_only
@pytest.mark.parametrize('ack_every', [1, 3])
def test_end_reached_inside_the_take_loop(context, tmp_path, ack_every):
    """The end completes while more messages wait in the queue: no take on a closed handle.

    Before the fix, ``_drain`` closed the bag and destroyed the subscriptions from inside the
    take loop, and the next ``take`` raised ``RCLError: subscription pointer is invalid``.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from trajectory_msgs.msg import JointTrajectory
    bag = tmp_path / 'rec'
    rec = McapRecorder(context=context, parameter_overrides=[
        Parameter('output', value=str(bag)),
        Parameter('topics', value=['power', 'block_energy', 'program/end']),
        Parameter('end_streams', value=['power']), Parameter('exit_at_end', value=True),
        Parameter('ack_every', value=ack_every)])
    writer = rclpy.create_node('writer', context=context)
    try:
        pub = writer.create_publisher(JointTrajectory, 'power', stream_qos())
        pub_end = writer.create_publisher(DiagnosticArray, 'program/end', latched_qos())
        pub_blocks = writer.create_publisher(DiagnosticArray, 'block_energy', latched_qos())
        _until(lambda: min(p.get_subscription_count() for p in (pub, pub_end, pub_blocks)),
               'the recorder matched the writers')
        batches = _batches(30)
        # The end marker names batch 9 as the last one: batches 10.. are still queued when
        # the recorder sees the end complete.
        end = ProgramEnd('p.nc', 100, 10, batches[0][0], batches[9][0])
        pub_end.publish(convert.program_end_msg(end))
        pub_blocks.publish(convert.block_energy_msg([(1, 1.0, 0.1)], stamp_ns=batches[9][0]))
        # the latched marker and block energies are taken first (conditions, not sleeps:
        # under load delivery takes longer than any fixed pause)
        _until(lambda: rec.poll(0.01) or (rec.sink.tracker.end is not None
                                          and rec.received >= 2),
               'the recorder took the end marker and the block energies')
        assert rec.exit_code is None
        for _, cdr in batches:
            pub.publish(cdr)
        # every batch sits in the recorder's reader queue once the reliable writer has its
        # acknowledgements (depth 100 > 30 batches: none is replaced)
        assert pub.wait_for_all_acked(Duration(seconds=30)), 'batches not acknowledged'
        rec.poll(0.1)   # one take loop: the end completes with batches 10.. still queued
        assert rec.exit_code == 0
        rec.poll(0.01)   # after the close: nothing to take, no error
        rec.close()
    finally:
        writer.destroy_node()
        rec.destroy_node()
    got = bagio.read_series(bag, bagio.TOPIC_POWER)
    assert got.t.shape[0] >= 100   # at least the ten batches up to the end


@child_only
def test_flush_is_due_by_wall_time_without_the_timer(context, tmp_path):
    """The take loop itself flushes once ``chunk_period_s`` has passed (no 0.2 s timer lag).

    Only ``poll`` runs here (no executor, so no timer): the flush that writes the message
    must start within ``chunk_period_s`` plus a few polls of the flush before it. Timed on
    the recorder's own flushes, not on when this test sees the message in the bag (DDS
    delivery and the check's bag reads each took tens of ms under load).
    """
    from trajectory_msgs.msg import JointTrajectory
    bag = tmp_path / 'rec'
    rec = McapRecorder(context=context, parameter_overrides=[
        Parameter('output', value=str(bag)), Parameter('topics', value=['power']),
        Parameter('chunk_period_s', value=0.3)])
    writer = rclpy.create_node('writer', context=context)
    try:
        assert read_count(bag) == 0   # readable from the start
        pub = writer.create_publisher(JointTrajectory, 'power', stream_qos())
        deadline = time.monotonic() + 20
        while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        rec.poll(0.01)
        flushes = []    # (start, end, messages buffered) of every flush of the recorder
        flush = rec._flush

        def timed_flush():
            t0, buffered = time.monotonic(), rec.sink.bag.buffered
            flush()
            flushes.append((t0, time.monotonic(), buffered))
        rec._flush = timed_flush
        rec._flush()   # start the period now
        ((_, cdr),) = _batches(1)
        pub.publish(cdr)
        _until(lambda: rec.poll(0.005) or any(f[2] for f in flushes),
               'a flush wrote the message', timeout_s=20.0)
        k = next(i for i, f in enumerate(flushes) if f[2])
        assert k >= 1
        # due chunk_period_s after the previous flush ended (when the period restarts)
        assert flushes[k][0] - flushes[k - 1][1] < 0.3 + 0.1
        assert flushes[k][0] - flushes[k - 1][1] >= 0.3    # and not before
        assert read_count(bag) == 1
    finally:
        writer.destroy_node()
        rec.close()
        rec.destroy_node()


def read_count(bag):
    """Messages recorded from the graph (the recorder's own plot topics not counted), from
    ``metadata.yaml`` (what rosbags' reader counts too, without opening every MCAP file:
    the wait loop above stays fine-grained)."""
    topics = bagio.read_metadata(bag)['topics_with_message_count']
    return sum(int(t['message_count']) for t in topics
               if not t['topic_metadata']['name'].startswith('/plot/'))


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The tests above, in their own interpreter (see conftest.run_module_in_child)."""
    run_module_in_child(__file__)
