"""Report of ``analyze``: residual vs states, residual spectrum, before/after courses, tables.

Agg canvas only (no pyplot). Files: ``residual_states.png`` (residual before and after
against velocity, position, acceleration and time, every measured axis), ``spectrum.png``
(run-averaged residual spectrum before and after), ``NN_<run>_after.png`` per held-out run
(measured, simulated before and after, and both errors), ``index.html``.
"""
from __future__ import annotations

from html import escape
import os
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np

from feed_axis_energy.core.identify.analyze import AnalysisResult, STATE_NAMES

from . import _stem, staged_report
from .html import METRIC_ROWS

__all__ = ['write_analyze_report']

_UNITS = {'velocity': 'm/s', 'position': 'm', 'acceleration': 'm/s²', 'time': 's'}


def _save(fig: Figure, path: Path, dpi: int) -> None:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=dpi)


def _residual_states(res: AnalysisResult, path: Path, dpi: int) -> None:
    k = len(res.axes)
    fig = Figure(figsize=(12, 3.0 * k + 0.8), layout='constrained')
    axs = fig.subplots(k, len(STATE_NAMES), squeeze=False)
    for j, axis in enumerate(res.axes):
        for i, name in enumerate(STATE_NAMES):
            ax = axs[j, i]
            x = np.concatenate([r.states[name][:, j] for r in res.runs])
            yb = np.concatenate([r.residual_before_w[:, j] for r in res.runs])
            ya = np.concatenate([r.residual_after_w[:, j] for r in res.runs])
            ax.plot(x, yb, '.', ms=1.5, color='#c92a2a', alpha=0.4, label='before')
            ax.plot(x, ya, '.', ms=1.5, color='#1f4e9a', alpha=0.4, label='after')
            ax.axhline(0.0, color='k', lw=0.6)
            ax.set_xlabel(f'{name} [{_UNITS[name]}]')
            ax.grid(True, alpha=0.3)
            if i == 0:
                ax.set_ylabel(f'residual [W], axis {axis}')
    axs[0, 0].legend(loc='best', markerscale=6, fontsize=8)
    fig.suptitle('residual = measured - simulated power, against the state '
                 '(after: selected effects fitted on all runs)', fontsize=10)
    _save(fig, path, dpi)


def _spectrum(res: AnalysisResult, path: Path, dpi: int) -> None:
    fig = Figure(figsize=(10, 3.2 * len(res.axes) + 0.6), layout='constrained')
    axs = fig.subplots(len(res.axes), 1, squeeze=False)[:, 0]
    for ax, axis in zip(axs, res.axes):
        f, before, after = res.spectra.get(axis, (np.zeros(0),) * 3)
        if f.size > 1:
            ax.semilogy(f[1:], before[1:], color='#c92a2a', lw=1.0, label='before')
            ax.semilogy(f[1:], after[1:], color='#1f4e9a', lw=1.0, label='after')
        ax.set_ylabel(f'power spectrum [W²]\naxis {axis}')
        ax.grid(True, alpha=0.3)
        ax.legend(loc='upper right')
    axs[-1].set_xlabel('frequency [Hz]')
    fig.suptitle('residual spectrum (Welch, averaged over runs)', fontsize=10)
    _save(fig, path, dpi)


def _run_plot(run, path: Path, dpi: int) -> None:
    fig = Figure(figsize=(10, 5.6), layout='constrained')
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(run.t, run.meas_w, color='#222', lw=1.0, label='measured')
    ax1.plot(run.t, run.sim_w, color='#d9480f', lw=1.0, ls='--', label='before (declared)')
    ax1.plot(run.t, run.after_w, color='#1f4e9a', lw=1.0, ls=':', label='after (held out)')
    ax1.set_ylabel('power [W]')
    ax1.legend(loc='upper right', fontsize=8)
    ax1.grid(True, alpha=0.3)
    ax2.plot(run.t, run.meas_w - run.sim_w, color='#d9480f', lw=0.9, label='before')
    ax2.plot(run.t, run.meas_w - run.after_w, color='#1f4e9a', lw=0.9, label='after')
    ax2.axhline(0.0, color='k', lw=0.6)
    ax2.set_ylabel('measured - simulated [W]')
    ax2.set_xlabel('time [s]')
    ax2.legend(loc='upper right', fontsize=8)
    ax2.grid(True, alpha=0.3)
    fig.suptitle(f'{run.name}: load {run.load_kg:g} kg; avg percentual error '
                 f'{run.before.avg_pct_error_pct:.2f} % -> {run.after.avg_pct_error_pct:.2f} %',
                 fontsize=10)
    _save(fig, path, dpi)


def _num(v, fmt: str) -> str:
    return '&ndash;' if v is None or not np.isfinite(v) else format(v, fmt)


def _bound(at_bound: str | None) -> str:
    return '' if at_bound is None else f' (on its {escape(at_bound)} bound)'


def _html(res: AnalysisResult, run_images: dict[str, str]) -> str:
    cols = [('all held-out', res.before, res.after)] + [
        (f'{load:g} kg', b, a) for load, b, a in res.by_load()]
    head = ''.join(f'<th colspan="2">{escape(c)}</th>' for c, _, _ in cols)
    sub = ''.join('<th>before</th><th>after</th>' for _ in cols)
    rows = [f'<tr><th></th>{head}</tr>', f'<tr><th>metric</th>{sub}</tr>']
    for label, attr, fmt in METRIC_ROWS:
        cells = ''.join(f'<td class="num">{_num(getattr(b, attr), fmt)}</td>'
                        f'<td class="num">{_num(getattr(a, attr), fmt)}</td>'
                        for _, b, a in cols)
        rows.append(f'<tr><th style="text-align:left">{escape(label)}</th>{cells}</tr>')
    table = '<table>' + '\n'.join(rows) + '</table>'
    eff = ['<tr><th>effect</th><th>axis</th><th>parameter</th><th>value</th><th>&plusmn;</th>'
           '<th>unit</th><th>share of structured residual</th><th>held-out gain</th>'
           '<th>aliases</th></tr>']
    for e in res.effects:
        for p in e.params:
            eff.append(f'<tr><td>{escape(e.id)}</td><td>{escape(e.axis)}</td>'
                       f'<td>{escape(p.name)}</td><td class="num">{p.value:.5g}</td>'
                       f'<td class="num">{_num(p.uncertainty, ".3g")}</td>'
                       f'<td>{escape(p.unit)}</td>'
                       f'<td class="num">{100 * e.share_of_structured:.1f} %</td>'
                       f'<td class="num">{100 * e.heldout_gain_rel:.1f} %</td>'
                       f'<td>{escape(", ".join(e.aliases))}</td></tr>')
    effects = ('<table>' + '\n'.join(eff) + '</table>' if res.effects
               else '<p>No effect added.</p>')
    unexpl = ''.join(f'<li><b>{escape(u["diagnostic"])}</b>: {escape(u["message"])}</li>'
                     for u in res.unexplained) or '<li>none</li>'
    fates = ''.join(f'<tr><td>{escape(f.effect)}</td><td>{escape(f.axis)}</td>'
                    f'<td>{escape(f.fate)}</td>'
                    f'<td class="num">{_num(100 * f.heldout_gain_rel, ".2f")}</td>'
                    f'<td>{escape(f.reason)}</td></tr>' for f in res.candidates)
    diag = ''.join(f'<tr><td>{escape(d.axis)}</td><td>{escape(d.name)}</td>'
                   f'<td>{"yes" if d.structured else "no"}</td><td>{escape(d.message)}</td></tr>'
                   for d in res.diagnostics_after)
    runs = ''.join(f'<h3>{escape(name)}</h3><p><img src="{escape(f)}" alt="{escape(name)}"></p>'
                   for name, f in run_images.items())
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>analyze: {escape(res.campaign)}</title>
<style>body {{ font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1150px; }}
table {{ border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.9em; }}
th, td {{ border: 1px solid #ccc; padding: 0.25em 0.6em; }} th {{ background: #f1f3f5; }}
td.num {{ text-align: right; }} img {{ max-width: 100%; }}</style></head><body>
<h1>Residual analysis: {escape(res.campaign)}</h1>
<p>Manifest {escape(res.manifest)}; machine {escape(res.machine.name)}; held out:
{escape(res.holdout)}. <b>{escape(res.status)}</b>: {escape(res.message)}</p>
<h2>Effects</h2>{effects}
<h2>Unexplained structure</h2><ul>{unexpl}</ul>
<h2>Every candidate</h2>
<p>Consistency loop: {res.rounds} round(s){', cap reached' if res.cap_reached else ''}.</p>
<table><tr><th>effect</th><th>axis</th><th>fate</th><th>held-out gain [%]</th><th>reason</th>
</tr>{fates}</table>
<h2>Before / after on held-out runs</h2>{table}
<h2>Residual diagnostics (after)</h2>
<table><tr><th>axis</th><th>test</th><th>structure</th><th>detail</th></tr>{diag}</table>
<p><img src="residual_states.png" alt="residual vs states"></p>
<p><img src="spectrum.png" alt="residual spectrum"></p>
<h2>Runs</h2>{runs}
</body></html>
"""


def write_analyze_report(res: AnalysisResult, out_dir: str | os.PathLike[str], *,
                         dpi: int = 90, force: bool = False) -> Path:
    """Write the plots and ``index.html`` into ``out_dir`` (all or nothing); return the page.

    ``force`` replaces an earlier report (or an empty directory) in ``out_dir``.

    Raises
    ------
    OutputError
        If ``out_dir`` must not be written (see :func:`.staged_report`).
    """
    out = Path(out_dir)
    with staged_report(out, written_by='feed-axis-energy analyze --report',
                       force=force) as tmp:
        _residual_states(res, tmp / 'residual_states.png', dpi)
        _spectrum(res, tmp / 'spectrum.png', dpi)
        images = {}
        for i, run in enumerate(res.heldout_runs):
            name = f'{_stem(i, run.name)}_after.png'
            _run_plot(run, tmp / name, dpi)
            images[run.name] = name
        (tmp / 'index.html').write_text(_html(res, images), encoding='utf-8')
    return out / 'index.html'
