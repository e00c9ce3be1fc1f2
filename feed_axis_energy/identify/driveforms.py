"""The catalog's effects as drive traces: what ``analyze`` selects on current, torque, force.

The catalog (:mod:`feed_axis_energy.effects`) gives every effect as the power ``P`` it adds to
an axis. On a drive trace (current, torque or force, :mod:`feed_axis_energy.measured.quantity`)
the residual ``q_meas - q_sim`` in the trace's unit [A, N·m, N] is fitted instead of a power,
with each candidate in its *force form*: the force along the axis ``F = P / v`` while the axis
moves, turned into the trace's unit as the dynamics turn a force into motor torque and the
torque into the trace, ``q = F · (lead / 2·pi) / g`` with ``g`` the torque per unit of the
trace (:func:`~feed_axis_energy.measured.torque_per_unit`: ``kt`` for current, 1 for torque,
``lead/(2·pi)`` for force, so that a force trace gets ``F`` itself; screw efficiency 1: the
candidates are small corrections). At rest an effect's force is what it holds there: the
weight of an undeclared inclination (``gravity``: ``m·g·sin(theta)``, the holding current a
vertical axis shows at every stop, which a power trace cannot see since ``omega = 0``) and a
constant force along the axis (``offset_force``: a cable carrier, a counterweight imbalance
pull at rest as in motion), nothing for the frictions (static friction takes any value up to
the breakaway force; the declared model's standstill hold is
:mod:`feed_axis_energy.physics.standstill`). So on a drive trace ``offset_force`` and the
asymmetric part of ``coulomb`` (the same power shape, :data:`~feed_axis_energy.effects.ALIASES`)
separate by the samples at rest.

Effects whose power is not a force along the axis have no force form and are not candidates
on a drive trace: a drive's standby draw, the motor's copper and iron losses (heat, or a
current the torque-producing component does not carry), the braking rule, and a residual
time offset (an artefact of alignment, its basis a power derivative).
"""
from __future__ import annotations

import math

import numpy as np

from ..effects import EffectState
from ..physics import REST_SPEED_M_S
from ..units import GRAVITY_M_S2

__all__ = ['HELD_AT_REST', 'NO_CURRENT_FORM', 'current_basis', 'has_current_form']

NO_CURRENT_FORM = ('standby', 'copper', 'iron', 'braking_loss', 'time_offset')
"""Effects that are not a force along the axis (see the module docstring)."""
HELD_AT_REST = ('gravity', 'offset_force')
"""Effects whose force acts at rest as in motion (see the module docstring)."""


def has_current_form(effect_id: str) -> bool:
    """Whether ``effect_id`` is a candidate on a drive trace (current, torque, force)."""
    return effect_id not in NO_CURRENT_FORM


def current_basis(effect_id: str, basis_w: np.ndarray, state: EffectState, j: int,
                  kt_nm_a: float) -> np.ndarray:
    """The basis of an effect on simulated axis ``j`` in a drive trace's unit, ``(n, p)``.

    Parameters
    ----------
    effect_id
        The effect (one with a current form, :func:`has_current_form`).
    basis_w
        Its power basis on axis ``j`` [W per unit], ``(n, p)`` (``Effect.basis``).
    state
        The state it was computed from (velocity, moved mass, lead).
    j
        Column of the axis in ``state``.
    kt_nm_a
        The torque per unit of the trace (:func:`~feed_axis_energy.measured.torque_per_unit`):
        the torque constant [N·m/A] of a current trace, 1 for torque, ``lead/(2·pi)`` [m]
        for force.

    Returns
    -------
    numpy.ndarray
        ``basis_w / v`` while moving, the held force at rest (:data:`HELD_AT_REST`), times
        ``lead/(2·pi)/kt_nm_a`` [A, N·m or N per unit of the effect's parameter].
    """
    v = state.velocity_m_s[:, j]
    moving = np.abs(v) > REST_SPEED_M_S
    force = np.zeros_like(basis_w)
    force[moving] = basis_w[moving] / v[moving, None]
    if effect_id == 'gravity':
        # the weight is there whether the axis moves or not: m·g per unit of sin(theta)
        force[~moving] = float(state.mass_kg[j]) * GRAVITY_M_S2
    elif effect_id == 'offset_force':
        # a cable carrier or a counterweight pulls at rest too: 1 N per newton of F0
        force[~moving] = 1.0
    return force * (float(state.lead_m[j]) / (2.0 * math.pi) / kt_nm_a)
