"""Drive, mass and signal effects: standby, motor losses, model errors, timing, braking."""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..units import GRAVITY_M_S2
from .catalog import Effect, EffectState, NON_NEGATIVE, Param, ParamValue, register_effect

__all__ = ['Standby', 'CopperLoss', 'IronLoss', 'MassError', 'Gravity', 'OffsetForce',
           'TorqueRipple', 'TimeOffset', 'BrakingLoss']


@register_effect
class Standby(Effect):
    """Power the drive draws whatever the motion (electronics, fans, holding current)."""

    id = 'standby'
    description = 'constant standby / offset power of the drive, also at standstill'
    formula = 'P = P0'
    params = (Param('p0_w', 'W', 0.0, 0.0, 500.0, 15.0, 'constant power', bounds=NON_NEGATIVE),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        return [np.ones(state.shape)]


@register_effect
class CopperLoss(Effect):
    """Resistive losses of the motor windings: ``R·I²`` with ``I = M/kt``, never negative."""

    id = 'copper'
    description = 'motor copper losses R·(M/kt)², proportional to the square of the screw torque'
    formula = 'P = k · M²,  k = R/kt² (R winding resistance, kt torque constant, per axis)'
    params = (Param('k_w_nm2', 'W/(N*m)^2', 0.0, 0.0, 100.0, 2.0, 'R/kt² factor',
                    bounds=NON_NEGATIVE),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        m = state.torque_nm
        return [m * m]


@register_effect
class IronLoss(Effect):
    """Hysteresis (∝ ω) and eddy-current (∝ ω²) losses in the motor iron."""

    id = 'iron'
    description = 'motor iron losses: hysteresis proportional to |omega|, eddy to omega²'
    formula = 'P = kh · |omega| + ke · omega²'
    params = (
        Param('k_h_w_s_rad', 'W*s/rad', 0.0, 0.0, 1.0, 0.05, 'hysteresis coefficient',
              bounds=NON_NEGATIVE),
        Param('k_e_w_s2_rad2', 'W*s^2/rad^2', 0.0, 0.0, 0.01, 1e-4, 'eddy-current coefficient',
              bounds=NON_NEGATIVE),
    )

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        w = state.omega_rad_s
        return [np.abs(w), w * w]


@register_effect
class MassError(Effect):
    """Moved mass differs from the declared one (forgotten vice, fixtures, carriages)."""

    id = 'mass_error'
    description = 'moved mass differs from the declared one: extra inertial force'
    formula = 'P = dm · a · v'
    params = (Param('dm_kg', 'kg', 0.0, -100.0, 100.0, 3.0, 'extra moved mass'),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        return [state.acceleration_m_s2 * state.velocity_m_s]


@register_effect
class Gravity(Effect):
    """Weight along an axis that is inclined but declared horizontal: ``m·g·sin θ``.

    ``m`` is the moved mass of the run (tables + load on axes that carry it), so one angle
    gives a different force for every load. For an axis declared inclined, ``sin_theta`` is
    the change of ``sin θ`` against the declared inclination.
    """

    id = 'gravity'
    description = 'undeclared inclination θ: weight m·g·sin θ of the moved mass (tables + load)'
    formula = 'P = m · g · sin(theta) · v'
    params = (Param('sin_theta', '-', 0.0, -1.0, 1.0, 0.05,
                    'sine of the inclination (positive: moving in + lifts)',
                    bounds=(-1.0, 1.0)),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        return [state.velocity_m_s * (state.mass_kg * GRAVITY_M_S2)]


@register_effect
class OffsetForce(Effect):
    """A constant force along the axis: cable carrier, counterweight imbalance, an incline.

    The drive pushes ``F0`` more moving in + and ``F0`` less moving in - (positive: the force
    pulls towards -). Aliases (:data:`~feed_axis_energy.effects.ALIASES`): on runs that all
    move the same mass it has the power shape of ``gravity`` (``sin_theta = F0/(m·g)``), which
    separates only when the moved mass varies between runs; and ``coulomb`` with
    ``F+ = Fc + F0``, ``F- = Fc - F0`` is symmetric friction ``Fc`` plus this force, the same
    power everywhere. Unlike friction it also acts at rest, where a force or torque trace (not
    the power) shows it.
    """

    id = 'offset_force'
    description = 'constant force along the axis (cable carrier, counterweight, incline)'
    formula = 'P = F0 · v'
    params = (Param('f0_n', 'N', 0.0, -500.0, 500.0, 30.0,
                    'constant force (positive: moving in + costs more)',
                    bounds=(-1.0e6, 1.0e6)),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        return [np.array(state.velocity_m_s, dtype=float)]


@register_effect
class TorqueRipple(Effect):
    """Torque that repeats every screw revolution (eccentricity, ball recirculation, cogging)."""

    id = 'torque_ripple'
    description = 'torque ripple at harmonics 1 and 2 of the screw revolution'
    formula = 'P = omega · sum_h (a_h · sin(h·phi) + b_h · cos(h·phi)),  h = 1, 2'
    params = (
        Param('a1_nm', 'N*m', 0.0, -1.0, 1.0, 0.05, 'sine term, 1 per revolution'),
        Param('b1_nm', 'N*m', 0.0, -1.0, 1.0, 0.02, 'cosine term, 1 per revolution'),
        Param('a2_nm', 'N*m', 0.0, -1.0, 1.0, 0.0, 'sine term, 2 per revolution'),
        Param('b2_nm', 'N*m', 0.0, -1.0, 1.0, 0.0, 'cosine term, 2 per revolution'),
    )

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        w = state.omega_rad_s
        phi = state.angle_rad
        return [w * np.sin(phi), w * np.cos(phi), w * np.sin(2.0 * phi), w * np.cos(2.0 * phi)]


@register_effect
class TimeOffset(Effect):
    """Measured and simulated records still shifted in time after alignment."""

    id = 'time_offset'
    description = 'residual time offset: the declared power appears delta later'
    formula = 'P = P_decl(t - delta) - P_decl(t)  ~=  -delta · dP_decl/dt'
    params = (Param('delta_s', 's', 0.0, -1.0, 1.0, 0.02, 'time shift (later is positive)'),)
    exact_basis = False
    # Describes how two records line up, not the machine; needs neighbouring samples.
    machine_property = False
    sample_local = False
    constant_at_rest = False

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        if state.t.shape[0] < 2:
            return [np.zeros(state.shape)]
        return [-np.gradient(state.power_w, state.t, axis=0)]

    def power_w(self, state: EffectState,
                params: Mapping[str, ParamValue] | None = None) -> np.ndarray:
        """Declared power shifted by ``delta_s`` minus itself [W] (held at the ends)."""
        values = self.resolve(params)
        n, k = state.shape
        delta = np.broadcast_to(np.asarray(values['delta_s'], dtype=float), (k,))
        shifted = np.column_stack([np.interp(state.t - delta[j], state.t, state.power_w[:, j])
                                   for j in range(k)]) if n else np.zeros((0, k))
        return shifted - state.power_w


@register_effect
class BrakingLoss(Effect):
    """Part of the braking energy is burned (brake chopper, converter losses), not returned."""

    id = 'braking_loss'
    description = 'fraction of the negative (braking) power that is not regenerated'
    formula = 'P = f · max(-P_decl, 0)'
    params = (Param('fraction', '-', 0.0, 0.0, 1.0, 0.3, 'share not returned',
                    bounds=(0.0, 1.0)),)

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        return [np.maximum(-state.power_w, 0.0)]
