"""The state the effect catalog computes from, built from a simulation of the declared model.

:class:`~feed_axis_energy.effects.catalog.EffectState` holds samples only; this module fills it
from the dynamics and power of a simulation and the machine (inclination, moved masses).
"""
from __future__ import annotations

import numpy as np

from ..effects import EffectState
from ..machine import Machine, moved_mass_kg
from ..units import GRAVITY_M_S2

__all__ = ['effect_state', 'state_from_simulation']


def effect_state(dyn, power, *, machine: Machine) -> EffectState:
    """Build an :class:`EffectState` from dynamics and power of the declared model.

    Parameters
    ----------
    dyn
        :class:`~feed_axis_energy.physics.dynamics.AxisDynamics`.
    power
        :class:`~feed_axis_energy.physics.energy.PowerResult` of the same samples.
    machine
        The machine (for the inclination that sets the guideway normal force).

    Returns
    -------
    EffectState
        The state.
    """
    incl = np.radians([machine.axis(a).inclination_deg for a in dyn.axes])
    mass = np.asarray(dyn.mass_kg, dtype=float)
    load = float(dyn.load_kg)
    # The load's share of each axis's moved mass: the load where the axis carries it, else 0.
    load_mass = np.array([moved_mass_kg(machine, a, load) - moved_mass_kg(machine, a, 0.0)
                          for a in dyn.axes])
    return EffectState(
        t=np.asarray(dyn.t, dtype=float), axes=tuple(dyn.axes), position_m=dyn.position_m,
        velocity_m_s=dyn.velocity_m_s, acceleration_m_s2=dyn.acceleration_m_s2,
        angle_rad=dyn.angle_rad, omega_rad_s=dyn.omega_rad_s, force_n=dyn.force_n,
        torque_nm=dyn.torque_nm, mass_kg=mass, load_kg=float(dyn.load_kg),
        normal_force_n=mass * GRAVITY_M_S2 * np.abs(np.cos(incl)), lead_m=dyn.lead_m,
        mechanical_w=power.mechanical_w, power_w=power.power_w,
        load_normal_force_n=load_mass * GRAVITY_M_S2 * np.abs(np.cos(incl)))


def state_from_simulation(result) -> EffectState:
    """:func:`effect_state` of a :class:`~feed_axis_energy.sim.simulate.SimulationResult`."""
    return effect_state(result.dynamics, result.power, machine=result.machine)
