"""The axis model: motion -> forces, torques, power and energy.

Rigid-body dynamics with the loss function (:mod:`.dynamics`), actual power (paper eq. 1) and
energy (eq. 2) with the braking rule (:mod:`.energy`), the electrical side of motor, drive and
supply (:mod:`.electrical`), energy by cause (:mod:`.breakdown`), the energy's uncertainty
(:mod:`.uncertainty`), the state the effect catalog computes from (:mod:`.effectstate`) and the
force an axis holds at standstill after it stops (:mod:`.standstill`).
Pure numpy on arrays ``(n_samples, n_axes)``; no files.
"""
from .breakdown import add_breakdown, BreakdownAccumulator, cause_names, cause_powers, LineEnergy
from .dynamics import AxisDynamics, compute_dynamics
from .effectstate import effect_state, state_from_simulation
from .electrical import (add_block_electrical, electrical_power, ElectricalAccumulator,
                         with_electrical)
from .energy import (apply_braking, compute_power, ElectricalPower, energy_by_line,
                     EnergyIntegrator, power_with_total, PowerResult)
from .standstill import holding_force, HoldState, last_direction, REST_SPEED_M_S
from .uncertainty import (add_uncertainty, relative_sd_pct, two_digits, UNCERTAINTY_KEY,
                          uncertainty_words, UncertaintyAccumulator)

__all__ = [
    'add_block_electrical', 'add_breakdown', 'add_uncertainty', 'apply_braking', 'AxisDynamics',
    'BreakdownAccumulator', 'cause_names', 'cause_powers', 'compute_dynamics', 'compute_power',
    'effect_state', 'electrical_power', 'ElectricalAccumulator', 'ElectricalPower',
    'energy_by_line',
    'EnergyIntegrator', 'holding_force', 'HoldState', 'last_direction', 'LineEnergy',
    'power_with_total', 'REST_SPEED_M_S', 'PowerResult', 'relative_sd_pct',
    'state_from_simulation', 'two_digits', 'UNCERTAINTY_KEY', 'uncertainty_words',
    'UncertaintyAccumulator', 'with_electrical',
]
