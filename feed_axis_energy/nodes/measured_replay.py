"""``measured_replay``: plays a measured run bag (``/measured/power``, ``/measured/kinematics``).

Messages are published unchanged (serialized, original header stamps) on the relative topics
``measured/power`` and ``measured/kinematics``, with the original timing scaled by ``rate``
(2.0 = twice as fast) or, with ``rate`` 0, as fast as possible. In the fast case the node
publishes ``burst`` messages per topic at most, then waits until every matched subscriber has
acknowledged them, so a subscriber that keeps up loses nothing. At the end it publishes
``program/end`` (same marker as ``gcode_trajectory``).
"""
from __future__ import annotations

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.node import Node
from trajectory_msgs.msg import JointTrajectory

from feed_axis_energy.core import bagio
from feed_axis_energy.core.graph import ProgramEnd, read_raw
from feed_axis_energy.nodes import convert
from feed_axis_energy.nodes.qos import latched_qos, stream_qos
from feed_axis_energy.nodes.runner import declare, run, StartupError, steady_timer

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
                            '0 as fast as possible')
        self.burst = declare(self, 'burst', 50, 'fast mode: messages between waits for acks')
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
        self.messages = read_raw(bag, BAG_TOPICS)
        self.bag = bag
        self.pubs = {t: self.create_publisher(JointTrajectory, t.lstrip('/'), stream_qos())
                     for t in sorted({m[0] for m in self.messages})}
        self.pub_end = self.create_publisher(DiagnosticArray, 'program/end', latched_qos())
        self._next = 0
        self._since_wait = 0
        self._t0_wall: float | None = None
        self._exit_after: float | None = None
        steady_timer(self, 0.002 if self.rate > 0 else 0.0, self._tick)
        counts = {t: sum(1 for m in self.messages if m[0] == t) for t in self.pubs}
        self.get_logger().info(f'replaying {bag}: {counts} at rate {self.rate:g}')

    def _tick(self) -> None:
        now = time.monotonic()
        if self._exit_after is not None:
            if now >= self._exit_after:
                self.exit_code = 0
            return
        if self._t0_wall is None:
            if any(p.get_subscription_count() < self.min_subscribers for p in self.pubs.values()):
                return
            self._t0_wall = now + 0.3  # let the remote side finish matching
        if now < self._t0_wall:
            return
        t0_log = self.messages[0][1]
        deadline = now + 0.05
        while self._next < len(self.messages) and time.monotonic() < deadline:
            topic, log_ns, data = self.messages[self._next]
            if self.rate > 0 and (log_ns - t0_log) / 1e9 / self.rate > now - self._t0_wall:
                break
            self.pubs[topic].publish(data)
            self._next += 1
            self._since_wait += 1
            if self.rate == 0 and self._since_wait >= self.burst:
                self._wait_acked()
        if self._next == len(self.messages):
            self._wait_acked()
            end = ProgramEnd(program=str(self.bag), samples=len(self.messages),
                             batches=len(self.messages), first_ns=self.messages[0][1],
                             last_ns=self.messages[-1][1])
            self.pub_end.publish(convert.program_end_msg(end))
            self.get_logger().info(f'replayed {len(self.messages)} messages')
            self._exit_after = now + (0.5 if self.exit_at_end else float('inf'))

    def _wait_acked(self) -> None:
        for pub in self.pubs.values():
            pub.wait_for_all_acked(Duration(seconds=10.0))
        self._since_wait = 0


def main(args: list[str] | None = None) -> None:
    """Run the node."""
    sys.exit(run(MeasuredReplay, args, name='measured_replay'))


if __name__ == '__main__':
    main()
