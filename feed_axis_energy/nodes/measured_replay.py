"""``measured_replay``: plays a measured run bag (``/measured/power``, ``/measured/kinematics``).

Messages are published unchanged (serialized, original header stamps) on the relative topics
``measured/power`` and ``measured/kinematics``, with the original timing scaled by ``rate``
(2.0 = twice as fast) or, with ``rate`` 0, as fast as the consumer acknowledges them: at most
``burst`` messages per topic are in flight, and a message is done when a consumer ack on
``ack_topic`` (``std_msgs/Header``, ``frame_id`` = the bag topic, e.g. ``/measured/power``, stamp
= newest stamp taken) has reached its stamp; ``mcap_recorder`` publishes such acks on
``recorder/stream_progress``. Since ``burst`` is below the stream depth, keep-last never
overwrites an unread message. At the end the node publishes ``program/end`` (same marker as
``gcode_trajectory``, plus the last stamp of each topic, keys ``last_stamp_ns:<topic>``).
"""
from __future__ import annotations

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory

from feed_axis_energy.record import bagio
from feed_axis_energy.graph import FlowWindow, ProgramEnd
from feed_axis_energy.nodes import convert
from feed_axis_energy.nodes.qos import latched_qos, stream_qos
from feed_axis_energy.nodes.runner import (declare, guard_parameters, run, StartupError,
                                           steady_timer)

__all__ = ['MeasuredReplay', 'main']

BAG_TOPICS = (bagio.TOPIC_MEASURED_POWER, bagio.TOPIC_MEASURED_KINEMATICS)


class MeasuredReplay(Node):
    """Replays measured data with its own stamps."""

    def __init__(self, **kwargs) -> None:
        super().__init__('measured_replay', **kwargs)
        self.exit_code: int | None = None
        bag = declare(self, 'bag', '', 'measured run bag directory (rosbag2/MCAP)')
        self.rate = declare(self, 'rate', 1.0,
                            'time scale: 1.0 original timing, 2.0 twice as fast, '
                            '0 as fast as the consumer acknowledges')
        self.burst = declare(self, 'burst', 50,
                             'rate 0: messages per topic in flight before waiting for acks')
        ack_topic = declare(self, 'ack_topic', 'recorder/stream_progress',
                            'rate 0: consumer acks (std_msgs/Header, frame_id = bag topic)')
        self.stall_timeout_s = declare(self, 'stall_timeout_s', 30.0,
                                       'rate 0: exit 1 if no ack arrives for this long [s]')
        self.min_subscribers = declare(self, 'min_subscribers', 1,
                                       'matched subscribers per topic before playing')
        self.exit_at_end = declare(self, 'exit_at_end', True, 'exit (code 0) when done')
        if not bag:
            raise StartupError('parameter bag (the measured run bag directory) is required')
        if self.rate < 0:
            msg = f'parameter rate must be >= 0 (0: as fast as possible), got {self.rate}'
            raise StartupError(msg)
        if self.burst < 1 or self.burst >= stream_qos().depth:
            msg = f'parameter burst must be in 1..{stream_qos().depth - 1}, got {self.burst}'
            raise StartupError(msg)
        # decoded and checked once here (bagio): a damaged bag is a DataError at start-up,
        # and corrupt CDR is never published
        self.messages = bagio.read_raw_messages(bag, BAG_TOPICS)
        self.bag = bag
        self._check_stamps()
        topics = sorted({m[0] for m in self.messages})
        self.pubs = {t: self.create_publisher(JointTrajectory, t.lstrip('/'), stream_qos())
                     for t in topics}
        self.pub_end = self.create_publisher(DiagnosticArray, 'program/end', latched_qos())
        self.flows = {t: FlowWindow(self.burst, ['ack']) for t in topics}
        self.sub_ack = None
        if self.rate == 0:
            self.sub_ack = self.create_subscription(Header, ack_topic, self._on_ack,
                                                    stream_qos())
        self._next = 0
        self._t0_wall: float | None = None
        self._last_ack = time.monotonic()
        self._end_sent = False
        self._exit_after: float | None = None
        steady_timer(self, 0.002 if self.rate > 0 else 0.01, self._tick)
        counts = {t: sum(1 for m in self.messages if m[0] == t) for t in self.pubs}
        self.get_logger().info(f'replaying {bag}: {counts} at rate {self.rate:g}')
        guard_parameters(self, {})   # the bag, its timing and the flow control are fixed

    def _check_stamps(self) -> None:
        if self.rate > 0:
            return
        last: dict[str, int] = {}
        for topic, log_ns, _ in self.messages:
            if log_ns <= last.get(topic, -1):
                msg = (f'{self.bag}: {topic} log times must increase for rate 0 (acks are '
                       f'by stamp), got {log_ns} after {last[topic]}')
                raise StartupError(msg)
            last[topic] = log_ns

    def _on_ack(self, msg: Header) -> None:
        flow = self.flows.get('/' + msg.frame_id.lstrip('/')) if msg.frame_id else None
        if flow is not None and flow.ack('ack', convert.time_to_ns(msg.stamp)):
            self._last_ack = time.monotonic()
            self._tick()

    def _matched(self) -> bool:
        if any(p.get_subscription_count() < self.min_subscribers for p in self.pubs.values()):
            return False
        return self.sub_ack is None or self.sub_ack.get_publisher_count() >= 1

    def _tick(self) -> None:
        now = time.monotonic()
        if self._exit_after is not None:
            if now >= self._exit_after:
                self.exit_code = 0
            return
        if self._t0_wall is None:
            if not self._matched():
                return
            self._t0_wall = now + 0.3  # let the remote side finish matching
            self._last_ack = self._t0_wall
        if now < self._t0_wall:
            return
        t0_log = self.messages[0][1]
        deadline = now + 0.05
        while self._next < len(self.messages) and time.monotonic() < deadline:
            topic, log_ns, data = self.messages[self._next]
            if self.rate > 0 and (log_ns - t0_log) / 1e9 / self.rate > now - self._t0_wall:
                break
            if self.rate == 0:
                flow = self.flows[topic]
                if not flow.can_send():
                    break
                flow.sent(log_ns)
            self.pubs[topic].publish(data)
            self._next += 1
        if self._next < len(self.messages) or self._end_sent:
            self._check_stall(now)
            return
        if self.rate == 0 and any(f.in_flight for f in self.flows.values()):
            self._check_stall(now)
            return
        if self.rate > 0:  # nobody acknowledges timed replay: wait for DDS delivery
            for pub in self.pubs.values():
                pub.wait_for_all_acked(Duration(seconds=5.0))
        # per-topic last stamps: the topics end at different stamps, and a consumer waiting
        # for the overall last stamp on each would never finish the one that ends earlier
        last = {topic.lstrip('/'): log_ns for topic, log_ns, _ in self.messages}
        end = ProgramEnd(program=str(self.bag), samples=len(self.messages),
                         batches=len(self.messages), first_ns=self.messages[0][1],
                         last_ns=self.messages[-1][1], topic_last_ns=last)
        self.pub_end.publish(convert.program_end_msg(end))
        self._end_sent = True
        self.get_logger().info(f'replayed {len(self.messages)} messages')
        self._exit_after = now + (0.5 if self.exit_at_end else float('inf'))

    def _check_stall(self, now: float) -> None:
        if (self.rate == 0 and self.exit_code is None
                and any(f.in_flight for f in self.flows.values())
                and now - self._last_ack > self.stall_timeout_s):
            self.get_logger().error(
                f'no acknowledgement on {self.sub_ack.topic_name} for {self.stall_timeout_s} s '
                f'after {self._next} of {len(self.messages)} messages: is a consumer '
                '(e.g. mcap_recorder) acknowledging them?')
            self.exit_code = 1


def main(args: list[str] | None = None) -> None:
    """Run the node."""
    sys.exit(run(MeasuredReplay, args, name='measured_replay'))


if __name__ == '__main__':
    main()
