"""The design's raw material: each run's residual and every candidate's columns.

:mod:`.grid` puts fast data on the analysis grid (bins of consecutive measured samples,
exact means); :mod:`.columns` simulates each run's declared model and builds, on that grid,
each run's residual, its motion states and every candidate's columns with their physical
bounds; :mod:`.statestore` holds the runs' simulations, records and comparisons within a
memory budget (memory-mapped beyond it). ``analyze``
(:mod:`feed_axis_energy.identify.analyze`) builds its selection's design from them.
"""
from .columns import (ALIGN_CHUNK_BYTES, axis_basis, axis_index, BASIS_CHUNK_SAMPLES,
                      candidate_block, effect_columns, POSITION_DIVISIONS, prepare_runs,
                      refine_shape, RunData, shape_grid, StatesOf)
from .grid import ANALYSIS_PERIOD_S, bin_windows, Bins, bins_for
from .statestore import (held_comparison, held_record, held_run, held_runs, HeldRecords,
                         STATE_MEMORY_BYTES, StateStore, StateWriter)

__all__ = [
    'ALIGN_CHUNK_BYTES', 'ANALYSIS_PERIOD_S', 'axis_basis', 'axis_index', 'BASIS_CHUNK_SAMPLES',
    'bin_windows', 'Bins', 'bins_for', 'candidate_block', 'effect_columns', 'held_comparison',
    'held_record', 'held_run', 'held_runs', 'HeldRecords', 'POSITION_DIVISIONS', 'prepare_runs',
    'refine_shape', 'RunData', 'shape_grid', 'STATE_MEMORY_BYTES', 'StateStore', 'StatesOf',
    'StateWriter',
]
