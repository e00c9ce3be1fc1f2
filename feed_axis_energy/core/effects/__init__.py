"""The effect catalog: physical effects a declared feed-axis model may be missing.

Each effect is one class registered in :data:`EFFECTS` (adding an effect = one class with
``@register_effect``). See :mod:`.base` for the contract and ``docs/effects.md`` for the
table of effects, formulas and parameters::

    state = state_from_simulation(simulate_program(program, machine, load_kg=17.336))
    extra = get_effect('load_friction').power_w(state, {'mu': 0.05})   # (n, k) [W]
    cols = get_effect('coulomb').basis(state)                          # (n, k, 2)
"""
from . import drive, friction  # noqa: F401  (registers the effects)
from .base import (EFFECTS, Effect, effect_state, effects_power_w, EffectState, get_effect,
                   Param, ParamValue, register_effect, state_from_simulation)

__all__ = ['EFFECTS', 'Effect', 'EffectState', 'Param', 'ParamValue', 'effect_state',
           'effects_power_w', 'get_effect', 'register_effect', 'state_from_simulation']
