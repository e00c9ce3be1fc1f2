"""Simulate a program: the one entrance for "program in, power and energy out".

:func:`simulate_stream` (:mod:`.stream`) runs moves -> motion chunks -> dynamics -> power and
energy chunk by chunk in bounded memory, with its summary (:mod:`.summary`) and roll-ups per
operation, tool and axis (:mod:`.rollup`); :func:`simulate_program` (:mod:`.simulate`) is the
whole-record form for small programs and tests. Tables out (:mod:`.exports`), what-if sweeps
(:mod:`.sweep`) and campaigns of many runs (:mod:`.batch`, :mod:`.batchspec`) are built on it.
:func:`phase_energy` (:mod:`.quadrature`) integrates the energy on the planned phases
instead of on samples, and :func:`summarize_phases` (:mod:`.phasesum`) makes the whole
summary that way (issue 23: so far without declared effects, see
:func:`phase_covered`).
"""
from .batch import BatchJob, JobResult, MAX_JOBS
from .bundle import run_batch
from .batchspec import expand_programs, load_batch_file, make_jobs
from .exports import EXPORT_MARKER, require_pyarrow, SeriesExporter, write_blocks, write_rollups
from .phasesum import summarize_phases
from .quadrature import phase_covered, phase_energy, PhaseEnergy
from .simulate import (declared_effects_power_w, line_table, simulate_motion, simulate_program,
                       SimulationResult, summarize)
from .stream import expand_gaps, sample_chunks, simulate_stream, streamable
from .sweep import (ALIASES, parse_vary, resolve_paths, sweep_rows, SweepRow, variant_machine,
                    variants)
from .trajcsv import load_trajectory_csv

__all__ = [
    'ALIASES', 'BatchJob', 'declared_effects_power_w', 'expand_gaps', 'expand_programs',
    'EXPORT_MARKER', 'JobResult', 'line_table', 'load_batch_file',
    'load_trajectory_csv', 'make_jobs', 'MAX_JOBS', 'parse_vary', 'phase_covered',
    'phase_energy', 'PhaseEnergy', 'require_pyarrow', 'resolve_paths', 'run_batch',
    'sample_chunks',
    'SeriesExporter', 'simulate_motion', 'simulate_program', 'simulate_stream', 'SimulationResult',
    'streamable', 'summarize', 'summarize_phases', 'sweep_rows', 'SweepRow', 'variant_machine',
    'variants', 'write_blocks', 'write_rollups',
]
