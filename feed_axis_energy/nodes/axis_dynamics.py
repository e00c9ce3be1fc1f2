"""``axis_dynamics``: ``setpoints`` -> ``axis_state`` batch by batch with the core dynamics.

Each setpoints batch becomes one axis_state batch with the same header stamp and sample
times (layout: :func:`feed_axis_energy.record.recording.axis_state_series`).
"""
from __future__ import annotations

import sys

import numpy as np
from rclpy.node import Node
from trajectory_msgs.msg import JointTrajectory

from feed_axis_energy.record import recording
from feed_axis_energy.physics import compute_dynamics
from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.machine import load_machine
from feed_axis_energy.plan import Motion
from feed_axis_energy.nodes import convert
from feed_axis_energy.nodes.qos import stream_qos
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
        # load_kg may change while running (a new workpiece): it applies from the next batch
        guard_parameters(self, {'load_kg': LiveParameter(check_mass, self._set_load)})

    def _set_load(self, value: float) -> None:
        self.load_kg = float(value)

    def _on_setpoints(self, data: bytes) -> None:
        try:
            s = convert.cdr_to_series(data)
            n = s.t.shape[0]
            motion = Motion(t=s.t, axes=s.names, pos=s.positions, vel=s.velocities,
                            acc=s.accelerations, line=np.zeros(n, dtype=np.int32))
            dyn = compute_dynamics(motion, self.machine, load_kg=self.load_kg)
            out = recording.axis_state_series(motion, dyn)
            ((_, cdr),) = convert.series_to_cdr(out, batch=max(n, 1))
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
