"""Friction effects: forces that oppose motion, as extra power ``F·|v|``.

``F·|v|`` is the power at the nut (force times carriage speed); the declared screw
efficiency is not applied to it, so a fitted force is the *effective force at the nut*: a
guideway force ``F_g`` shows up as ``F_g/eta`` (``docs/effects.md``). ``v`` is the carriage
velocity [m/s].
"""
from __future__ import annotations

import math

import numpy as np

from ..units import GRAVITY_M_S2
from .catalog import Effect, EffectState, NON_NEGATIVE, Param, ParamValue, register_effect

__all__ = ['Coulomb', 'Viscous', 'ViscousAsymmetry', 'LoadFriction', 'Stribeck',
           'PositionFriction', 'ThermalDrift']


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
class ViscousAsymmetry(Effect):
    """Viscous friction that differs between the + and the - direction.

    With ``viscous`` (``c``) it makes the directional pair ``c+ = c + d``, ``c- = c - d``:
    ``c·v² + d·v·|v|`` is ``c+·v²`` moving in + and ``c-·v²`` moving in -. On a program that
    moves alike in both directions the two columns are orthogonal, so the symmetric part and
    the asymmetry are told apart (unlike Coulomb's asymmetry, see ``offset_force``).
    """

    id = 'viscous_asymmetry'
    description = 'viscous friction differing by direction: half the difference c+ - c-'
    formula = 'P = d · v · |v|,  d = (c+ - c-)/2'
    params = (Param('d_n_s_m', 'N*s/m', 0.0, -5000.0, 5000.0, 50.0,
                    'half the difference of the viscous coefficients, + minus -'),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        v = state.velocity_m_s
        return [v * np.abs(v)]


@register_effect
class LoadFriction(Effect):
    """Friction proportional to the weight on the guideways (table + load)."""

    id = 'load_friction'
    description = 'guideway friction proportional to the normal force of table + load'
    formula = 'P = mu · N · |v|,  N = m · g · |cos(incl)|'
    params = (Param('mu', '-', 0.0, 0.0, 0.5, 0.05, 'friction coefficient',
                    bounds=NON_NEGATIVE),)

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
    params = (Param('mu_l', '-', 0.0, 0.0, 0.5, 0.05, 'friction coefficient of the load',
                    bounds=NON_NEGATIVE),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        n_load = (np.full(len(state.axes), state.load_kg * GRAVITY_M_S2)
                  if state.load_normal_force_n is None else state.load_normal_force_n)
        return [np.abs(state.velocity_m_s) * n_load]


@register_effect
class Stribeck(Effect):
    """Excess static friction that dies away with speed (the Stribeck curve).

    The friction force falls from the static level ``Fc + Fs`` at rest to the Coulomb level
    ``Fc`` (held by the loss function or ``coulomb``) as ``exp(-(|v|/vs)^delta)``: the
    characteristic (Stribeck) speed ``vs`` and the shape exponent ``delta`` (2: Gaussian,
    the default; 1: a plain exponential; the literature finds 0.5 ... 2). ``analyze``
    searches ``vs`` with ``delta`` as given (default 2).
    """

    id = 'stribeck'
    description = 'static friction excess decaying with speed (Stribeck curve)'
    formula = 'P = Fs · exp(-(|v|/vs)^delta) · |v|'
    params = (
        Param('f_s_n', 'N', 0.0, 0.0, 500.0, 40.0, 'static excess force at v -> 0',
              bounds=NON_NEGATIVE),
        Param('v_s_m_s', 'm/s', 0.01, 0.0005, 0.2, 0.01, 'Stribeck speed', linear=False,
              bounds=(1e-9, math.inf)),
        Param('delta', '-', 2.0, 0.5, 2.0, 2.0, 'shape exponent of the decay', linear=False,
              bounds=(0.1, 10.0)),
    )

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        v = state.velocity_m_s
        k = v.shape[1]
        vs = np.broadcast_to(np.asarray(values['v_s_m_s'], dtype=float), (k,))
        delta = np.broadcast_to(np.asarray(values['delta'], dtype=float), (k,))
        return [np.exp(-(np.abs(v) / vs) ** delta) * np.abs(v)]


BUMPS = 16
"""Number of position-friction coefficients (bumps); unused bumps have no column."""
BUMP_WIDTH = 0.6
"""Standard deviation of a bump over the spacing: sums flat within 0.5 %, still local."""


@register_effect
class PositionFriction(Effect):
    """Friction that varies along the stroke (rough spot, screw straightness, rail wear).

    A smooth basis of ``BUMPS`` Gaussian bumps at ``x0 + (i-1)·s`` with standard deviation
    ``0.6·s`` (equal coefficients sum to a force flat within 0.5 %): the spacing ``s`` sets
    the resolution; a rough spot about ``1.4·s`` wide at half height is one bump.
    ``analyze`` picks ``s`` among a few candidates by the held-out error.
    """

    id = 'position_friction'
    description = 'friction force varying along the stroke: Gaussian bumps spaced s apart'
    formula = 'P = |v| · sum_i c_i · exp(-(x - x0 - (i-1)·s)² / (2·(0.6·s)²)),  i = 1..16'
    params = tuple(
        Param(f'c{i}_n', 'N', 0.0, -200.0, 200.0, 30.0 if i == 6 else 0.0,
              f'extra friction force at bump {i}') for i in range(1, BUMPS + 1)) + (
        Param('x0_m', 'm', 0.0, -5.0, 5.0, 0.0, 'position of bump 1', linear=False),
        Param('spacing_m', 'm', 0.03, 0.005, 1.0, 0.03, 'spacing s of the bumps',
              linear=False, bounds=(1e-6, math.inf)),
    )

    @staticmethod
    def centres(values: dict[str, ParamValue], k: int) -> tuple[np.ndarray, np.ndarray]:
        """Bump centres ``(BUMPS, k)`` [m] and spacing ``(k,)`` [m]."""
        x0 = np.broadcast_to(np.asarray(values['x0_m'], dtype=float), (k,))
        step = np.broadcast_to(np.asarray(values['spacing_m'], dtype=float), (k,))
        return x0[None, :] + np.arange(BUMPS)[:, None] * step[None, :], step

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        speed = np.abs(state.velocity_m_s)
        centres, step = self.centres(values, speed.shape[1])
        sigma = BUMP_WIDTH * step
        return [speed * np.exp(-0.5 * ((state.position_m - c) / sigma) ** 2) for c in centres]


@register_effect
class ThermalDrift(Effect):
    """Friction that changes as screw, nut and bearings warm up during the run.

    Exponential warm-up ``dF(t) = r·tau·(1 - exp(-t/tau))``: the initial rate ``r`` [N/s] and
    the time constant ``tau``; the final change is ``r·tau``. For ``tau`` much longer than the
    run it becomes the linear drift ``r·t`` (the default ``tau`` = 1e9 s is that limit).
    """

    id = 'thermal_drift'
    description = 'friction force changing with time since program start: exponential warm-up'
    formula = 'P = r · tau · (1 - exp(-max(t,0)/tau)) · |v|'
    params = (Param('rate_n_s', 'N/s', 0.0, -1.0, 1.0, 0.05, 'initial growth of the force'),
              Param('tau_s', 's', 1e9, 10.0, 1e5, 1e9, 'warm-up time constant', linear=False,
                    bounds=(1e-3, math.inf)))
    constant_at_rest = True     # grows with t, but is proportional to |v|: zero at rest

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        tau = np.broadcast_to(np.asarray(values['tau_s'], dtype=float),
                              (state.velocity_m_s.shape[1],))
        t = np.maximum(state.t, 0.0)[:, None]
        # -tau·expm1(-t/tau) keeps full precision in the linear limit (tau >> t)
        return [-tau * np.expm1(-t / tau) * np.abs(state.velocity_m_s)]
