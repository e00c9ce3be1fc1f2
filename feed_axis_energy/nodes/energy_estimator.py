"""``energy_estimator``: ``axis_state`` -> ``power`` and, at program end, ``block_energy``.

Power and cumulative energy come from :class:`feed_axis_energy.graph.flow.StreamingPower`
(the braking rule and :class:`feed_axis_energy.physics.energy.EnergyIntegrator`), so they
equal the offline result. The ``power`` stamps double as flow-control acknowledgements for
``gcode_trajectory``.

Jobs (docs/nodes.md, "Jobs"): every stream message names its job in ``header.frame_id``. A
batch of a new job starts a fresh integration (with the job's machine and load from the
latched ``job/state``); at the job's ``program/end`` (once every batch sent is integrated)
the node publishes ``block_energy`` and the job's energy report on ``job/energy``
(:class:`feed_axis_energy.cell.EnergyReport`), from which ``gcode_trajectory`` makes the
job's result. Messages of a job already reported are ignored.
"""
from __future__ import annotations

from collections import deque
import sys
import time

import numpy as np

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from feed_axis_energy.cell import dumps, ELECTRICAL_KEYS, EnergyReport, job_machine, JobSpec
from feed_axis_energy.record import bagio, recording
from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.graph import (EndTracker, header_frame_id, JobRouter, lines_at,
                                    live_payload, LIVE_CLOCKS, parse_state_text, seconds_to_ns,
                                    StreamingPower)
from feed_axis_energy.machine import load_machine
from feed_axis_energy.plan import Motion
from feed_axis_energy.nodes import convert
from feed_axis_energy.nodes.qos import command_qos, job_qos, latched_qos, report_qos, stream_qos
from feed_axis_energy.nodes.runner import (check_mass, declare, guard_parameters, LiveParameter,
                                           run, StartupError, steady_timer)
from feed_axis_energy.paths import default_machine

__all__ = ['EnergyEstimator', 'main']


class _Run:
    """What the node integrates for one job (``job_id`` '' : the graph's one program)."""

    def __init__(self, job_id: str) -> None:
        self.job_id = job_id
        self.power: StreamingPower | None = None
        self.lines = None
        self.tracker = EndTracker(['axis_state'])
        self.published = False
        self.wall_anchor_ns: int | None = None     # wall-clock ns of simulation time 0


class EnergyEstimator(Node):
    """Actual power P = sum M·omega (eq. 1) and energy E = integral P dt (eq. 2), streamed."""

    def __init__(self, **kwargs) -> None:
        super().__init__('energy_estimator', **kwargs)
        self.exit_code: int | None = None
        path = declare(self, 'machine', '', 'machine config YAML (its braking rule is used)')
        self.exit_at_end = declare(self, 'exit_at_end', False,
                                   'exit (code 0) once block_energy is published and acked')
        self.load_kg = declare(self, 'load_kg', 0.0,
                               'workpiece mass [kg]; used by declared effects of the machine')
        if not self.load_kg >= 0.0:
            msg = f'parameter load_kg must be >= 0, got {self.load_kg}'
            raise StartupError(msg)
        self.live_clock = declare(self, 'live_clock', 'simulation',
                                  'stamps of job/live: simulation (time from 0) or wall '
                                  '(wall-clock time; the launcher sets it in realtime mode)')
        if self.live_clock not in LIVE_CLOCKS:
            msg = f'parameter live_clock must be one of {LIVE_CLOCKS}, got {self.live_clock!r}'
            raise StartupError(msg)
        self.machine = load_machine(path or default_machine())
        self.current_run = _Run('')
        self.finished: deque[str] = deque(maxlen=64)     # jobs reported: late messages ignored
        self.router: JobRouter[bytes] = JobRouter()
        self._exit_after: float | None = None
        self.pub_power = self.create_publisher(JointTrajectory, 'power', stream_qos())
        self.pub_blocks = self.create_publisher(DiagnosticArray, 'block_energy', latched_qos())
        self.pub_report = self.create_publisher(String, 'job/energy', report_qos())
        self.pub_live = self.create_publisher(String, 'job/live', command_qos())
        self.create_subscription(JointTrajectory, 'axis_state', self._on_state, stream_qos(),
                                 raw=True)
        self.create_subscription(JointTrajectory, 'program/lines', self._on_lines,
                                 latched_qos(), raw=True)
        self.create_subscription(DiagnosticArray, 'program/end', self._on_end, latched_qos())
        self.create_subscription(String, 'job/state', self._on_job_state, job_qos())
        steady_timer(self, 0.1, self._check_exit)
        # load_kg may change while running: the declared effects use it from the next batch
        guard_parameters(self, {'load_kg': LiveParameter(check_mass, self._set_load)})

    # compatibility with the single-program form (tests and the launcher read these)
    @property
    def power(self) -> StreamingPower | None:
        """The current run's integrator."""
        return self.current_run.power

    @power.setter
    def power(self, value: StreamingPower | None) -> None:
        self.current_run.power = value

    @property
    def published(self) -> bool:
        """Whether the current run's ``block_energy`` is out."""
        return self.current_run.published

    def _set_load(self, value: float) -> None:
        self.load_kg = float(value)
        if self.current_run.job_id == '' and self.current_run.power is not None:
            self.current_run.power.load_kg = self.load_kg

    def _run_for(self, job_id: str) -> _Run | None:
        """The run of ``job_id``, a fresh one for a new job; ``None`` for a job reported."""
        if job_id and job_id in self.finished:
            return None
        if self.current_run.job_id != job_id:
            old = self.current_run
            if old.job_id and not old.published and old.power is not None:
                self.get_logger().error(
                    f'job {old.job_id!r} left without its end marker: {old.power.n_samples} '
                    'samples integrated, no report')
            self.current_run = _Run(job_id)
        return self.current_run

    def _on_job_state(self, msg: String) -> None:
        try:
            _, _, spec = parse_state_text(msg.data)
        except FeedAxisError as err:
            self.get_logger().error(str(err))
            return
        if spec is not None and self.router.spec(spec.job_id) is None:
            for spec_, data in self.router.note(spec):
                self._integrate(data, spec_)

    def _on_state(self, data: bytes) -> None:
        try:
            job_id = header_frame_id(data)
        except FeedAxisError as err:
            self.get_logger().error(f'dropped an axis_state batch: {err}')
            return
        spec = self.router.spec(job_id) if job_id else None
        if job_id and spec is None:
            self.router.hold(job_id, data)      # its job/state has not arrived yet
            return
        self._integrate(data, spec)

    def _integrate(self, data: bytes, spec: JobSpec | None) -> None:
        job_id = '' if spec is None else spec.job_id
        run_ = self._run_for(job_id)
        if run_ is None:
            return
        try:
            batch = convert.decode_trajectory(data)
            s = convert.batch_to_series(batch)
            k = len(s.names) // 2
            axes = s.names[:k]
            if s.names[k:] != tuple(recording.screw_joint(a) for a in axes):
                msg = f'axis_state joints {s.names} are not axes followed by their screws'
                raise ValueError(msg)
            if run_.power is None:
                machine = self.machine if spec is None else job_machine(spec)
                load = self.load_kg if spec is None else spec.load_kg
                run_.power = StreamingPower(axes, braking=machine.braking, machine=machine,
                                            load_kg=load)
                if run_.lines is not None:
                    run_.power.set_lines(*run_.lines)
            n = s.t.shape[0]
            motion = Motion(t=s.t, axes=axes, pos=s.positions[:, :k], vel=s.velocities[:, :k],
                            acc=s.accelerations[:, :k], line=np.zeros(n, dtype=np.int32))
            both, energy = run_.power.update(s.t, s.effort[:, k:], s.velocities[:, k:],
                                             motion=motion)
            out = bagio.Series(t=s.t, names=axes + ('total',), positions=energy,
                               velocities=both)
            ((_, cdr),) = convert.series_to_cdr(out, batch=max(s.t.shape[0], 1),
                                                frame_id=job_id)
        except (FeedAxisError, ValueError, TypeError) as err:
            self.get_logger().error(f'dropped an axis_state batch: {err}')
            return
        self.pub_power.publish(cdr)
        run_.tracker.seen('axis_state', batch.stamp_ns)
        if self.pub_live.get_subscription_count():
            self._publish_live(run_, batch.stamp_ns)
        self._maybe_finish(run_)

    def _publish_live(self, run_: _Run, first_ns: int) -> None:
        """One ``job/live`` message for the batch just integrated (only while subscribed)."""
        power = run_.power
        last_ns = int(seconds_to_ns(power.last_time_s))
        stamp = last_ns
        if self.live_clock == 'wall':
            # real time: a batch is sent when the wall clock reaches its first sample, so
            # the job's first batch anchors simulation time 0 to the wall clock
            if run_.wall_anchor_ns is None:
                run_.wall_anchor_ns = time.time_ns() - first_ns
            stamp = run_.wall_anchor_ns + last_ns
        line = None
        if run_.lines is not None:
            line = int(lines_at(np.array([last_ns]), *run_.lines)[0])
        try:
            text = dumps(live_payload(power, job_id=run_.job_id, stamp_ns=stamp,
                                      clock=self.live_clock, line=line))
        except ValueError as err:       # a NaN would not be JSON: never sent
            self.get_logger().error(f'job/live not sent: {err}')
            return
        self.pub_live.publish(String(data=text))

    def _on_lines(self, data: bytes) -> None:
        try:
            job_id = header_frame_id(data)
            lines = convert.lines_from_cdr(data)
        except FeedAxisError as err:
            self.get_logger().error(str(err))
            return
        run_ = self._run_for(job_id)
        if run_ is None:
            return
        run_.lines = lines
        if run_.power is not None:
            run_.power.set_lines(*lines)
        self._maybe_finish(run_)

    def _on_end(self, msg: DiagnosticArray) -> None:
        try:
            end = convert.program_end_from_msg(msg)
        except FeedAxisError as err:
            self.get_logger().error(str(err))
            return
        run_ = self._run_for(end.job_id)
        if run_ is None:
            return
        run_.tracker.end = end
        self._maybe_finish(run_)

    def _maybe_finish(self, run_: _Run) -> None:
        end = run_.tracker.end
        if run_.published or end is None or not run_.tracker.done:
            return
        if end.samples > 0 and (run_.lines is None or run_.power is None):
            return
        power = run_.power
        if power is not None and run_.lines is not None:
            blocks = power.block_energy()
            self.pub_blocks.publish(convert.block_energy_msg(
                blocks, stamp_ns=int(seconds_to_ns(power.last_time_s)), program=end.program,
                frame_id=run_.job_id))
            energy = power.energy_j
            per_axis = ', '.join(f'{a} {e:.3f} J' for a, e in zip(power.axes, energy[:-1]))
            who = f'job {run_.job_id}: ' if run_.job_id else ''
            self.get_logger().info(
                f'{who}program end: {power.n_samples} samples, energy {per_axis}, '
                f'total {energy[-1]:.3f} J, {len(blocks)} blocks')
        run_.published = True
        n = power.n_samples if power is not None else 0
        if n != end.samples:
            self.get_logger().error(
                f'{end.samples - n} samples lost before energy_estimator')
        if run_.job_id:
            self.finished.append(run_.job_id)
            try:
                self.pub_report.publish(String(data=dumps(_report(run_).to_dict())))
            except (FeedAxisError, ValueError) as err:
                self.get_logger().error(f'job {run_.job_id}: no energy report: {err}')
            return
        if self.exit_at_end:
            self.pub_blocks.wait_for_all_acked(Duration(seconds=5.0))
            self._exit_after = time.monotonic() + 0.5

    def _check_exit(self) -> None:
        if self._exit_after is not None and time.monotonic() >= self._exit_after:
            end = self.current_run.tracker.end
            lost = self.current_run.power is not None and end is not None and (
                self.current_run.power.n_samples != end.samples)
            self.exit_code = 1 if lost else 0


def _report(run_: _Run) -> EnergyReport:
    """The energy report of a finished run (zeros when nothing was integrated)."""
    p = run_.power
    if p is None:
        return EnergyReport(job_id=run_.job_id, samples=0, duration_s=0.0,
                            energy_j={'total': 0.0}, peak_power_w={'total': 0.0},
                            braking_returned_j=0.0)
    names = list(p.axes) + ['total']
    elec = p.electrical_summary()
    return EnergyReport(job_id=run_.job_id, samples=p.n_samples, duration_s=p.duration_s,
                        energy_j=dict(zip(names, p.energy_j.tolist())),
                        peak_power_w=dict(zip(names, p.peak_w.tolist())),
                        braking_returned_j=p.regenerated_j,
                        electrical={k: elec[k] for k in ELECTRICAL_KEYS} if elec else None)


def main(args: list[str] | None = None) -> None:
    """Run the node."""
    sys.exit(run(EnergyEstimator, args, name='energy_estimator'))


if __name__ == '__main__':
    main()
