"""``axis_dynamics``: ``setpoints`` -> ``axis_state`` batch by batch with the core dynamics.

Each setpoints batch becomes one axis_state batch with the same header stamp, sample
times and ``frame_id`` (the job id; layout:
:func:`feed_axis_energy.record.recording.axis_state_series`). A batch of a job uses the job's
machine and load (from the latched ``job/state``; batches that arrive before it are held,
:class:`feed_axis_energy.graph.JobRouter`); a batch without a job id uses the parameters.
"""
from __future__ import annotations

import sys

import numpy as np
from rclpy.node import Node
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from feed_axis_energy.cell import job_machine, JobSpec
from feed_axis_energy.graph import header_frame_id, JobRouter, parse_state_text

from feed_axis_energy.record import recording
from feed_axis_energy.physics import compute_dynamics
from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.machine import load_machine
from feed_axis_energy.plan import Motion
from feed_axis_energy.nodes import convert
from feed_axis_energy.nodes.qos import job_qos, stream_qos
from feed_axis_energy.nodes.runner import (check_mass, declare, guard_parameters, LiveParameter,
                                           run, StartupError)
from feed_axis_energy.paths import default_machine

__all__ = ['AxisDynamicsNode', 'main']


class AxisDynamicsNode(Node):
    """Screw speeds, nut forces and screw torques of every setpoint sample."""

    def __init__(self, **kwargs) -> None:
        super().__init__('axis_dynamics', **kwargs)
        self.exit_code: int | None = None
        path = declare(self, 'machine', '', 'machine config YAML (empty: the demonstrator)')
        self.load_kg = declare(self, 'load_kg', 0.0, 'workpiece mass on the load axis [kg]')
        if not self.load_kg >= 0.0:
            msg = f'parameter load_kg must be >= 0, got {self.load_kg}'
            raise StartupError(msg)
        self.machine = load_machine(path or default_machine())
        self.pub = self.create_publisher(JointTrajectory, 'axis_state', stream_qos())
        self.sub = self.create_subscription(JointTrajectory, 'setpoints', self._on_setpoints,
                                            stream_qos(), raw=True)
        self.batches = 0
        self.router: JobRouter[bytes] = JobRouter()
        self.create_subscription(String, 'job/state', self._on_job_state, job_qos())
        # load_kg may change while running (a new workpiece): it applies from the next batch
        guard_parameters(self, {'load_kg': LiveParameter(check_mass, self._set_load)})

    def _set_load(self, value: float) -> None:
        self.load_kg = float(value)

    def _on_job_state(self, msg: String) -> None:
        try:
            _, _, spec = parse_state_text(msg.data)
        except FeedAxisError as err:
            self.get_logger().error(str(err))
            return
        if spec is not None and self.router.spec(spec.job_id) is None:
            for spec_, data in self.router.note(spec):
                self._compute(data, spec_)

    def _on_setpoints(self, data: bytes) -> None:
        try:
            job_id = header_frame_id(data)
        except FeedAxisError as err:
            self.get_logger().error(f'dropped a setpoints batch: {err}')
            return
        spec = self.router.spec(job_id) if job_id else None
        if job_id and spec is None:
            self.router.hold(job_id, data)      # its job/state has not arrived yet
            return
        self._compute(data, spec)

    def _compute(self, data: bytes, spec: JobSpec | None) -> None:
        try:
            machine = self.machine if spec is None else job_machine(spec)
            load_kg = self.load_kg if spec is None else spec.load_kg
            s = convert.cdr_to_series(data)
            n = s.t.shape[0]
            motion = Motion(t=s.t, axes=s.names, pos=s.positions, vel=s.velocities,
                            acc=s.accelerations, line=np.zeros(n, dtype=np.int32))
            dyn = compute_dynamics(motion, machine, load_kg=load_kg)
            out = recording.axis_state_series(motion, dyn)
            ((_, cdr),) = convert.series_to_cdr(
                out, batch=max(n, 1), frame_id='' if spec is None else spec.job_id)
        except (FeedAxisError, ValueError, TypeError) as err:
            self.get_logger().error(f'dropped a setpoints batch: {err}')
            return
        self.pub.publish(cdr)
        self.batches += 1


def main(args: list[str] | None = None) -> None:
    """Run the node."""
    sys.exit(run(AxisDynamicsNode, args, name='axis_dynamics'))


if __name__ == '__main__':
    main()
