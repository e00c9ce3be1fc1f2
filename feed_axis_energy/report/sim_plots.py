"""The plots of ``simulate --report``, drawn from a decimated :class:`.decimate.Trace`.

Power is drawn as the band between the smallest and largest value of every time column, so a
peak of a single sample stays visible however long the program. Agg canvas only (no pyplot).
"""
from __future__ import annotations

from collections.abc import Sequence

from matplotlib.figure import Figure
import numpy as np

from .decimate import Trace
from .page import figure_png, short

__all__ = ['plot_bbox_path', 'plot_blocks', 'plot_causes', 'plot_energy', 'plot_power']

_COLOURS = ('#1f4e9a', '#d9480f', '#2b8a3e', '#862e9c', '#e67700', '#0b7285')
_TOTAL = '#222222'


def _band(ax, tr: Trace, j: int, colour: str, label: str) -> None:
    """Min/max envelope of power column ``j``: a vertical stroke per time column."""
    x = np.repeat(0.5 * (tr.t_lo + tr.t_hi), 2)
    y = np.empty(x.shape)
    y[0::2] = tr.p_min[:, j]
    y[1::2] = tr.p_max[:, j]
    ax.plot(x, y, color=colour, lw=0.8, label=label)


def plot_power(tr: Trace, blocks: Sequence[tuple[int, str]], *, dpi: int = 100) -> bytes:
    """Total power (top, with the given blocks labelled at their peak) and power per axis.

    Parameters
    ----------
    tr
        The decimated series.
    blocks
        ``(line, text)`` of the blocks to label (the most energetic ones).
    dpi
        Resolution.

    Returns
    -------
    bytes
        PNG.
    """
    k = len(tr.axes)
    fig = Figure(figsize=(10, 6.4), layout='constrained')
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    _band(ax1, tr, k, _TOTAL, 'total')
    ax1.set_ylabel('total power [W]')
    for n, (line, _text) in enumerate(blocks):
        at = np.flatnonzero(tr.line_at_peak == line)
        if at.size == 0:
            continue
        i = at[np.argmax(tr.p_max[at, k])]
        ax1.annotate(f'L{line}', (0.5 * (tr.t_lo[i] + tr.t_hi[i]), tr.p_max[i, k]),
                     xytext=(4, 4 + 9 * (n % 3)), textcoords='offset points', fontsize=8,
                     color='#c92a2a', arrowprops=dict(arrowstyle='-', color='#c92a2a', lw=0.6))
    for j, axis in enumerate(tr.axes):
        _band(ax2, tr, j, _COLOURS[j % len(_COLOURS)], f'axis {axis}')
    ax2.set_ylabel('power per axis [W]')
    ax2.set_xlabel('time [s]')
    if tr.axes:
        ax2.legend(loc='upper right', fontsize=8)
    for ax in (ax1, ax2):
        ax.axhline(0.0, color='k', lw=0.5)
        ax.grid(True, alpha=0.3)
    fig.suptitle('drawn power over time (band: smallest to largest value per time column; '
                 'Ln: source line at its peak)', fontsize=10)
    return figure_png(fig, dpi=dpi)


def plot_energy(tr: Trace, *, dpi: int = 100) -> bytes:
    """Cumulative energy per axis and total over time; returns PNG bytes."""
    fig = Figure(figsize=(10, 4.0), layout='constrained')
    ax = fig.subplots()
    k = len(tr.axes)
    ax.plot(tr.t_hi, tr.e_end[:, k], color=_TOTAL, lw=1.4, label='total')
    for j, axis in enumerate(tr.axes):
        ax.plot(tr.t_hi, tr.e_end[:, j], color=_COLOURS[j % len(_COLOURS)], lw=1.0,
                label=f'axis {axis}')
    ax.set_xlabel('time [s]')
    ax.set_ylabel('energy since the start [J]')
    ax.grid(True, alpha=0.3)
    ax.legend(loc='upper left', fontsize=8)
    fig.suptitle('cumulative energy', fontsize=10)
    return figure_png(fig, dpi=dpi)


def plot_blocks(rows: Sequence[tuple[int, str, float]], *, title: str,
                dpi: int = 100) -> bytes:
    """Horizontal bars of energy [J], largest on top, labelled ``Lline text``.

    ``rows`` are ``(line, text, energy_j)`` in the order to draw (largest first).
    """
    n = max(len(rows), 1)
    fig = Figure(figsize=(10, 1.2 + 0.28 * n), layout='constrained')
    ax = fig.subplots()
    labels = [f'L{line}  {short(text, 44)}' for line, text, _ in rows]
    values = [e for _, _, e in rows]
    y = np.arange(len(rows))
    colours = ['#1f4e9a' if v >= 0 else '#2b8a3e' for v in values]
    ax.barh(y, values, color=colours)
    ax.set_yticks(y, labels, fontsize=8, family='monospace')
    ax.invert_yaxis()
    ax.axvline(0.0, color='k', lw=0.5)
    ax.set_xlabel('energy [J]')
    ax.grid(True, axis='x', alpha=0.3)
    fig.suptitle(title, fontsize=10)
    return figure_png(fig, dpi=dpi)


def plot_causes(rows: Sequence[tuple[str, float]], *, dpi: int = 100) -> bytes:
    """Horizontal bars of energy [J] by cause (negative: returned); returns PNG bytes."""
    n = max(len(rows), 1)
    fig = Figure(figsize=(8, 1.2 + 0.35 * n), layout='constrained')
    ax = fig.subplots()
    y = np.arange(len(rows))
    values = [e for _, e in rows]
    ax.barh(y, values, color=['#d9480f' if v >= 0 else '#2b8a3e' for v in values])
    ax.set_yticks(y, [short(name, 40) for name, _ in rows], fontsize=8)
    ax.invert_yaxis()
    ax.axvline(0.0, color='k', lw=0.5)
    ax.set_xlabel('energy [J]')
    ax.grid(True, axis='x', alpha=0.3)
    fig.suptitle('energy by cause', fontsize=10)
    return figure_png(fig, dpi=dpi)


def plot_bbox_path(tr: Trace, *, dpi: int = 100) -> bytes:
    """The path seen from above (first two axes; and first against third when there are
    three or more), coloured by the total power at each time column's peak, with the
    program's bounding box; one axis: position over time. Positions in mm."""
    k = len(tr.axes)
    if k == 0 or tr.t_lo.shape[0] == 0:
        fig = Figure(figsize=(10, 1.5), layout='constrained')
        fig.text(0.5, 0.5, 'no samples: no path to draw', ha='center', va='center')
        return figure_png(fig, dpi=dpi)
    mm = 1e3 * tr.pos_at_peak
    colour = tr.p_max[:, k]
    lo, hi = 1e3 * tr.pos_min, 1e3 * tr.pos_max
    if k >= 2:
        views = [(0, 1)] + ([(0, 2)] if k >= 3 else [])
        fig = Figure(figsize=(10, 4.8), layout='constrained')
        axs = fig.subplots(1, len(views), squeeze=False)[0]
        sc = None
        for ax, (a, b) in zip(axs, views):
            ax.plot(mm[:, a], mm[:, b], color='#adb5bd', lw=0.5, zorder=1)
            sc = ax.scatter(mm[:, a], mm[:, b], c=colour, s=4, cmap='viridis', zorder=2)
            ax.add_patch(_rect(lo[a], lo[b], hi[a], hi[b]))
            ax.set_xlabel(f'{tr.axes[a]} [mm]')
            ax.set_ylabel(f'{tr.axes[b]} [mm]')
            ax.set_aspect('equal', adjustable='datalim')
            ax.grid(True, alpha=0.3)
        fig.colorbar(sc, ax=list(axs), label='total power [W]', shrink=0.9)
    else:
        fig = Figure(figsize=(10, 3.6), layout='constrained')
        ax = fig.subplots()
        t = 0.5 * (tr.t_lo + tr.t_hi)
        sc = ax.scatter(t, mm[:, 0], c=colour, s=4, cmap='viridis')
        for v in (lo[0], hi[0]):
            ax.axhline(v, color='#c92a2a', lw=0.7, ls='--')
        ax.set_xlabel('time [s]')
        ax.set_ylabel(f'{tr.axes[0]} [mm]' if tr.axes else 'position [mm]')
        ax.grid(True, alpha=0.3)
        fig.colorbar(sc, ax=ax, label='total power [W]')
    fig.suptitle('path coloured by power (dashed: bounding box)', fontsize=10)
    return figure_png(fig, dpi=dpi)


def _rect(x0: float, y0: float, x1: float, y1: float):
    from matplotlib.patches import Rectangle
    return Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ls='--', lw=0.8,
                     edgecolor='#c92a2a', zorder=3)
