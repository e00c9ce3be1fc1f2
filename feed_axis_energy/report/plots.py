"""The paper's three plots per run (Figs 6-8 kind), drawn with matplotlib's Agg canvas only.

* power: actual power over time, measured vs simulated (Fig 6 kind), one panel for the sum of
  the measured axes and one per axis when there are several;
* energy: consumed energy over time, measured vs simulated (Fig 7 kind);
* signal (drive traces only: current, torque, force): the trace measured vs simulated per
  axis in its own unit, with its RMSE and R²;
* error: differential error ``P_meas - P_sim`` [W] and percentual error
  ``100 |dP| / |P_meas|`` [%] over time (Fig 8 kind); the percentual error is drawn only where
  ``|P_meas|`` is above the run's floor, as in the metrics. Its scale ends at the 99th
  percentile (a single sample of 100 % would otherwise flatten the rest); samples above are
  drawn as markers on the top edge and the plot says how many and how large.

No pyplot: figures are :class:`matplotlib.figure.Figure` objects on an Agg canvas, so nothing
touches a display or global state.
"""
from __future__ import annotations

from matplotlib.figure import Figure
import numpy as np

from feed_axis_energy.measured import quantity_of, RunComparison

from .page import figure_png

__all__ = ['PCT_SCALE_PERCENTILE', 'PLOT_KINDS', 'pct_scale', 'plot_energy', 'plot_error',
           'plot_power', 'plot_signal', 'run_plots']

PLOT_KINDS = ('power', 'energy', 'error')
PCT_SCALE_PERCENTILE = 99.0
"""The percentual-error plot's scale ends at this percentile of its samples (times 1.1)."""

_MEAS = dict(color='#1f4e9a', lw=1.1, label='measured')
_SIM = dict(color='#d9480f', lw=1.1, ls='--', label='simulated')


def _title(run: RunComparison, what: str) -> str:
    return f'{run.name}: {what}, load {run.load_kg:g} kg'


def _offset_note(run: RunComparison) -> str:
    return (f'simulation shifted by {run.offset_used_s:+.3f} s (offset {run.offset.status}); '
            f'simulated power averaged over {run.window_s * 1e3:.0f} ms intervals')


def pct_scale(pct: np.ndarray) -> tuple[float, int]:
    """Upper end of the percentual-error scale and how many samples lie above it.

    ``1.1`` times the :data:`PCT_SCALE_PERCENTILE` percentile of the finite samples, but at
    least 1 % and never more than the largest sample (then nothing is clipped).
    """
    finite = pct[np.isfinite(pct)]
    if finite.size == 0:
        return 1.0, 0
    top = float(finite.max())
    limit = max(1.1 * float(np.percentile(finite, PCT_SCALE_PERCENTILE)), 1.0)
    if limit >= top:
        return max(1.05 * top, 1.0), 0
    return limit, int(np.count_nonzero(finite > limit))


def plot_power(run: RunComparison, *, dpi: int = 100) -> bytes:
    """Actual power over time, measured vs simulated (Fig 6 kind); returns PNG bytes."""
    panels = [('sum of ' + ', '.join(run.axes) if len(run.axes) > 1 else f'axis {run.axes[0]}',
               run.total_meas_w, run.total_sim_w)]
    if len(run.axes) > 1:
        panels += [(f'axis {a}', run.power_meas_w[:, j], run.power_sim_w[:, j])
                   for j, a in enumerate(run.axes)]
    fig = Figure(figsize=(10, 2.2 + 2.0 * len(panels)), layout='constrained')
    axs = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (label, meas, sim) in zip(axs, panels):
        ax.plot(run.t, meas, **_MEAS)
        ax.plot(run.t, sim, **_SIM)
        ax.set_ylabel(f'power [W]\n{label}')
        ax.grid(True, alpha=0.3)
    axs[0].legend(loc='upper right')
    axs[-1].set_xlabel('time [s]')
    fig.suptitle(f'{_title(run, "actual power")}\n{_offset_note(run)}', fontsize=10)
    return figure_png(fig, dpi=dpi)


def plot_energy(run: RunComparison, *, dpi: int = 100) -> bytes:
    """Consumed energy over time, measured vs simulated (Fig 7 kind); returns PNG bytes."""
    e_meas = run.energy_meas_j()
    e_sim = run.energy_sim_j()
    fig = Figure(figsize=(10, 4.2), layout='constrained')
    ax = fig.subplots()
    ax.plot(run.t, e_meas, **_MEAS)
    ax.plot(run.t, e_sim, **_SIM)
    m = run.metrics
    pct = f'{m.energy_error_pct:+.1f} %' if np.isfinite(m.energy_error_pct) else 'n/a'
    ax.set_title(f'at the end: measured {m.energy_meas_j:.1f} J, simulated '
                 f'{m.energy_sim_j:.1f} J, error {m.energy_error_j:+.1f} J ({pct})',
                 fontsize=9)
    ax.set_xlabel('time [s]')
    ax.set_ylabel('energy [J]')
    ax.grid(True, alpha=0.3)
    ax.legend(loc='upper left')
    what = 'consumed energy' + (f' (sum of {", ".join(run.axes)})' if len(run.axes) > 1 else '')
    fig.suptitle(_title(run, what), fontsize=10)
    return figure_png(fig, dpi=dpi)


def plot_error(run: RunComparison, *, dpi: int = 100) -> bytes:
    """Differential [W] and percentual [%] error over time (Fig 8 kind); returns PNG bytes."""
    meas = run.total_meas_w
    diff = meas - run.total_sim_w
    m = run.metrics
    above = (np.abs(meas) >= m.pct_floor_w) & (np.abs(meas) > 0.0)
    pct = np.full(meas.shape, np.nan)
    pct[above] = 100.0 * np.abs(diff[above]) / np.abs(meas[above])
    fig = Figure(figsize=(10, 5.6), layout='constrained')
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(run.t, diff, color='#5f3dc4', lw=1.0, label='P_meas - P_sim')
    ax1.axhline(0.0, color='k', lw=0.6)
    for sign in (1.0, -1.0):
        ax1.axhline(sign * m.avg_diff_error_w, color='#2b8a3e', lw=0.9, ls=':',
                    label=f'± average |dP| = {m.avg_diff_error_w:.2f} W' if sign > 0 else None)
    ax1.set_ylabel('differential error [W]')
    ax1.legend(loc='upper right', fontsize=8)
    ax1.grid(True, alpha=0.3)
    ax2.plot(run.t, pct, color='#c92a2a', lw=1.0, marker='.', ms=2.5,
             label=f'100 |dP| / |P_meas| where |P_meas| ≥ {m.pct_floor_w:.3g} W')
    if np.isfinite(m.avg_pct_error_pct):
        ax2.axhline(m.avg_pct_error_pct, color='#2b8a3e', lw=0.9, ls=':',
                    label=f'average {m.avg_pct_error_pct:.2f} %')
    limit, above = pct_scale(pct)
    if above:
        over = np.isfinite(pct) & (pct > limit)
        ax2.plot(run.t[over], np.full(above, limit), '^', color='#c92a2a', ms=5, clip_on=False,
                 label=f'{above} sample{"s" if above > 1 else ""} above the scale (up to '
                       f'{np.nanmax(pct):.0f} %); scale ends at 1.1 x the '
                       f'{PCT_SCALE_PERCENTILE:g}th percentile')
    ax2.set_ylabel('percentual error [%]')
    ax2.set_xlabel('time [s]')
    ax2.set_ylim(0.0, limit)
    ax2.legend(loc='best', fontsize=8)
    ax2.grid(True, alpha=0.3)
    what = 'differential and percentual error'
    if len(run.axes) > 1:
        what += f' (sum of {", ".join(run.axes)})'
    fig.suptitle(f'{_title(run, what)}\n{_offset_note(run)}', fontsize=10)
    return figure_png(fig, dpi=dpi)


def plot_signal(run: RunComparison, *, dpi: int = 100) -> bytes:
    """A drive trace (current, torque, force) measured vs simulated per axis; PNG bytes."""
    qty = quantity_of(run.measures)
    meas, sim = run.signal_meas, run.signal_sim
    if meas is None or sim is None:
        raise ValueError(f'run {run.name!r} carries no trace')
    fig = Figure(figsize=(10, 2.2 + 2.0 * len(run.axes)), layout='constrained')
    axs = fig.subplots(len(run.axes), 1, sharex=True, squeeze=False)[:, 0]
    for j, (ax, a) in enumerate(zip(axs, run.axes)):
        ax.plot(run.t, meas[:, j], **_MEAS)
        ax.plot(run.t, sim[:, j], **_SIM)
        m = run.signal_metrics.get(a)
        note = '' if m is None else f'\nRMSE {m.rmse:.3g} {qty.unit}, R² {m.r2:.3f}'
        ax.set_ylabel(f'{qty.name} [{qty.unit}]\naxis {a}{note}')
        ax.grid(True, alpha=0.3)
    axs[0].legend(loc='upper right')
    axs[-1].set_xlabel('time [s]')
    fig.suptitle(f'{_title(run, qty.words)}\nsimulation shifted by {run.offset_used_s:+.3f} s '
                 f'(offset {run.offset.status})', fontsize=10)
    return figure_png(fig, dpi=dpi)


def run_plots(run: RunComparison, *, dpi: int = 100) -> dict[str, bytes]:
    """The plots of one run: kind -> PNG bytes (``signal`` for a drive trace, then
    :data:`PLOT_KINDS` in order)."""
    kinds = PLOT_KINDS if quantity_of(run.measures).is_power else ('signal',) + PLOT_KINDS
    # looked up by name at call time, so a test can replace one
    return {kind: globals()[f'plot_{kind}'](run, dpi=dpi) for kind in kinds}
