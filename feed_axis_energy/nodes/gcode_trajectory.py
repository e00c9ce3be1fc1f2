"""``gcode_trajectory``: plans an NC program and streams its setpoints (a lifecycle node).

configure: load the machine and survey the program (a first planning pass: samples, duration,
the table of source lines; :class:`~feed_axis_energy.graph.source.SetpointSource`);
activate: wait until the graph is matched, publish ``program/lines``, stream ``setpoints``
planned anew chunk by chunk (bounded memory: one planner chunk and one batch, never every
sample of the program) with at most ``flow_window`` batches in flight, publish
``program/end``; deactivate: pause; cleanup: forget the program.
With ``autostart`` (default) the node configures and activates itself.
"""
from __future__ import annotations

from dataclasses import replace
import sys
import time

from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory
from diagnostic_msgs.msg import DiagnosticArray

from feed_axis_energy.gcode import iter_moves
from feed_axis_energy.graph import (FlowWindow, header_stamp_ns, NS_PER_S, pacing_delay_s,
                                    ProgramEnd, SetpointSource)
from feed_axis_energy.machine import load_machine
from feed_axis_energy.plan import iter_motion
from feed_axis_energy.nodes import convert
from feed_axis_energy.nodes.qos import clock_qos, latched_qos, stream_qos
from feed_axis_energy.nodes.runner import (check_positive, declare, guard_parameters,
                                           LiveParameter, run, STARTUP_ERRORS, StartupError,
                                           steady_timer)
from feed_axis_energy.paths import default_machine

__all__ = ['GcodeTrajectory', 'main']

MODES = ('fast', 'realtime')


class GcodeTrajectory(LifecycleNode):
    """Setpoint source of the graph; drives simulated time in fast mode."""

    def __init__(self, **kwargs) -> None:
        super().__init__('gcode_trajectory', **kwargs)
        self.exit_code: int | None = None
        self.program = declare(self, 'program', '', 'NC program (G-code) file to run')
        self.machine_path = declare(self, 'machine', '',
                                    'machine config YAML (empty: the shipped demonstrator)')
        self.rate_hz = declare(self, 'rate_hz', 0.0,
                               'sampling rate [Hz] (0: the machine config\'s planner rate)')
        self.mode = declare(self, 'mode', 'fast',
                            'fast: as fast as possible in simulated time (publishes /clock); '
                            'realtime: paced by the wall clock')
        self.batch = declare(self, 'batch', 100, 'samples per setpoints message')
        self.window = declare(self, 'flow_window', 16,
                              'max setpoint batches in flight before waiting for acks')
        self.ack_recorder = declare(self, 'ack_recorder', False,
                                    'also wait for recorder/progress acks (no sample lost '
                                    'in a recording)')
        self.start_delay_s = declare(self, 'start_delay_s', 0.5,
                                     'settling time after the graph is matched [s]')
        self.stall_timeout_s = declare(self, 'stall_timeout_s', 30.0,
                                       'exit with an error if no ack arrives for this long [s]')
        self.autostart = declare(self, 'autostart', True,
                                 'configure and activate without a lifecycle manager')
        self._check_parameters()
        self._reset()
        # the program, machine, timing mode and flow window shape the plan and the stream:
        # fixed once started; the stall timeout may change while it runs
        guard_parameters(self, {'stall_timeout_s': LiveParameter(check_positive,
                                                                 self._set_stall_timeout)})
        if self.autostart:
            if self.trigger_configure() != TransitionCallbackReturn.SUCCESS:
                msg = self._error or 'configure failed'
                raise StartupError(msg)
            self.trigger_activate()

    def _check_parameters(self) -> None:
        if self.mode not in MODES:
            msg = f'parameter mode must be one of {MODES}, got {self.mode!r}'
            raise StartupError(msg)
        if self.batch < 1 or self.window < 1:
            msg = f'batch ({self.batch}) and flow_window ({self.window}) must be >= 1'
            raise StartupError(msg)
        if self.window >= stream_qos().depth:
            depth = stream_qos().depth
            msg = f'flow_window ({self.window}) must be below the stream depth {depth}'
            raise StartupError(msg)
        if not self.program:
            msg = 'parameter program (the NC file) is required'
            raise StartupError(msg)

    def _set_stall_timeout(self, value: float) -> None:
        self.stall_timeout_s = float(value)

    def _reset(self) -> None:
        self._error = ''
        self.survey = None
        self._source: SetpointSource | None = None
        self._batches = None            # the iterator of batches while streaming
        self._pending = None            # a batch waiting for pacing or the flow window
        self._sent = 0
        self._streaming = False
        self._matched_at: float | None = None
        self._t_start: float | None = None
        self._end_sent = False
        self._done_logged = False
        self._last_progress = time.monotonic()
        self._timer = None

    # lifecycle transitions ---------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Load and plan the program; create publishers and ack subscriptions."""
        try:
            machine = load_machine(self.machine_path or default_machine())
            options = machine.planner.options()
            if self.rate_hz > 0:
                options = replace(options, rate_hz=float(self.rate_hz))
            program, keywords, limits = self.program, machine.gcode_keywords(), machine.limits()

            def open_motion():
                return iter_motion(iter_moves(program, **keywords), limits, options=options,
                                   file=program)
            self._source = SetpointSource(open_motion, batch=self.batch)
            self.survey = self._source.survey()
        except STARTUP_ERRORS as err:
            self._error = str(err)
            self.get_logger().error(f'configure failed: {err}')
            return TransitionCallbackReturn.FAILURE
        if self.survey.n_samples == 0:
            self._error = f'{self.program}: the program has no motion'
            self.get_logger().error(self._error)
            return TransitionCallbackReturn.FAILURE
        self.pub_setpoints = self.create_publisher(JointTrajectory, 'setpoints', stream_qos())
        self.pub_lines = self.create_publisher(JointTrajectory, 'program/lines', latched_qos())
        self.pub_end = self.create_publisher(DiagnosticArray, 'program/end', latched_qos())
        self.pub_clock = self.create_publisher(Clock, '/clock', clock_qos())
        sources = ['power'] + (['recorder'] if self.ack_recorder else [])
        self.flow = FlowWindow(self.window, sources)
        self.sub_power = self.create_subscription(
            JointTrajectory, 'power', self._on_power, stream_qos(), raw=True)
        self.sub_progress = self.create_subscription(
            Header, 'recorder/progress', self._on_progress, stream_qos())
        sv = self.survey
        self.get_logger().info(
            f'planned {self.program}: {sv.n_samples} samples, {sv.duration_s:.3f} s, '
            f'{sv.n_batches} batches, mode {self.mode}')
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Start (or resume) streaming once the graph is matched."""
        self._streaming = True
        period = 0.002 if self.mode == 'realtime' else 0.01
        self._timer = steady_timer(self, period, self._pump)
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Pause streaming (in-flight batches still finish)."""
        self._streaming = False
        if self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = None
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Forget the plan and the publishers."""
        for name in ('pub_setpoints', 'pub_lines', 'pub_end', 'pub_clock'):
            self.destroy_publisher(getattr(self, name))
        self.destroy_subscription(self.sub_power)
        self.destroy_subscription(self.sub_progress)
        self._reset()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop streaming."""
        self._streaming = False
        return TransitionCallbackReturn.SUCCESS

    # streaming ---------------------------------------------------------------------------
    def _on_power(self, data: bytes) -> None:
        self._ack('power', header_stamp_ns(data))

    def _on_progress(self, msg: Header) -> None:
        if msg.frame_id:
            return   # a per-stream ack; the empty frame_id one covers every recorded stream
        self._ack('recorder', convert.time_to_ns(msg.stamp))

    def _ack(self, source: str, stamp_ns: int) -> None:
        if self.survey is None:
            return
        if self.flow.ack(source, stamp_ns):
            self._last_progress = time.monotonic()
        self._pump()

    def _graph_matched(self) -> bool:
        # With a recorder, axis_state and power each need its subscription too: streams are
        # volatile, so a batch sent before the recorder's reader is known would never be
        # recorded and the recorder's ack would wait for it forever (seen once in 14 runs).
        need = 2 if self.ack_recorder else 1
        if self.pub_setpoints.get_subscription_count() < need:
            return False
        if self.sub_power.get_publisher_count() < 1:
            return False
        if self.count_subscribers(self.resolve_topic_name('axis_state')) < need:
            return False
        if self.count_subscribers(self.resolve_topic_name('power')) < need:
            return False
        if self.ack_recorder and self.sub_progress.get_publisher_count() < 1:
            return False
        return True

    def _pump(self) -> None:
        if not self._streaming or self.exit_code is not None:
            return
        now = time.monotonic()
        if self._t_start is None:
            if not self._graph_matched():
                self._matched_at = None
                return
            if self._matched_at is None:
                self._matched_at = now
                self.get_logger().info('graph matched; streaming starts')
            if now - self._matched_at < self.start_delay_s:
                return
            self._t_start = now
            self._last_progress = now
            sv = self.survey
            self.pub_lines.publish(convert.lines_to_cdr(sv.starts_ns, sv.lines,
                                                        first_ns=sv.first_ns))
            self._batches = self._source.batches()
        sv = self.survey
        while self._sent < sv.n_batches and self.flow.can_send():
            if self._pending is None:
                self._pending = next(self._batches)
            b = self._pending
            if self.mode == 'realtime' and pacing_delay_s(
                    (int(b.t_ns[0]) - sv.first_ns) / NS_PER_S, 0.0, now - self._t_start) > 0:
                break
            self._send(b)
            self._pending = None
            self._sent += 1
        if self._sent == sv.n_batches and not self._end_sent:
            end = ProgramEnd(program=str(self.program), samples=sv.n_samples,
                             batches=sv.n_batches, first_ns=sv.first_ns,
                             last_ns=sv.last_batch_ns)
            self.pub_end.publish(convert.program_end_msg(end))
            self._end_sent = True
            self._batches = None
        if self._end_sent and self.flow.in_flight == 0 and not self._done_logged:
            wall = time.monotonic() - self._t_start
            self.get_logger().info(
                f'program done: {sv.n_samples} samples, {sv.duration_s:.3f} s '
                f'simulated in {wall:.3f} s wall (x{sv.duration_s / wall:.1f})')
            self._done_logged = True
        if self.flow.in_flight and now - self._last_progress > self.stall_timeout_s:
            self.get_logger().error(
                f'no acknowledgement for {self.stall_timeout_s} s with {self.flow.in_flight} '
                'batches in flight: is energy_estimator (or the recorder) running?')
            self.exit_code = 1

    def _send(self, b) -> None:
        stamp = int(b.t_ns[0])
        data = convert.encode_trajectory(
            stamp, b.t_ns - stamp, self.survey.axes,
            {'positions': b.pos, 'velocities': b.vel, 'accelerations': b.acc})
        self.flow.sent(stamp)
        self.pub_setpoints.publish(data)
        if self.mode == 'fast':
            self.pub_clock.publish(convert.clock_msg(stamp))


def main(args: list[str] | None = None) -> None:
    """Run the node (``ros2 run feed_axis_energy gcode_trajectory``)."""
    sys.exit(run(GcodeTrajectory, args, name='gcode_trajectory'))


if __name__ == '__main__':
    main()
