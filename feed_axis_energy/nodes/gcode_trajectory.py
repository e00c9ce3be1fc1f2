"""``gcode_trajectory``: plans an NC program and streams its setpoints (a lifecycle node).

configure: load the machine and survey the program (a first planning pass: samples, duration,
the table of source lines; :class:`~feed_axis_energy.graph.source.SetpointSource`);
activate: wait until the graph is matched, publish ``program/lines``, stream ``setpoints``
planned anew chunk by chunk (bounded memory: one planner chunk and one batch, never every
sample of the program) with at most ``flow_window`` batches in flight, publish
``program/end``; deactivate: pause; cleanup: forget the program.
With ``autostart`` (default) the node configures and activates itself.

With ``program_root`` the node runs *jobs* instead of one program (docs/nodes.md, "Jobs"):
it stays up, takes ``start``/``abort``/``result`` commands on ``job/command`` (JSON), answers
on ``job/reply``, plans each job when it is started, streams it with the job id in every
message's ``frame_id``, and publishes the job state (``job/state``) and each job's result
(``job/result``, from ``energy_estimator``'s ``job/energy``), both latched. The job logic
itself is :class:`feed_axis_energy.cell.JobBoard` (no ROS in it).
"""
from __future__ import annotations

from dataclasses import replace
import json
from pathlib import Path
import sys
import time

from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Header, String
from trajectory_msgs.msg import JointTrajectory
from diagnostic_msgs.msg import DiagnosticArray

from feed_axis_energy.cell import (dumps, EnergyReport, job_machine, JobBoard, JobLimits,
                                   JobResult, JobSnapshot, JobSpec, parse_command, reply)
from feed_axis_energy.errors import FeedAxisError, JobError
from feed_axis_energy.gcode import iter_moves
from feed_axis_energy.graph import (FlowWindow, header_frame_id, header_stamp_ns, NS_PER_S,
                                    pacing_delay_s, ProgramEnd, SetpointSource)
from feed_axis_energy.machine import load_machine
from feed_axis_energy.plan import iter_motion
from feed_axis_energy.nodes import convert
from feed_axis_energy.heap import fix_mmap_threshold
from feed_axis_energy.nodes.qos import (clock_qos, command_qos, job_qos, latched_qos, report_qos,
                                        stream_qos)
from feed_axis_energy.nodes.runner import (check_positive, declare, guard_parameters,
                                           LiveParameter, run, STARTUP_ERRORS, StartupError,
                                           steady_timer)
from feed_axis_energy.paths import config_dir, default_machine

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
        self.program_root = declare(self, 'program_root', '',
                                    'run jobs (job/command) on programs inside this directory '
                                    'instead of one program (empty: run `program`)')
        self.machine_root = declare(self, 'machine_root', '',
                                    'directory a job may name its machine YAML in (empty: '
                                    'jobs use `machine`; "shipped": the shipped config/)')
        self.max_load_kg = declare(self, 'max_load_kg', 10000.0,
                                   'largest workpiece mass a job may ask for [kg]')
        self.keep_results = declare(self, 'keep_results', 100,
                                    'results of this many jobs are kept for the result command')
        self.record_root = declare(self, 'record_root', '',
                                   'jobs: the directory the recorder writes one recording per '
                                   'job into; a job id whose recording exists is refused')
        self.board: JobBoard | None = None
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
        if self.program_root:
            if self.program:
                msg = ('parameters program and program_root exclude each other: one program, '
                       'or jobs on programs under the root')
                raise StartupError(msg)
            machine_root = (config_dir() if self.machine_root == 'shipped'
                            else self.machine_root or None)
            self.board = JobBoard(JobLimits(
                program_root=self.program_root,
                default_machine=Path(self.machine_path or default_machine()),
                machine_root=None if machine_root is None else Path(machine_root),
                max_load_kg=float(self.max_load_kg),
                record_root=Path(self.record_root) if self.record_root else None),
                keep=int(self.keep_results))
        elif not self.program:
            msg = 'parameter program (the NC file) is required (or program_root for jobs)'
            raise StartupError(msg)

    def _set_stall_timeout(self, value: float) -> None:
        self.stall_timeout_s = float(value)

    def _reset(self) -> None:
        self._error = ''
        self.survey = None
        self._source: SetpointSource | None = None
        self._job: JobSpec | None = None      # the job being streamed (job mode)
        self._job_id = ''                     # its id: frame_id of every stream message
        self._aborted = False
        self._sent_samples = 0
        self._last_sent_ns = -1
        self._end_at: float | None = None      # when the end marker went out
        self._graph_ready = False
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
    def _open(self, program: str, machine) -> tuple[SetpointSource, object]:
        """The setpoint source of ``program`` on ``machine`` and its survey."""
        options = machine.planner.options()
        if self.rate_hz > 0:
            options = replace(options, rate_hz=float(self.rate_hz))
        keywords, limits = machine.gcode_keywords(), machine.limits()

        def open_motion():
            return iter_motion(iter_moves(program, **keywords), limits, options=options,
                               file=program)
        source = SetpointSource(open_motion, batch=self.batch)
        return source, source.survey()

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Load and plan the program; create publishers and ack subscriptions."""
        try:
            machine = load_machine(self.machine_path or default_machine())
            if self.board is None:
                self._source, self.survey = self._open(self.program, machine)
        except STARTUP_ERRORS as err:
            self._error = str(err)
            self.get_logger().error(f'configure failed: {err}')
            return TransitionCallbackReturn.FAILURE
        if self.board is None and self.survey.n_samples == 0:
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
        if self.board is not None:
            self._configure_jobs()
            return TransitionCallbackReturn.SUCCESS
        sv = self.survey
        self.get_logger().info(
            f'planned {self.program}: {sv.n_samples} samples, {sv.duration_s:.3f} s, '
            f'{sv.n_batches} batches, mode {self.mode}')
        return TransitionCallbackReturn.SUCCESS

    # jobs --------------------------------------------------------------------------------
    def _configure_jobs(self) -> None:
        self.pub_state = self.create_publisher(String, 'job/state', job_qos())
        self.pub_result = self.create_publisher(String, 'job/result', job_qos())
        self.pub_reply = self.create_publisher(String, 'job/reply', command_qos())
        self.sub_command = self.create_subscription(String, 'job/command', self._on_command,
                                                    command_qos())
        self.sub_energy = self.create_subscription(String, 'job/energy', self._on_energy,
                                                   report_qos())
        self.board.on_change.append(self._publish_state)
        self._publish_state(self.board.snapshot)
        self.get_logger().info(f'waiting for jobs on job/command (programs under '
                               f'{self.board.limits.program_root})')

    def _publish_state(self, snap: JobSnapshot) -> None:
        self.pub_state.publish(String(data=dumps(snap.to_dict())))
        note = f' ({snap.message})' if snap.message not in ('', snap.state.value) else ''
        self.get_logger().info(f'job {snap.job_id or "-"}: {snap.state.value}{note}')

    def _reply(self, request_id: str, *, accepted: bool, message: str, job_id: str = '',
               field: str = '', result: dict | None = None) -> None:
        body = reply(request_id, accepted=accepted, message=message, job_id=job_id,
                     state=self.board.state.value, field=field)
        if result is not None:
            body['result'] = result
        self.pub_reply.publish(String(data=dumps(body)))

    def _on_command(self, msg: String) -> None:
        try:
            cmd = parse_command(msg.data)
        except JobError as err:
            self.get_logger().warning(f'refused a command: {err}')
            self._reply('', accepted=False, message=str(err), field=err.field)
            return
        job_id = cmd.body.get('job_id')
        job_id = job_id if isinstance(job_id, str) and len(job_id) <= 64 else ''
        try:
            if cmd.command == 'start':
                spec = self.board.start(cmd.body)
                self._reply(cmd.request_id, accepted=True, message='planning',
                            job_id=spec.job_id)
                self._plan_job(spec)
            elif cmd.command == 'abort':
                self.board.abort(str(cmd.body.get('job_id', '')))
                self._reply(cmd.request_id, accepted=True, message='abort requested',
                            job_id=job_id)
                self._pump()
            else:
                result = self.board.result(str(cmd.body.get('job_id', '')))
                self._reply(cmd.request_id, accepted=True, message=result.status,
                            job_id=result.job_id, result=result.to_dict())
        except JobError as err:
            self.get_logger().warning(f'refused {cmd.command}: {err}')
            self._reply(cmd.request_id, accepted=False, message=str(err), job_id=job_id,
                        field=err.field)

    def _plan_job(self, spec: JobSpec) -> None:
        """Survey the job's program (synchronous: the node answers no command meanwhile)."""
        try:
            source, survey = self._open(str(spec.program), job_machine(spec))
            if survey.n_samples == 0:
                raise JobError('the program has no motion', field='program', job_id=spec.job_id)
        except (FeedAxisError, OSError) as err:
            self._finish_job(JobResult.build(spec, None, status='failed', message=str(err)))
            return
        except Exception as err:     # a callback never raises: the job fails, the node stays
            self.get_logger().error(f'job {spec.job_id}: planning failed unexpectedly: '
                                    f'{type(err).__name__}: {err}')
            self._finish_job(JobResult.build(spec, None, status='failed',
                                             message=f'{type(err).__name__}: {err}'))
            return
        self._source, self.survey = source, survey
        self._job, self._job_id, self._aborted = spec, spec.job_id, False
        self._batches = self._pending = None
        self._sent = self._sent_samples = 0
        self._last_sent_ns = -1
        self._t_start = None
        self._end_sent = self._done_logged = False
        self._end_at = None
        self._last_progress = time.monotonic()
        self.flow = FlowWindow(self.window, ['power'] + (['recorder'] if self.ack_recorder
                                                         else []))
        self.get_logger().info(
            f'job {spec.job_id}: planned {spec.program}: {survey.n_samples} samples, '
            f'{survey.duration_s:.3f} s, {survey.n_batches} batches')
        self.board.planned(spec.job_id, samples=survey.n_samples)
        self._pump()

    def _on_energy(self, msg: String) -> None:
        try:
            report = EnergyReport.from_dict(json.loads(msg.data))
        except (ValueError, FeedAxisError) as err:
            self.get_logger().error(f'bad job/energy message: {err}')
            return
        job = self._job
        if job is None or report.job_id != job.job_id or not self._end_sent:
            return        # a report of an earlier job (transient local history)
        lost = self._sent_samples - report.samples
        if self._aborted:
            status, message = 'aborted', (f'aborted by request after {self._sent_samples} of '
                                          f'{self.survey.n_samples} samples')
        elif lost:
            status, message = 'failed', f'{lost} samples lost before energy_estimator'
        else:
            status, message = 'ended', 'program completed'
        self._finish_job(JobResult.build(job, report, status=status, message=message,
                                         sent_samples=self._sent_samples))

    def _fail_job(self, message: str) -> None:
        job = self._job
        if job is None:
            return
        if not self._end_sent:
            self._send_end()
        self._finish_job(JobResult.build(job, None, status='failed', message=message,
                                         sent_samples=self._sent_samples))

    def _finish_job(self, result: JobResult) -> None:
        self.pub_result.publish(String(data=dumps(result.to_dict())))
        try:
            self.board.finish(result)
        except JobError as err:
            self.get_logger().error(f'result not taken: {err}')
        self._job, self._job_id, self._source, self.survey = None, '', None, None
        self._batches = self._pending = None
        energy = f'{result.energy_total_j:.6g} J' if result.energy_j else 'no energy'
        self.get_logger().info(f'job {result.job_id}: {result.status}, {energy}, '
                               f'{result.samples} samples ({result.message})')

    def _send_end(self) -> None:
        sv = self.survey
        end = ProgramEnd(program=str(self._job.program if self._job else self.program),
                         samples=self._sent_samples, batches=self._sent,
                         first_ns=sv.first_ns, last_ns=self._last_sent_ns,
                         job_id=self._job_id)
        self.pub_end.publish(convert.program_end_msg(end, aborted=self._aborted))
        self._end_sent = True
        self._end_at = time.monotonic()
        self._batches = None

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
        if self.board is not None and self._job is not None:
            self._fail_job('gcode_trajectory was cleaned up (lifecycle) during the job')
        jobs = ('pub_state', 'pub_result', 'pub_reply') if self.board is not None else ()
        for name in ('pub_setpoints', 'pub_lines', 'pub_end', 'pub_clock') + jobs:
            self.destroy_publisher(getattr(self, name))
        self.destroy_subscription(self.sub_power)
        self.destroy_subscription(self.sub_progress)
        if self.board is not None:
            self.destroy_subscription(self.sub_command)
            self.destroy_subscription(self.sub_energy)
            self.board.on_change.remove(self._publish_state)
        self._reset()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop streaming."""
        self._streaming = False
        return TransitionCallbackReturn.SUCCESS

    # streaming ---------------------------------------------------------------------------
    def _on_power(self, data: bytes) -> None:
        if self.board is not None and header_frame_id(data) != self._job_id:
            return       # an ack of an earlier job
        self._ack('power', header_stamp_ns(data))

    def _on_progress(self, msg: Header) -> None:
        if msg.frame_id != self._job_id:
            return   # an earlier job's ack (jobs: frame_id = job id; one program: '')
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
        if not self._streaming or self.exit_code is not None or self.survey is None:
            return
        now = time.monotonic()
        if self.board is not None and self.board.abort_requested and not self._end_sent:
            self._aborted = True
            self._send_end()       # nothing more is sent: the stream stops at this batch
        if self._t_start is None and not self._end_sent:
            if not self._graph_matched():
                self._matched_at = None
                self._graph_ready = False
                return
            if self._matched_at is None:
                self._matched_at = now
                self.get_logger().info('graph matched; streaming starts')
            if now - self._matched_at < self.start_delay_s and not self._graph_ready:
                return
            self._graph_ready = True
            self._t_start = now
            self._last_progress = now
            sv = self.survey
            self.pub_lines.publish(convert.lines_to_cdr(sv.starts_ns, sv.lines,
                                                        first_ns=sv.first_ns,
                                                        frame_id=self._job_id))
            self._batches = self._source.batches()
        sv = self.survey
        while not self._end_sent and self._sent < sv.n_batches and self.flow.can_send():
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
            self._send_end()
        if (self.board is not None and self._end_sent and self._end_at is not None
                and now - self._end_at > self.stall_timeout_s):
            self._fail_job(f'no energy report from energy_estimator {self.stall_timeout_s} s '
                           'after the end of the stream')
            return
        if (self._end_sent and self.flow.in_flight == 0 and not self._done_logged
                and self._t_start is not None and not self._aborted):
            wall = time.monotonic() - self._t_start
            self.get_logger().info(
                f'program done: {sv.n_samples} samples, {sv.duration_s:.3f} s '
                f'simulated in {wall:.3f} s wall (x{sv.duration_s / wall:.1f})')
            self._done_logged = True
        if self.flow.in_flight and now - self._last_progress > self.stall_timeout_s:
            why = (f'no acknowledgement for {self.stall_timeout_s} s with '
                   f'{self.flow.in_flight} batches in flight: is energy_estimator (or the '
                   'recorder) running?')
            if self.board is not None:
                self._fail_job(why)      # the graph stays up for the next job
                return
            self.get_logger().error(why)
            self.exit_code = 1

    def _send(self, b) -> None:
        stamp = int(b.t_ns[0])
        data = convert.encode_trajectory(
            stamp, b.t_ns - stamp, self.survey.axes,
            {'positions': b.pos, 'velocities': b.vel, 'accelerations': b.acc},
            frame_id=self._job_id)
        self.flow.sent(stamp)
        self._sent_samples += int(b.t_ns.shape[0])
        self._last_sent_ns = stamp
        self.pub_setpoints.publish(data)
        if self.mode == 'fast':
            self.pub_clock.publish(convert.clock_msg(stamp))


def main(args: list[str] | None = None) -> None:
    """Run the node (``ros2 run feed_axis_energy gcode_trajectory``)."""
    fix_mmap_threshold()    # the planner's 1.5 MiB chunks must not grow the heap for good
    sys.exit(run(GcodeTrajectory, args, name='gcode_trajectory'))


if __name__ == '__main__':
    main()
