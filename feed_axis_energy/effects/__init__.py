"""The effect catalog: physical effects a declared feed-axis model may be missing.

Each effect is one class registered in :data:`EFFECTS` (adding an effect = one class with
``@register_effect`` in :mod:`.friction` or :mod:`.drive`), with its physical form (power as a
function of an :class:`EffectState`) and the bounds of its parameters. The catalog knows no
machine file and no simulation: the machine loader checks declared effects against it, and
:mod:`feed_axis_energy.physics` builds the state it computes from. ``docs/effects.md`` has the
table of effects, formulas and parameters::

    state = state_from_simulation(simulate_program(program, machine, load_kg=17.336))
    extra = get_effect('load_friction').power_w(state, {'mu': 0.05})   # (n, k) [W]
"""
from . import drive, friction  # noqa: F401  (importing them registers the effects)
from .aliases import Alias, ALIASES, aliases_of, join_coulomb, masses_vary, split_coulomb
from .catalog import (Effect, EFFECTS, effects_power_w, EffectState, get_effect, Param,
                      ParamValue, register_effect)

__all__ = [
    'Alias', 'ALIASES', 'aliases_of', 'Effect', 'EFFECTS', 'effects_power_w', 'EffectState',
    'get_effect', 'join_coulomb', 'masses_vary', 'Param', 'ParamValue', 'register_effect',
    'split_coulomb',
]
