"""Friction effects: forces at the nut that oppose motion, as extra power ``F·|v|``.

The extra force is applied at the nut; the declared screw efficiency is not applied to it
(the identification finds effective forces). ``v`` is the carriage velocity [m/s].
"""
from __future__ import annotations

import numpy as np

from ..mass import GRAVITY_M_S2
from .base import Effect, EffectState, Param, ParamValue, register_effect

__all__ = ['Coulomb', 'Viscous', 'LoadFriction', 'Stribeck', 'PositionFriction',
           'ThermalDrift']


@register_effect
class Coulomb(Effect):
    """Direction-dependent constant friction force."""

    id = 'coulomb'
    description = 'constant friction force, different in the positive and negative direction'
    formula = 'P = F+ · max(v, 0) + F- · max(-v, 0)'
    params = (
        Param('f_pos_n', 'N', 0.0, -500.0, 500.0, 20.0, 'friction force moving in +'),
        Param('f_neg_n', 'N', 0.0, -500.0, 500.0, 25.0, 'friction force moving in -'),
    )

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        v = state.velocity_m_s
        return [np.maximum(v, 0.0), np.maximum(-v, 0.0)]


@register_effect
class Viscous(Effect):
    """Friction force proportional to speed (lubricant shear)."""

    id = 'viscous'
    description = 'viscous friction force proportional to the carriage speed'
    formula = 'P = c · v²'
    params = (Param('c_n_s_m', 'N*s/m', 0.0, -5000.0, 5000.0, 100.0, 'viscous coefficient'),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        v = state.velocity_m_s
        return [v * v]


@register_effect
class LoadFriction(Effect):
    """Friction proportional to the weight on the guideways (table + load)."""

    id = 'load_friction'
    description = 'guideway friction proportional to the normal force of table + load'
    formula = 'P = mu · N · |v|,  N = m · g · |cos(incl)|'
    params = (Param('mu', '-', 0.0, -0.1, 0.5, 0.05, 'friction coefficient'),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        return [np.abs(state.velocity_m_s) * state.normal_force_n]


@register_effect
class ClampedLoadFriction(Effect):
    """Friction proportional to the clamped load's weight only.

    What a loss function fitted on no-load runs (the paper's section 2.1) misses when the
    guideway friction grows with the normal force: the table's share is already inside the
    fitted loss, only the workpiece's is not. ``load_friction`` would count the table twice.
    """

    id = 'clamped_load_friction'
    description = ('guideway friction of the clamped load only (the rest is in a loss '
                   'function fitted at no load)')
    formula = 'P = mu_l · N_l · |v|,  N_l = m_load · g · |cos(incl)| on axes carrying the load'
    params = (Param('mu_l', '-', 0.0, -0.1, 0.5, 0.05, 'friction coefficient of the load'),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        n_load = (np.full(len(state.axes), state.load_kg * GRAVITY_M_S2)
                  if state.load_normal_force_n is None else state.load_normal_force_n)
        return [np.abs(state.velocity_m_s) * n_load]


@register_effect
class Stribeck(Effect):
    """Excess static friction that dies away with speed."""

    id = 'stribeck'
    description = 'static friction excess decaying with speed (Stribeck curve)'
    formula = 'P = Fs · exp(-(v/vs)²) · |v|'
    params = (
        Param('f_s_n', 'N', 0.0, 0.0, 500.0, 40.0, 'static excess force at v -> 0'),
        Param('v_s_m_s', 'm/s', 0.01, 0.0005, 0.2, 0.01, 'Stribeck speed', linear=False),
    )

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        v = state.velocity_m_s
        vs = np.broadcast_to(np.asarray(values['v_s_m_s'], dtype=float), (v.shape[1],))
        return [np.exp(-(v / vs) ** 2) * np.abs(v)]


@register_effect
class PositionFriction(Effect):
    """Friction that varies along the stroke (screw straightness, preload, rail wear)."""

    id = 'position_friction'
    description = 'friction force varying along the stroke: low-order cosine terms of x'
    formula = 'P = |v| · sum_i c_i · cos(i·pi·x/L),  i = 1..3'
    params = (
        Param('c1_n', 'N', 0.0, -200.0, 200.0, 15.0, 'first cosine term'),
        Param('c2_n', 'N', 0.0, -200.0, 200.0, 8.0, 'second cosine term'),
        Param('c3_n', 'N', 0.0, -200.0, 200.0, 0.0, 'third cosine term'),
        Param('stroke_m', 'm', 0.4, 0.01, 5.0, 0.4, 'length L the terms span', linear=False),
    )

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        speed = np.abs(state.velocity_m_s)
        stroke = np.broadcast_to(np.asarray(values['stroke_m'], dtype=float),
                                 (speed.shape[1],))
        phase = np.pi * state.position_m / stroke
        return [speed * np.cos(i * phase) for i in (1, 2, 3)]


@register_effect
class ThermalDrift(Effect):
    """Friction that changes as screw, nut and bearings warm up during the run."""

    id = 'thermal_drift'
    description = 'friction force changing linearly with time since program start'
    formula = 'P = r · max(t, 0) · |v|'
    params = (Param('rate_n_s', 'N/s', 0.0, -1.0, 1.0, 0.05, 'growth of the friction force'),)
    constant_at_rest = True     # grows with t, but is proportional to |v|: zero at rest

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        t = np.maximum(state.t, 0.0)[:, None]
        return [t * np.abs(state.velocity_m_s)]
