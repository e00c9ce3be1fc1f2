"""The virtual test rig: "measured" campaigns from a truth model, to test the loop.

A truth model is the declared machine plus catalog effects it does not declare (and,
optionally, one effect outside the catalog), recorded by a virtual meter with noise,
quantisation, drift and an unknown start offset (:mod:`.truth`); :mod:`.campaign` writes
campaigns of such runs (manifest, CSV files, programs, ``truth.json`` for tests only), the
``feed-axis-energy rig`` command.
"""
from .campaign import (CLOCK_START_MS, make_campaign, PAPER_FEEDS_MM_S, PAPER_LOADS_KG,
                       paper_scenario, RigConfig, stroke_program)
from .truth import (EffectSpec, Instrument, instrument_record, OUTSIDE_KINDS, outside_power_w,
                    parse_effects, RigRun, simulate_run, truth_power_w)

__all__ = [
    'CLOCK_START_MS', 'EffectSpec', 'Instrument', 'instrument_record', 'make_campaign',
    'OUTSIDE_KINDS', 'outside_power_w', 'PAPER_FEEDS_MM_S', 'PAPER_LOADS_KG', 'paper_scenario',
    'parse_effects', 'RigConfig', 'RigRun', 'simulate_run', 'stroke_program', 'truth_power_w',
]
