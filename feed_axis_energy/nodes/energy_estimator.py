"""``energy_estimator``: ``axis_state`` -> ``power`` and, at program end, ``block_energy``.

Power and cumulative energy come from :class:`feed_axis_energy.graph.flow.StreamingPower`
(the braking rule and :class:`feed_axis_energy.physics.energy.EnergyIntegrator`), so they
equal the offline result. The ``power`` stamps double as flow-control acknowledgements for
``gcode_trajectory``.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.node import Node
from trajectory_msgs.msg import JointTrajectory

from feed_axis_energy.record import bagio, recording
from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.graph import EndTracker, seconds_to_ns, StreamingPower
from feed_axis_energy.machine import load_machine
from feed_axis_energy.plan import Motion
from feed_axis_energy.nodes import convert
from feed_axis_energy.nodes.qos import latched_qos, stream_qos
from feed_axis_energy.nodes.runner import (check_mass, declare, guard_parameters, LiveParameter,
                                           run, StartupError, steady_timer)
from feed_axis_energy.paths import default_machine

__all__ = ['EnergyEstimator', 'main']


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
        self.machine = load_machine(path or default_machine())
        self.power: StreamingPower | None = None
        self.lines = None
        self.tracker = EndTracker(['axis_state'])
        self.published = False
        self._exit_after: float | None = None
        self.pub_power = self.create_publisher(JointTrajectory, 'power', stream_qos())
        self.pub_blocks = self.create_publisher(DiagnosticArray, 'block_energy', latched_qos())
        self.create_subscription(JointTrajectory, 'axis_state', self._on_state, stream_qos(),
                                 raw=True)
        self.create_subscription(JointTrajectory, 'program/lines', self._on_lines,
                                 latched_qos(), raw=True)
        self.create_subscription(DiagnosticArray, 'program/end', self._on_end, latched_qos())
        steady_timer(self, 0.1, self._check_exit)
        # load_kg may change while running: the declared effects use it from the next batch
        guard_parameters(self, {'load_kg': LiveParameter(check_mass, self._set_load)})

    def _set_load(self, value: float) -> None:
        self.load_kg = float(value)
        if self.power is not None:
            self.power.load_kg = self.load_kg

    def _on_state(self, data: bytes) -> None:
        try:
            batch = convert.decode_trajectory(data)
            s = convert.batch_to_series(batch)
            k = len(s.names) // 2
            axes = s.names[:k]
            if s.names[k:] != tuple(recording.screw_joint(a) for a in axes):
                msg = f'axis_state joints {s.names} are not axes followed by their screws'
                raise ValueError(msg)
            if self.power is None:
                self.power = StreamingPower(axes, braking=self.machine.braking,
                                            machine=self.machine, load_kg=self.load_kg)
                if self.lines is not None:
                    self.power.set_lines(*self.lines)
            n = s.t.shape[0]
            motion = Motion(t=s.t, axes=axes, pos=s.positions[:, :k], vel=s.velocities[:, :k],
                            acc=s.accelerations[:, :k], line=np.zeros(n, dtype=np.int32))
            both, energy = self.power.update(s.t, s.effort[:, k:], s.velocities[:, k:],
                                             motion=motion)
            out = bagio.Series(t=s.t, names=axes + ('total',), positions=energy,
                               velocities=both)
            ((_, cdr),) = convert.series_to_cdr(out, batch=max(s.t.shape[0], 1))
        except (FeedAxisError, ValueError, TypeError) as err:
            self.get_logger().error(f'dropped an axis_state batch: {err}')
            return
        self.pub_power.publish(cdr)
        self.tracker.seen('axis_state', batch.stamp_ns)
        self._maybe_finish()

    def _on_lines(self, data: bytes) -> None:
        try:
            self.lines = convert.lines_from_cdr(data)
        except FeedAxisError as err:
            self.get_logger().error(str(err))
            return
        if self.power is not None:
            self.power.set_lines(*self.lines)
        self._maybe_finish()

    def _on_end(self, msg: DiagnosticArray) -> None:
        try:
            self.tracker.end = convert.program_end_from_msg(msg)
        except FeedAxisError as err:
            self.get_logger().error(str(err))
            return
        self._maybe_finish()

    def _maybe_finish(self) -> None:
        if self.published or not self.tracker.done or self.lines is None or self.power is None:
            return
        end = self.tracker.end
        blocks = self.power.block_energy()
        self.pub_blocks.publish(convert.block_energy_msg(
            blocks, stamp_ns=int(seconds_to_ns(self.power.last_time_s)), program=end.program))
        self.published = True
        energy = self.power.energy_j
        per_axis = ', '.join(f'{a} {e:.3f} J' for a, e in zip(self.power.axes, energy[:-1]))
        self.get_logger().info(
            f'program end: {self.power.n_samples} samples, energy {per_axis}, '
            f'total {energy[-1]:.3f} J, {len(blocks)} blocks')
        if self.power.n_samples != end.samples:
            self.get_logger().error(
                f'{end.samples - self.power.n_samples} samples lost before energy_estimator')
        if self.exit_at_end:
            self.pub_blocks.wait_for_all_acked(Duration(seconds=5.0))
            self._exit_after = time.monotonic() + 0.5

    def _check_exit(self) -> None:
        if self._exit_after is not None and time.monotonic() >= self._exit_after:
            lost = self.power is not None and self.tracker.end is not None and (
                self.power.n_samples != self.tracker.end.samples)
            self.exit_code = 1 if lost else 0


def main(args: list[str] | None = None) -> None:
    """Run the node."""
    sys.exit(run(EnergyEstimator, args, name='energy_estimator'))


if __name__ == '__main__':
    main()
