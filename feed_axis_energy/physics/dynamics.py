"""Axis dynamics: sampled motion + machine -> nut forces, screw torques and speeds.

For every axis ``k`` (columns of the ``(n, k)`` arrays in ``motion.axes`` order):

* moved mass ``m_k`` (:func:`.machine.moved_mass_kg`: own table, axes riding on it, load) and
  rotary inertia ``J_k`` = motor + coupling + screw;
* screw speed ``omega = 2·pi·v/lead`` and acceleration ``alpha = 2·pi·a/lead``;
* force the nut must push the carriage with,
  ``F = m·a + m·g·sin(incl) + F_loss(v)`` (less a declared counterbalance, which acts
  against the weight), where ``F_loss = -loss.force_n(v)`` has the sign of ``v`` (the drive
  overcomes the resistance) and the guideway normal force handed to the
  loss model is ``m·g·|cos(incl)|``;
* screw (= motor, direct drive) torque ``M = J·alpha + M_F`` with
  ``M_F = F·lead/(2·pi·eta)`` when the motor drives the load (``F·v >= 0``) and
  ``M_F = F·lead·eta/(2·pi)`` when the load back-drives the screw (``F·v < 0``, e.g. braking
  or lowering a vertical axis): screw-nut friction then reduces the torque that reaches the
  motor. The same ``eta`` is used in both directions. With ``eta = 1`` (the demonstrator)
  ``M·omega = d/dt(J·omega**2/2) + F·v`` exactly, which the energy balance tests rely on.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..errors import ConfigError
from ..units import GRAVITY_M_S2
from ..machine import Machine, moved_mass_kg
from ..plan import Motion

__all__ = ['AxisDynamics', 'compute_dynamics']

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class AxisDynamics:
    """Forces, torques and screw speeds of the axes over time (SI units).

    Attributes
    ----------
    t
        Sample times [s], ``(n,)``.
    axes
        Axis names (column order).
    position_m, velocity_m_s, acceleration_m_s2
        Carriage kinematics, ``(n, k)``.
    angle_rad, omega_rad_s, alpha_rad_s2
        Screw angle, angular velocity and acceleration, ``(n, k)``.
    force_n
        Total force at the nut ``m·a + m·g·sin(incl) + F_loss`` [N], ``(n, k)``.
    loss_force_n
        Part of ``force_n`` that overcomes the passive resistances [N], sign of ``v``.
    gravity_force_n
        Part of ``force_n`` that holds/lifts the weight on an inclined axis [N].
    torque_nm
        Screw torque [N·m], ``(n, k)``.
    line
        Source line of every sample, ``(n,)``.
    mass_kg, inertia_kg_m2, lead_m, efficiency
        Per-axis parameters used, ``(k,)``.
    load_kg
        Workpiece mass used [kg].
    source
        Where the motion came from.
    """

    t: np.ndarray
    axes: tuple[str, ...]
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    angle_rad: np.ndarray
    omega_rad_s: np.ndarray
    alpha_rad_s2: np.ndarray
    force_n: np.ndarray
    loss_force_n: np.ndarray
    gravity_force_n: np.ndarray
    torque_nm: np.ndarray
    line: np.ndarray
    mass_kg: np.ndarray
    inertia_kg_m2: np.ndarray
    lead_m: np.ndarray
    efficiency: np.ndarray
    load_kg: float = 0.0
    source: str = ''

    @property
    def loss_power_w(self) -> np.ndarray:
        """Power spent on the passive resistances ``F_loss·v`` [W], ``(n, k)``, >= 0."""
        return self.loss_force_n * self.velocity_m_s


def compute_dynamics(motion: Motion, machine: Machine, *, load_kg: float = 0.0) -> AxisDynamics:
    """Compute nut forces, screw torques and speeds for every axis of ``motion``.

    Parameters
    ----------
    motion
        Sampled positions, velocities and accelerations; every axis must exist in ``machine``.
    machine
        The machine model.
    load_kg
        Mass of the clamped workpiece on the ``load_axis`` table [kg], ``>= 0``.

    Returns
    -------
    AxisDynamics
        Arrays in ``motion.axes`` order (see the module docstring for the equations).

    Raises
    ------
    ConfigError
        An axis of the motion that the machine lacks, or a negative/non-finite load.
    """
    if not (math.isfinite(load_kg) and load_kg >= 0.0):
        msg = f'compute_dynamics: load_kg must be a finite number >= 0, got {load_kg!r}'
        raise ConfigError(msg, key='load_kg')
    specs = []
    for name in motion.axes:
        if name not in machine.axis_names:
            msg = (f'motion axis {name!r} (from {motion.source or "motion"}) is not an axis of '
                   f'machine {machine.name!r} {machine.axis_names}')
            raise ConfigError(msg, key='axes')
        specs.append(machine.axis(name))

    mass = np.array([moved_mass_kg(machine, s.name, load_kg) for s in specs], dtype=float)
    inertia = np.array([s.rotary_inertia_kg_m2 for s in specs], dtype=float)
    lead = np.array([s.screw.lead_m for s in specs], dtype=float)
    eta = np.array([s.screw.efficiency for s in specs], dtype=float)
    incl = np.radians([s.inclination_deg for s in specs])

    pos = np.asarray(motion.pos, dtype=float)
    vel = np.asarray(motion.vel, dtype=float)
    acc = np.asarray(motion.acc, dtype=float)
    scale = TWO_PI / lead
    omega = vel * scale
    alpha = acc * scale

    gravity = np.empty_like(vel)       # keeps the layout of vel (column-major from the planner)
    gravity[...] = mass * GRAVITY_M_S2 * np.sin(incl)
    balance = np.array([s.counterbalance_n for s in specs], dtype=float)
    if balance.any():
        # a weight compensation acts against the weight (AxisSpec.weight_force_n)
        gravity -= balance * np.sign(np.sin(incl))
    normal = mass * GRAVITY_M_S2 * np.abs(np.cos(incl))
    loss = np.empty_like(vel)
    for j, spec in enumerate(specs):
        loss[:, j] = -np.asarray(spec.loss.force_n(vel[:, j], normal_force_n=normal[j]))
    # in place, in the same order of operations (same bits, fewer temporaries)
    force = np.multiply(acc, mass)
    force += gravity
    force += loss

    to_torque = lead / TWO_PI
    torque = _screw_torque(force, vel, to_torque, eta)
    torque += inertia * alpha

    return AxisDynamics(
        t=np.asarray(motion.t, dtype=float), axes=tuple(motion.axes), position_m=pos,
        velocity_m_s=vel, acceleration_m_s2=acc, angle_rad=pos * scale, omega_rad_s=omega,
        alpha_rad_s2=alpha, force_n=force, loss_force_n=loss, gravity_force_n=gravity,
        torque_nm=torque, line=np.asarray(motion.line), mass_kg=mass, inertia_kg_m2=inertia,
        lead_m=lead, efficiency=eta, load_kg=float(load_kg), source=motion.source)


def _screw_torque(force: np.ndarray, vel: np.ndarray, to_torque: np.ndarray,
                  eta: np.ndarray) -> np.ndarray:
    """``F lead / (2 pi eta)`` where the motor drives (``F v >= 0``), else ``F lead eta / (2 pi)``.

    With ``eta = 1`` on every axis both are ``F lead / (2 pi)`` (``x / 1 == x * 1 == x``),
    so the element-wise select is skipped.
    """
    torque = force * to_torque
    if np.all(eta == 1.0):
        return torque
    drives = np.multiply(force, vel) >= 0.0
    braked = torque * eta
    return np.divide(torque, eta, out=braked, where=drives)
