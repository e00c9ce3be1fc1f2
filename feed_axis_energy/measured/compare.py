"""Compare a campaign of measured runs with the simulation: alignment, Table-1 metrics, groups.

For every run: load the measured data (:func:`.csvload.load_run`); build the motion from the
run's NC program (planned with the machine's limits) or from the data's own commanded or
actual positions; simulate with the run's load; estimate how much later the measured record
is than the simulated one (:func:`.align.estimate_offset`, on the summed power of the
measured axes); average the simulated power over each measuring interval
(:func:`.align.align_simulated`, the instrument model, never point samples) and compute the
Table-1 metrics (:func:`.metrics.table1_metrics`) per measured axis and for their sum.
Runs are pooled by load (:func:`.metrics.group_metrics`), as the paper's Table 1 does.

Offset policy: the estimate is used unless its status is ``'weak'`` (peak correlation below
``min_correlation`` or a constant signal), in which case the run is compared at offset 0 and
the status and message are carried into the result. A poor match is a result, not an error.

"total" means the sum over the axes that have a measured power column; simulated axes
without a measured counterpart (e.g. a Z axis without a power column) are left out of it.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, DataError
from ..gcode import iter_moves, load_gcode
from ..machine import load_machine, Machine
from ..plan import DEFAULT_CHUNK_SAMPLES, Motion, motion_from_samples, plan
from ..sim import simulate_motion, simulate_stream, SimulationResult, streamable
from ..physics import relative_sd_pct, UNCERTAINTY_KEY
from .align import (align_simulated, clock_corrected, estimate_offset, first_order_lag,
                    OffsetResult, step_error_rms)
from .csvload import load_run
from .run import MeasuredRun
from .campaign import Campaign, default_instrument, RunSpec
from .comparison import CampaignComparison, GroupComparison, RunComparison
from .instrument import check_instrument, MeterFit
from .motiondata import reconstruct_motion
from .quantity import (measured_signal, omega_columns, pool_signal_metrics, predicted_signal,
                       quantity_of, sign_warnings, signal_metrics, SignalMetrics,
                       torque_per_unit)
from .spatial import (estimate_work_offset, measured_velocity, motion_anchor, refine_range_s,
                      WorkOffset)
from .states import residual_by_state, state_labels
from .metrics import group_metrics, table1_metrics

__all__ = ['DEFAULT_MAX_LAG_S', 'compare_campaign', 'compare_run', 'simulate_declared_chunks']

DEFAULT_MAX_LAG_S = 5.0
"""Largest time offset searched by default, in either direction [s]."""
MAX_CLOCK_PPM = 500.0
"""Largest clock rate [ppm] the measured motion's estimate corrects: a meter's quartz is
within about 100 ppm; a larger rate says the machine ran the program at another pace than
planned (an override, another planner), which is reported, not hidden in the stamps."""
STEP_SAMPLES = 1_000_000
"""Simulated samples (from the run's start) over which a comparison estimates what the
simulation's sampling changes in the meter's readings (``RunComparison.step_error``): an
RMS over a representative stretch, its memory bounded for runs of any length."""
MIN_CLOCK_PERIODS = 1.0e-3
"""A clock rate is corrected only when it moves the stamps at the record's ends by more than
this many sampling periods (the tolerance a motion-anchored offset is kept to): below that
no comparison can tell."""


class MotionCache:
    """Plans each NC program once; runs that share a program differ only in load."""

    def __init__(self, machine: Machine):
        self.machine = machine
        self._plans: dict[tuple[Path, tuple[float, float, float]], Motion] = {}

    def program_motion(self, path: Path,
                       start: tuple[float, float, float] | None = None) -> Motion:
        key = (path, start or (0.0, 0.0, 0.0))
        if key not in self._plans:
            program = load_gcode(path, start=key[1], **self.machine.gcode_keywords())
            self._plans[key] = plan(program, self.machine.limits(),
                                    options=self.machine.planner.options())
        return self._plans[key]


def simulate_declared(spec: RunSpec, run: MeasuredRun, machine: Machine,
                      cache: MotionCache) -> tuple[SimulationResult, str]:
    if spec.motion_program is not None:
        motion = cache.program_motion(spec.motion_program, spec.motion_start_m)
        source = str(spec.motion_program)
    else:
        kind = spec.motion_from_data or 'commanded'
        # Measured velocity/acceleration columns, where mapped, beat differentiated positions.
        vel, acc = run.derivatives(kind)
        where = f'{run.file} ({kind} positions)'
        rate = machine.planner.rate_hz
        if spec.motion_reconstruct == 'pulses' and float(np.median(np.diff(run.t))) > 1.5 / rate:
            # coarse samples: accelerations between the stamps from positions and velocities
            motion = reconstruct_motion(run.t, run.positions(kind), axes=run.axes,
                                        rate_hz=rate, vel=vel, acc=acc, source=where)
        else:
            motion = motion_from_samples(run.t, run.positions(kind), axes=run.axes,
                                         source=where, vel=vel, acc=acc)
        source = f'data:{kind}'
    return simulate_motion(motion, machine, load_kg=spec.load_kg), source


def simulate_declared_chunks(spec: RunSpec, run: MeasuredRun, machine: Machine,
                             cache: MotionCache, on_chunk: Callable[[SimulationResult], None],
                             *, chunk_samples: int = DEFAULT_CHUNK_SAMPLES) -> str:
    """The run's simulation of the declared model handed to ``on_chunk`` piece by piece.

    A run driven by an NC program on a machine whose declared effects are all sample-local
    is simulated chunk by chunk (``simulate_stream``, every sample at the full rate, equal
    to the whole-record simulation), so a long run at a drive-trace rate never holds the
    whole simulation (some 30 arrays per sample); any other run, and one whose record spans
    no more than one chunk at the planner's rate (one piece either way, without the streamed
    path's buffers), is simulated whole (:func:`simulate_declared`) and handed over in one
    piece. ``chunk_samples``: samples per chunk. Returns the motion source
    (``RunComparison.motion_source``).

    Raises
    ------
    DataError
        The program has no motion to simulate.
    """
    span = float(run.t[-1] - run.t[0]) if run.t.size else 0.0
    if (spec.motion_program is None or not streamable(machine)
            or span * machine.planner.rate_hz <= chunk_samples):
        sim, source = simulate_declared(spec, run, machine, cache)
        on_chunk(sim)
        return source
    _stream_program(spec, spec.motion_program, machine, on_chunk, chunk_samples=chunk_samples)
    return str(spec.motion_program)


def _stream_program(spec: RunSpec, program: Path, machine: Machine,
                    on_chunk: Callable[[SimulationResult], None], *,
                    chunk_samples: int = DEFAULT_CHUNK_SAMPLES) -> dict[str, Any]:
    """``program`` simulated chunk by chunk for the run ``spec`` (its start position and
    load), every chunk to ``on_chunk``; returns ``simulate_stream``'s summary.

    Raises
    ------
    DataError
        The program has no motion to simulate.
    """
    moved = False

    def forward(chunk: SimulationResult) -> None:
        nonlocal moved
        moved = True
        on_chunk(chunk)

    moves = iter_moves(program, start=spec.motion_start_m or (0.0, 0.0, 0.0),
                       **machine.gcode_keywords())
    summary, _ = simulate_stream(moves, machine, file=str(program), load_kg=spec.load_kg,
                                 on_chunk=forward, chunk_samples=chunk_samples)
    if not moved:
        msg = 'the program has no motion to simulate'
        raise DataError(msg, file=str(program))
    return summary


@dataclass(frozen=True)
class SimTrace:
    """What a comparison keeps of a simulation: no more than it uses.

    Attributes
    ----------
    t
        Simulated times [s], ``(m,)``.
    signal
        The predicted trace of the run's measured axes in the quantity's SI unit, ``(m, k)``
        (:func:`.quantity.predicted_signal`: power [W], current [A], torque, force).
    omega
        Screw speed of the measured axes [rad/s], ``(m, k)``, for a drive trace's Table-1
        figures (``q·g·omega``); ``None`` for power.
    vel
        Simulated velocity per motion axis [m/s], ``(m, j)`` (motion states).
    pos
        Simulated position per motion axis [m], ``(m, j)`` (the work offset), or ``None``.
    motion_axes
        The ``j`` axes of ``vel`` and ``pos``.
    source
        Where the motion came from (``RunComparison.motion_source``).
    energy_sd_pct
        Standard uncertainty of the simulated energy of the measured axes [%] (NaN if none).
    """

    t: np.ndarray
    signal: np.ndarray
    omega: np.ndarray | None
    vel: np.ndarray
    source: str
    energy_sd_pct: float
    pos: np.ndarray | None = None
    motion_axes: tuple[str, ...] = ()


def _predicted(spec: RunSpec, sim: SimulationResult, machine: Machine,
               gains: Sequence[float | None] | None,
               run: MeasuredRun | None = None) -> np.ndarray:
    # a window of a longer record: the direction each axis last moved in before it
    before = None if run is None else run.extra.get('direction_before')
    return predicted_signal(spec.instrument.measures, sim, machine, spec.measured_axes,
                            gains=gains, manifest=spec.manifest, key=spec.key,
                            start_direction=before)


def _whole_trace(spec: RunSpec, run: MeasuredRun, machine: Machine, cache: MotionCache,
                 gains: Sequence[float | None] | None = None) -> SimTrace:
    sim, source = simulate_declared(spec, run, machine, cache)
    omega = (None if quantity_of(spec.instrument.measures).is_power
             else omega_columns(sim, spec.measured_axes))
    return SimTrace(sim.power.t, _predicted(spec, sim, machine, gains, run), omega,
                    sim.motion.vel, source, relative_sd_pct(sim, spec.measured_axes),
                    pos=sim.motion.pos if _record_positions(run) is not None else None,
                    motion_axes=tuple(sim.motion.axes))


def _record_positions(run: MeasuredRun) -> np.ndarray | None:
    """The record's positions that :func:`_work_offset` compares the simulated ones with
    (actual, else commanded), or ``None``: then a trace does not keep the simulated ones (a
    long run's positions are as large as its velocities)."""
    return run.position_m if run.position_m is not None else run.command_position_m


class _Growing:
    """An array filled chunk by chunk, its capacity doubled when full.

    One large buffer instead of a list of chunks to join: a long run's chunks would scatter
    over the heap and stay there as fragments after the join; the untouched end of a large
    buffer costs no memory.
    """

    def __init__(self, capacity: int, tail: tuple[int, ...]):
        self.buf = np.empty((max(1, capacity),) + tail)
        self.n = 0

    def add(self, values: np.ndarray) -> None:
        need = self.n + values.shape[0]
        if need > self.buf.shape[0]:
            grown = np.empty((max(need, 2 * self.buf.shape[0]),) + self.buf.shape[1:])
            grown[:self.n] = self.buf[:self.n]
            self.buf = grown
        self.buf[self.n:need] = values
        self.n = need

    def array(self) -> np.ndarray:
        return self.buf[:self.n]


def _streamed_trace(spec: RunSpec, program: Path, machine: Machine,
                    expected_s: float, keep_pos: bool = True) -> SimTrace:
    """The run's program simulated chunk by chunk, keeping only what :class:`SimTrace` holds.

    Equal to the whole-record simulation (``simulate_stream``'s contract) in a fraction of
    its memory: a whole simulation holds some 30 arrays per sample, the trace 2 + 2 per axis.
    ``expected_s`` (the measured record's length) sizes the buffers; ``keep_pos``: whether
    the positions are kept (only a record with positions uses them).
    """
    capacity = int(machine.planner.rate_hz * (expected_s + 60.0)) + 1
    t = _Growing(capacity, ())
    p = _Growing(capacity, (len(spec.measured_axes),))
    v: _Growing | None = None
    x: _Growing | None = None
    names: list[tuple[str, ...]] = []

    def keep(chunk: SimulationResult) -> None:
        nonlocal v, x
        t.add(chunk.power.t)
        p.add(_predicted(spec, chunk, machine, None))
        if v is None:
            v = _Growing(capacity, chunk.motion.vel.shape[1:])
            if keep_pos:
                x = _Growing(capacity, chunk.motion.pos.shape[1:])
            names.append(tuple(chunk.motion.axes))
        v.add(chunk.motion.vel)
        if x is not None:
            x.add(chunk.motion.pos)

    summary = _stream_program(spec, program, machine, keep)
    assert v is not None        # _stream_program raised if no chunk came
    return SimTrace(t.array(), p.array(), None, v.array(), str(program),
                    _summary_sd_pct(summary, spec.measured_axes),
                    pos=None if x is None else x.array(), motion_axes=names[0])


def _summary_sd_pct(summary: dict[str, Any], axes: Sequence[str]) -> float:
    """:func:`~feed_axis_energy.physics.relative_sd_pct` from a streamed summary."""
    found = summary.get(UNCERTAINTY_KEY)
    moved = [a for a in axes if a in summary['energy_j'] and a != 'total']
    if found is None or not moved or summary['samples'] < 2:
        return math.nan
    if any(a not in found['axes'] for a in moved):
        return math.nan
    energy = math.fsum(float(summary['energy_j'][a]) for a in moved)
    value = math.sqrt(math.fsum(float(found['energy_sd_j'][a]) ** 2 for a in moved))
    return 100.0 * value / energy if energy > 0.0 and math.isfinite(value) else math.nan


def simulate_trace(spec: RunSpec, run: MeasuredRun, machine: Machine, cache: MotionCache,
                   gains: Sequence[float | None] | None = None) -> SimTrace:
    """Simulate a run for comparison: streamed when it comes from a program that streams.

    A power run driven by an NC program on a machine whose declared effects are all
    sample-local is simulated chunk by chunk (:func:`_streamed_trace`), so a long run at a
    drive-trace rate holds a few arrays, not the whole simulation; other runs (drive traces
    in current, torque or force among them, whose prediction at rest carries state across
    samples) take the whole-record path (:func:`simulate_declared`, its plan cached per
    program). ``gains``: :func:`.quantity.torque_per_unit` of a drive trace's axes.
    """
    if (quantity_of(spec.instrument.measures).is_power and spec.motion_program is not None
            and streamable(machine)):
        return _streamed_trace(spec, spec.motion_program, machine,
                               float(run.t[-1] - run.t[0]),
                               keep_pos=_record_positions(run) is not None)
    return _whole_trace(spec, run, machine, cache, gains)


def compare_run(spec: RunSpec, machine: Machine, *, max_lag_s: float = DEFAULT_MAX_LAG_S,
                window_s: float | None = None, offset_s: float | None = None,
                min_correlation: float = 0.5, floor_fraction: float = 0.05,
                stamp: str | None = None, filter_s: float | None = None) -> RunComparison:
    """Compare one measured run with its simulation.

    Parameters
    ----------
    spec
        The run (from a campaign manifest).
    machine
        The machine model.
    max_lag_s
        Largest offset searched, in either direction [s].
    window_s
        Measuring interval [s] (0: point samples); default: the run's instrument
        (declared in the manifest, else :func:`.campaign.default_instrument`).
    offset_s
        Compare at this offset instead of estimating one (status ``'fixed'``).
    stamp
        Where the meter stamps its window; default: the run's instrument.
    filter_s
        Time constant [s] of the meter's first-order smoothing; default: the run's
        instrument (``instrument.filter_s``, else 0).
    min_correlation
        Below this peak correlation the estimate is ``'weak'`` and offset 0 is used.
    floor_fraction
        Floor of the percentual error, as a fraction of the run's peak measured power.

    Returns
    -------
    RunComparison
        Offset, metrics and the aligned series.

    Raises
    ------
    DataError, ConfigError, GcodeError, PlanningError
        Unreadable data, program or a run that does not fit the machine (never for a poor
        match).
    """
    return compare_one_run(spec, machine, MotionCache(machine), max_lag_s=max_lag_s,
                           window_s=window_s, offset_s=offset_s, min_correlation=min_correlation,
                           floor_fraction=floor_fraction, stamp=stamp, filter_s=filter_s)


def compare_one_run(spec: RunSpec, machine: Machine, cache: MotionCache, *, max_lag_s: float,
                    window_s: float | None, offset_s: float | None, min_correlation: float,
                    floor_fraction: float, stamp: str | None = None,
                    check_meter: bool = True, measured: MeasuredRun | None = None,
                    filter_s: float | None = None,
                    clock_ppm: float | None = None) -> RunComparison:
    # ``measured``: the run already loaded from ``spec`` (analyze compares each run several
    # times; a long CSV is parsed once). ``clock_ppm``: with a given offset, the clock rate
    # to correct the stamps for (an earlier comparison's ``clock_ppm``)
    run = load_run(spec) if measured is None else measured
    qty = quantity_of(spec.instrument.measures)
    axes = spec.measured_axes
    gains = (None if qty.is_power else
             torque_per_unit(qty.name, machine, axes, declared_kt=spec.instrument.kt_by_axis,
                             manifest=spec.manifest, key=spec.key))
    sim = simulate_trace(spec, run, machine, cache, gains)
    # the trace's arrays as names, each let go as soon as it is used up (long runs)
    t_sim, sim_q, omega_sim, vel = sim.t, sim.signal, sim.omega, sim.vel
    source, sim_duration, energy_sd = sim.source, float(t_sim[-1] - t_sim[0]), sim.energy_sd_pct
    sim_pos, motion_axes = sim.pos, sim.motion_axes
    del sim
    meas_q = measured_signal(run, measures=qty.name, axes=axes, invert=spec.instrument.invert)
    meter = (spec.instrument if spec.instrument.declared
             else replace(default_instrument(spec.motion_from_data, qty.name),
                          filter_s=spec.instrument.filter_s))
    period = float(np.median(np.diff(run.t), overwrite_input=True))
    # the stamps on the simulation's clock (the file's, unless the measured motion times a
    # meter clock that runs fast or slow)
    t_meas = run.t
    clock = 0.0
    window = meter.window_for(period) if window_s is None else float(window_s)
    stamp = meter.stamp if stamp is None else stamp
    if window_s is not None or stamp != meter.stamp:
        meter = replace(meter, window_s=window, stamp=stamp, declared=True)
    if filter_s is not None and filter_s != meter.filter_s:
        meter = replace(meter, filter_s=float(filter_s), declared=True)
    # every second simulated sample, unfiltered, over at most STEP_SAMPLES of them: the same
    # simulation at half its rate, to estimate what the simulation's own sampling changes in
    # what the meter reads (copies: a long run's full trace is not kept for it)
    step_end = min(t_sim.size, STEP_SAMPLES)
    t_half, q_half = t_sim[:step_end:2].copy(), sim_q[:step_end:2].copy()
    if meter.filter_s:
        # the meter's own smoothing: what it would read, on the simulation's time base (the
        # offset search, the meter check and the comparison all see the filtered signal)
        sim_q = first_order_lag(t_sim, sim_q, meter.filter_s)
    if not np.isfinite(sim_q).all():
        sample = int(np.flatnonzero(~np.isfinite(sim_q).all(axis=1))[0]) + 1
        msg = (f'the simulation of this run overflowed (simulated {qty.column} sample '
               f'{sample} is not finite); check the run\'s kinematics and the machine config')
        raise DataError(msg, file=run.file)
    # the signal the offset is searched on, summed once (a long run holds no more copies of
    # it than it needs): the power; or the magnitudes of the drive traces, each scaled by its
    # measured RMS (amperes of different motors add up to nothing), so that a trace of the
    # opposite sign convention is aligned all the same and then reported
    if qty.is_power:
        y_meas, y_sim = _total(meas_q), _total(sim_q)
    else:
        rms = np.sqrt(np.mean(meas_q * meas_q, axis=0))
        scale = np.where(rms > 0.0, rms, 1.0)
        y_meas = (np.abs(meas_q) / scale).sum(axis=1)
        y_sim = (np.abs(sim_q) / scale).sum(axis=1)
    if offset_s is None:
        try:
            anchor = _motion_anchor(spec, run, t_sim, vel, motion_axes, max_lag_s=max_lag_s,
                                    min_correlation=min_correlation)
            if anchor is not None and anchor.status == 'ok':
                anchor, clock = _on_clock(anchor, spec, run, t_sim, vel, motion_axes,
                                          max_lag_s=max_lag_s, min_correlation=min_correlation,
                                          period_s=period)
                t_meas = clock_corrected(run.t, clock)
                found = _refined(anchor, t_meas, y_meas, t_sim, y_sim, max_lag_s=max_lag_s,
                                 window_s=window, period_s=period, stamp=stamp,
                                 min_correlation=min_correlation)
            else:
                found = estimate_offset(run.t, y_meas, t_sim, y_sim,
                                        max_lag_s=max_lag_s, window_s=window, stamp=stamp,
                                        min_correlation=min_correlation, period_s=period)
                if anchor is not None:
                    found = replace(found, motion_s=anchor.offset_s, message=(
                        f'{found.message} (the measured motion does not pin it: '
                        f'{anchor.status}, {anchor.message})'))
        except DataError as err:
            msg = f'the time offset cannot be estimated: {err.reason}'
            raise DataError(msg, file=run.file, column=err.column) from err
        # a weak power match: at the motion's offset where the motion pinned one, else at 0
        used = found.offset_s if found.anchor == 'motion' else (
            0.0 if found.status == 'weak' else found.offset_s)
        if found.status == 'weak' and found.anchor != 'motion':
            found = replace(found, message=f'{found.message}; compared at offset 0')
    else:
        used = float(offset_s)
        found = OffsetResult(used, math.nan, 'fixed', f'offset {used:+.4f} s given by the caller',
                             anchor='given')
        clock = float(clock_ppm or 0.0)
        t_meas = clock_corrected(run.t, clock)
    labels = state_labels(t_sim, vel, t_meas, period_s=period, offset_s=used)
    del vel
    work = _work_offset(spec, run, t_meas, t_sim, sim_pos, motion_axes, used)
    del sim_pos
    try:
        fits: tuple[MeterFit, ...] = ()
        if qty.is_power and check_meter and offset_s is None and found.status != 'weak':
            fits = check_instrument(t_meas, y_meas, t_sim, y_sim,
                                    offset_s=used, window_s=window, stamp=stamp,
                                    same_clock=spec.motion_program is None,
                                    period_s=period)
        aligned_q = align_simulated(t_sim, sim_q, t_meas, offset_s=used, window_s=window,
                                    stamp=stamp)
        # the stamps whose readings lie inside that stretch of the simulation (a simulation
        # has a first sample: sim_duration above reads it); the stamps increase, so the
        # stretch is one slice (views: no run-sized mask or copies)
        first = int(np.searchsorted(t_meas, used + t_half[0] + 2.0 * window + meter.filter_s))
        stop = int(np.searchsorted(t_meas, used + t_half[-1] - 2.0 * window, side='right'))
        step_error = step_error_rms(t_half, q_half, t_meas[first:stop], aligned_q[first:stop],
                                    offset_s=used, window_s=window, stamp=stamp,
                                    filter_s=meter.filter_s)
        del t_half, q_half
        if qty.is_power:
            meas, aligned = meas_q, aligned_q
        else:
            # Table-1 figures of a drive trace: q·g·omega [W] (I·kt·omega for current), both
            # sides with the simulated speed, so that they weigh the unit figures by omega
            assert omega_sim is not None    # a drive trace takes the whole-record path
            omega = align_simulated(t_sim, omega_sim, t_meas, offset_s=used, window_s=window,
                                    stamp=stamp)
            g = np.array(gains, dtype=float)
            meas, aligned = meas_q * g * omega, aligned_q * g * omega
    except DataError as err:
        # align names its arrays only; the run's file is the place the user can act on
        msg = f'simulated {qty.column} cannot be aligned: {err.reason}'
        raise DataError(msg, file=run.file, column=err.column) from err
    # the simulation is no longer needed: a long run's metrics have its memory
    del t_sim, sim_q, y_sim, omega_sim
    where: dict[str, Any] = {'file': run.file, 'rows': run.extra.get('rows'),
                             'floor_fraction': floor_fraction}
    word = 'power' if qty.is_power else f'{qty.symbol}*g*omega'
    meas_total = y_meas if qty.is_power else _total(meas)
    aligned_total = _total(aligned)
    states = residual_by_state(labels, meas_total - aligned_total)
    del labels
    total = table1_metrics(t_meas, meas_total, aligned_total,
                           columns=('time', f'measured total {word}', f'simulated total {word}'),
                           **where)
    # one measured axis is the total: the same arrays, the same metrics
    per_axis = ({axes[0]: total} if meas.shape[1] == 1 else
                {a: table1_metrics(t_meas, meas[:, j], aligned[:, j],
                                   columns=('time', f'measured {a} {word}',
                                            f'simulated {a} {word}'), **where)
                 for j, a in enumerate(axes)})
    signal: dict[str, SignalMetrics] = {
        a: signal_metrics(meas_q[:, j], aligned_q[:, j], quantity=qty)
        for j, a in enumerate(axes)}
    return RunComparison(
        name=spec.name, role=spec.role, load_kg=spec.load_kg, data_file=run.file,
        motion_source=source, axes=axes, window_s=window, offset=found,
        offset_used_s=used, metrics=total, axis_metrics=per_axis, t=t_meas,
        power_meas_w=meas, power_sim_w=aligned, sim_duration_s=sim_duration,
        excluded_rows=int(run.extra.get('excluded_rows', 0)), stamp=stamp,
        instrument=meter.describe(period), meter_fits=fits, states=states,
        filter_s=meter.filter_s,
        energy_sd_pct=energy_sd, measures=qty.name,
        signal_meas=meas_q, signal_sim=aligned_q, signal_metrics=signal,
        torque_per_unit=(None if gains is None
                         else {a: float(g_) for a, g_ in zip(axes, gains)
                               if g_ is not None}),
        sign_warnings=(() if qty.is_power else
                       tuple(sign_warnings(signal, quantity=qty,
                                           invert=spec.instrument.invert))),
        work_offset=work, clock_ppm=clock,
        step_error={a: float(e) for a, e in zip(axes, step_error)},
    )


def _motion_anchor(spec: RunSpec, run: MeasuredRun, t_sim: np.ndarray, vel: np.ndarray,
                   motion_axes: Sequence[str], *, max_lag_s: float,
                   min_correlation: float, t_meas: np.ndarray | None = None,
                   ) -> OffsetResult | None:
    """The offset from the run's measured motion (:func:`.spatial.motion_anchor`) for a run
    simulated from its program whose record maps velocities or positions of the axes the
    motion has; else ``None``. ``t_meas``: the stamps on a corrected clock (default the
    file's)."""
    if spec.motion_program is None:
        return None
    axes = [a for a in run.axes if a in motion_axes]
    v_meas = measured_velocity(run, axes)
    if v_meas is None:
        return None
    v_sim = np.column_stack([vel[:, list(motion_axes).index(a)] for a in axes])
    return motion_anchor(run.t if t_meas is None else t_meas, v_meas, t_sim, v_sim,
                         max_lag_s=max_lag_s, min_correlation=min_correlation)


def _on_clock(anchor: OffsetResult, spec: RunSpec, run: MeasuredRun, t_sim: np.ndarray,
              vel: np.ndarray, motion_axes: Sequence[str], *, max_lag_s: float,
              min_correlation: float, period_s: float) -> tuple[OffsetResult, float]:
    """The motion anchor on the simulation's clock, and the clock rate corrected [ppm].

    The measured motion's two halves time the record's clock (:data:`.spatial.
    MOTION_DRIFT_MIN_S`); a rate within :data:`MAX_CLOCK_PPM` that moves the stamps at the
    record's ends by more than :data:`MIN_CLOCK_PERIODS` sampling periods is corrected
    (:func:`.align.clock_corrected`) and the anchor estimated again on the corrected
    stamps (its offset is the one at the record's middle). Else the anchor as it is, 0.
    """
    rate = anchor.drift_ppm
    if not (math.isfinite(rate) and rate != 0.0):
        return anchor, 0.0
    moved = 0.5e-6 * abs(rate) * float(run.t[-1] - run.t[0])
    if moved <= MIN_CLOCK_PERIODS * period_s:
        return replace(anchor, drift_message=(
            f'{anchor.drift_message}; not corrected: it moves the stamps at the record\'s '
            f'ends by {1e3 * moved:.2f} ms, within {MIN_CLOCK_PERIODS:g} of a sampling '
            'period')), 0.0
    if abs(rate) > MAX_CLOCK_PPM:
        return replace(anchor, drift_message=(
            f'{anchor.drift_message}; not corrected: beyond {MAX_CLOCK_PPM:g} ppm, no meter '
            'clock is that far off (the program ran at another pace than planned?)')), 0.0
    again = _motion_anchor(spec, run, t_sim, vel, motion_axes, max_lag_s=max_lag_s,
                           min_correlation=min_correlation,
                           t_meas=clock_corrected(run.t, rate))
    if again is None or again.status != 'ok':
        return anchor, 0.0
    return replace(again, drift_ppm=rate, drift_message=(
        f'{anchor.drift_message}; corrected: the stamps are put on the simulation\'s clock '
        f'(measured time - {rate:+.1f} ppm of the time from the record\'s middle)')), rate


def _refined(anchor: OffsetResult, t_meas: np.ndarray, y_meas: np.ndarray, t_sim: np.ndarray,
             y_sim: np.ndarray, *, max_lag_s: float, window_s: float, period_s: float,
             stamp: str, min_correlation: float) -> OffsetResult:
    """The power's offset searched near the motion anchor (docs/compare.md, "Alignment").

    Within :func:`.spatial.refine_range_s` of the anchor: the meter's lag behind the motion
    columns. The anchor's status, runner-up (another stroke) and drift stand; a refinement
    that is weak or at the end of its range leaves the anchor's offset.
    """
    m = float(anchor.offset_s)
    reach = min(refine_range_s(window_s, period_s), max_lag_s)
    fine = estimate_offset(t_meas - m, y_meas, t_sim, y_sim, max_lag_s=reach,
                           window_s=window_s, stamp=stamp, min_correlation=min_correlation,
                           period_s=period_s)
    head = (f'aligned on the measured motion at {m:+.4f} s (velocity correlation '
            f'{anchor.peak_correlation:.3f})')
    if fine.status in ('ok', 'ambiguous'):
        offset, peak, rms = m + fine.offset_s, fine.peak_correlation, fine.rms_w
        message = (f'{head}; the power refines it by {1e3 * fine.offset_s:+.1f} ms to '
                   f'{offset:+.4f} s (correlation {peak:.3f})')
    elif fine.status == 'edge':
        offset, peak, rms = m, math.nan, math.nan
        message = (f'{head}; the power fits best at the end of the +-{reach:.3g} s '
                   'refinement, so the motion\'s offset is used')
    else:
        # the power does not match the prediction at the right time: a result ('weak'),
        # compared at the motion's offset
        return replace(anchor, status='weak', anchor='motion', motion_s=m, message=(
            f'{head}, but the power correlates weakly there ({fine.message}); compared at '
            'the motion\'s offset'), peak_correlation=fine.peak_correlation, rms_w=fine.rms_w,
            runner_up_rms_w=math.nan)
    return OffsetResult(offset, peak, 'ok', message, fine.lags_s + m, fine.correlation,
                        rms_w=rms, runner_up_s=anchor.runner_up_s,
                        runner_up_correlation=anchor.runner_up_correlation,
                        drift_ppm=anchor.drift_ppm, drift_message=anchor.drift_message,
                        anchor='motion', motion_s=m)


def _work_offset(spec: RunSpec, run: MeasuredRun, t_meas: np.ndarray, t_sim: np.ndarray,
                 pos: np.ndarray | None, motion_axes: Sequence[str],
                 offset_s: float) -> WorkOffset | None:
    """The work offset of a run simulated from its program whose data has positions
    (machine coordinates) of axes the motion has (:mod:`.spatial`), else ``None``."""
    if spec.motion_program is None or pos is None:
        return None
    measured = _record_positions(run)
    if measured is None:
        return None
    axes = [a for a in run.axes if a in motion_axes]
    if not axes:
        return None
    meas = np.column_stack([measured[:, run.axes.index(a)] for a in axes])
    sim = np.column_stack([pos[:, list(motion_axes).index(a)] for a in axes])
    return estimate_work_offset(t_meas, meas, t_sim, sim, axes=axes, offset_s=offset_s,
                                declared=dict(spec.work_offset_m) or None)


def _total(power_w: np.ndarray) -> np.ndarray:
    """Sum over the axes, ``(n,)``: the one column itself (a view) when there is one."""
    return power_w[:, 0] if power_w.shape[1] == 1 else power_w.sum(axis=1)


def _groups(runs: Sequence[RunComparison]) -> tuple[GroupComparison, ...]:
    by_load: dict[float, list[RunComparison]] = {}
    for r in runs:
        by_load.setdefault(r.load_kg, []).append(r)
    out = []
    for load in sorted(by_load):
        members = by_load[load]
        shared = [a for a in members[0].axes if all(a in m.axes for m in members)]
        out.append(GroupComparison(
            load_kg=load, runs=tuple(m.name for m in members),
            metrics=group_metrics([m.metrics for m in members]),
            axis_metrics={a: group_metrics([m.axis_metrics[a] for m in members])
                          for a in shared},
            signal_metrics={a: pool_signal_metrics([m.signal_metrics[a] for m in members])
                            for a in shared if all(a in m.signal_metrics
                                                   and m.measures == members[0].measures
                                                   for m in members)}))
    return tuple(out)


def compare_campaign(campaign: Campaign, *, machine: Machine | None = None,
                     runs: Sequence[str] | None = None, max_lag_s: float = DEFAULT_MAX_LAG_S,
                     window_s: float | None = None, min_correlation: float = 0.5,
                     floor_fraction: float = 0.05, stamp: str | None = None,
                     progress: Callable[[float], None] | None = None,
                     loaded: Mapping[str, MeasuredRun] | None = None) -> CampaignComparison:
    """Compare every (or the named) run of a campaign with the simulation.

    Parameters
    ----------
    campaign
        From :func:`.manifest.load_campaign`.
    machine
        The machine model; default: the manifest's machine config.
    runs
        Names of the runs to compare, in this order; default: all, in manifest order.
    max_lag_s
        Largest time offset searched, in either direction [s].
    window_s
        Measuring interval [s] (0: point samples); default: each run's instrument.
    stamp
        Where the meter stamps its window; default: each run's instrument.
    min_correlation
        Peak correlation below which an offset estimate is ``'weak'`` (then offset 0).
    floor_fraction
        Floor of the percentual error, as a fraction of each run's peak measured power.
    progress
        Called with the finished fraction (0..1) after every run.
    loaded
        Runs already loaded (:func:`.csvload.load_run`), by name; the others are loaded here.

    Returns
    -------
    CampaignComparison
        Per-run results and per-load groups.

    Raises
    ------
    ConfigError
        Unknown run names (naming the known ones), a bad machine config or a run whose
        axes the machine lacks.
    DataError, GcodeError, PlanningError
        Unusable data or programs.
    """
    if not (math.isfinite(max_lag_s) and max_lag_s >= 0.0):
        msg = f'max_lag_s must be a finite number >= 0, got {max_lag_s!r}'
        raise ConfigError(msg, file=str(campaign.file), key='max_lag_s')
    if runs is None:
        specs = list(campaign.runs)
    else:
        known = [r.name for r in campaign.runs]
        missing = [n for n in runs if n not in known]
        if missing:
            msg = f'no run named {missing[0]!r}; runs are {", ".join(known)}'
            raise ConfigError(msg, file=str(campaign.file), key='runs')
        specs = [campaign.run(n) for n in runs]
        if not specs:
            raise ConfigError('no runs selected', file=str(campaign.file), key='runs')
    machine_file = ''
    if machine is None:
        machine = load_machine(campaign.machine)
        machine_file = str(campaign.machine)
    cache = MotionCache(machine)
    results = []
    for i, spec in enumerate(specs):
        results.append(compare_one_run(spec, machine, cache, max_lag_s=max_lag_s,
                                       window_s=window_s,
                                       offset_s=None, min_correlation=min_correlation,
                                       floor_fraction=floor_fraction, stamp=stamp,
                                       measured=(loaded or {}).get(spec.name)))
        if progress is not None:
            progress((i + 1) / len(specs))
    return CampaignComparison(
        campaign=campaign.name, manifest=str(campaign.file), machine=machine.name,
        machine_file=machine_file, max_lag_s=float(max_lag_s), runs=tuple(results),
        groups=_groups(results))
