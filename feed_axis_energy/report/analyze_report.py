"""Report of ``analyze``: residual vs states, residual spectrum, before/after courses, tables.

Agg canvas only (no pyplot). Files: ``residual_states.png`` (residual before and after
against velocity, position, acceleration and time, every measured axis), ``spectrum.png``
(run-averaged residual spectrum before and after), ``NN_<run>_after.png`` per held-out run
(measured, simulated before and after, and both errors), ``index.html`` (one line
answering first, plain words before the statistics, which sit in a details section; every
image embedded as well, so the page alone opens offline).
"""
from __future__ import annotations

from html import escape
import math
import os
from pathlib import Path

from matplotlib.figure import Figure
import numpy as np

from feed_axis_energy.identify import AnalysisResult, found_text, STATE_NAMES

from .staging import report_stem, staged_report
from .html import METRIC_ROWS
from .page import figure_png, fmt_pct, img, page, short, table

__all__ = ['analyze_answer', 'write_analyze_report']

_UNITS = {'velocity': 'm/s', 'position': 'm', 'acceleration': 'm/s²', 'kinetic_power': 'W/kg',
          'time': 's'}


def _save(fig: Figure, path: Path, dpi: int) -> bytes:
    """Write ``fig`` to ``path`` as PNG; return the bytes (embedded in the page too)."""
    png = figure_png(fig, dpi=dpi)
    path.write_bytes(png)
    return png


def _residual_states(res: AnalysisResult, path: Path, dpi: int) -> bytes:
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
    return _save(fig, path, dpi)


def _spectrum(res: AnalysisResult, path: Path, dpi: int) -> bytes:
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
    return _save(fig, path, dpi)


def _run_plot(run, path: Path, dpi: int) -> bytes:
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
    return _save(fig, path, dpi)


def _num(v, fmt: str) -> str:
    return '&ndash;' if v is None or not np.isfinite(v) else format(v, fmt)


_HOLDOUT_WORDS = {
    'loro': 'each run is predicted by a model fitted on the other runs only '
            '(leave-one-run-out)',
    'roles': 'the model is fitted on the calibration runs and scored on the validation runs',
}


def analyze_answer(res: AnalysisResult) -> str:
    """The one-line answer: what was added and how much better runs not fitted on got."""
    added = found_text(res.effects, res.ambiguous)
    what = f'Added {escape(short(added, 120))}' if res.effects else 'No effect added'
    if res.offered:
        shape = ' + '.join(f'{e.id} on {e.axis}' for e in res.offered)
        what += (f'{"; offered" if res.effects else ", but offered"} a loss of the shape of '
                 f'{escape(short(shape, 120))} that the data do not attribute to one effect')
    before, after = res.before.avg_pct_error_pct, res.after.avg_pct_error_pct
    text = (f'{what}: on runs the fit did not see, the power error goes from '
            f'<b>{fmt_pct(before)}</b> to <b>{fmt_pct(after)}</b> on average')
    if res.unexplained:
        text += '; some structure is left that no known effect explains'
    return text + '.'


def _bound(at_bound: str | None) -> str:
    return '' if at_bound is None else f' (on its {escape(at_bound)} bound)'


def _effect_table(effects, min_share: float) -> str:
    rows = []
    for e in sorted(effects, key=lambda e: -e.energy_share if math.isfinite(e.energy_share)
                    else 0.0):
        size = (fmt_pct(100 * e.energy_share) if math.isfinite(e.energy_share) else '-')
        if not e.matters:
            size += f' (&lt; {100 * min_share:g} %)'
        for p in e.params:
            rows.append([escape(e.id), escape(e.axis), escape(p.name),
                         f'<td class="num">{p.value:.5g}{_bound(p.at_bound)}</td>',
                         f'<td class="num">{_num(p.uncertainty, ".3g")}</td>', escape(p.unit),
                         f'<td class="num">{size}</td>',
                         f'<td class="num">{fmt_pct(100 * e.heldout_gain_rel)}</td>',
                         escape(short(', '.join(e.aliases), 80))])
    return table(['effect', 'axis', 'parameter', 'value', '&plusmn;', 'unit',
                  'share of the energy', 'gain on unseen runs', 'could also be'], rows)


def _html(res: AnalysisResult, images: dict[str, bytes], run_images: dict[str, str]) -> str:
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
    metrics = '<div class="fit"><table>' + '\n'.join(rows) + '</table></div>'
    effects = (_effect_table(res.effects, res.min_share) if res.effects
               else '<p>No effect added.</p>')
    if res.offered:
        effects += ('<h3>Offered, not attributed</h3><p>A loss of this shape makes the '
                    'prediction better on unseen runs, but the data do not attribute it to '
                    'one effect (see "What is left unexplained"); it is in the augmented '
                    'machine file.</p>' + _effect_table(res.offered, res.min_share))
    if res.ambiguous:
        items = ''.join(
            f'<li>{escape(short(g.message, 400))}<ul>'
            + ''.join(f'<li>{escape(" + ".join(f.replaces))} = '
                      f'{escape(" + ".join(f.members))}: they differ by '
                      f'{fmt_pct(100 * f.relative_residual)} of its power (limit '
                      f'{fmt_pct(100 * f.limit)}, from the noise)</li>' for f in g.forms)
            + '</ul></li>' for g in res.ambiguous)
        effects += ('<p>The power of these effects has one shape that other forms of the '
                    'catalog reproduce within the noise: the data cannot tell which it is. '
                    'The effect listed above is one form (its fitted power is what counts), '
                    f'not a finding of that effect:</p><ol>{items}</ol>')
    unexpl = ''.join(f'<li><b>{escape(u["diagnostic"])}</b>: {escape(short(u["message"], 300))}'
                     f'</li>' for u in res.unexplained) or '<li>none</li>'
    fates = table(['effect', 'axis', 'fate', 'gain on unseen runs', 'why'],
                  [[escape(f.effect), escape(f.axis), escape(f.fate),
                    f'<td class="num">{fmt_pct(100 * f.heldout_gain_rel)}</td>',
                    escape(short(f.reason, 300))] for f in res.candidates])
    cap = ', its cap reached' if res.cap_reached else ''
    ranges = ''.join(f'<li>{escape(short(w, 300))}</li>' for w in res.warnings)
    ranges = (f'<h2>Used outside the calibrated range</h2><ul>{ranges}</ul>' if ranges else '')
    noise = escape('; '.join(f'{a} {n.sigma_w:.3g} W ({n.method}; sample-to-sample '
                             f'{n.white_w:.3g} W, correlation {n.correlation:.3g})'
                             for a, n in res.noise.items()) or 'not estimated')
    diag = table(['axis', 'test', 'pattern left', 'detail'],
                 [[escape(d.axis), escape(d.name), 'yes' if d.structured else 'no',
                   escape(short(d.message, 300))] for d in res.diagnostics_after])
    runs = ''.join(f'<h3>{escape(short(name))}</h3>'
                   + img(images[f], name, link=f) for name, f in run_images.items())
    body = f"""
<p>The residual is the measured power minus the simulated power. An effect of the catalog
is added only if it makes the prediction better on runs it was not fitted on: here
{_HOLDOUT_WORDS.get(res.holdout, escape(res.holdout))}. Machine
{escape(res.machine.name)}; <b>{escape(res.status)}</b>: {escape(short(res.message, 300))}</p>
<h2>Effects added</h2>{effects}
<h2>What is left unexplained</h2><ul>{unexpl}</ul>
<h2>Every candidate effect and its fate</h2>
<p>Selection rounds (each redone without effects that were inconsistent across runs):
{res.rounds}{cap}.</p>{fates}{ranges}
<h2>Before and after, on runs the fit did not see</h2>{metrics}
<h2>Residual against the state of the axis</h2>
{img(images['residual_states.png'], 'residual vs states', link='residual_states.png')}
<h2>Runs</h2>{runs}
<details><summary>Details: statistical tests and spectrum</summary>
<p class="note">Manifest {escape(short(res.manifest, 120))}. "Share of the energy" is
the energy of the effect's fitted power over the measured energy; an effect below
{100 * res.min_share:g} % is detected but does not matter at that threshold
(<code>--min-share</code>); "gain on
unseen runs" the relative drop of the mean squared error on held-out runs; the
&plusmn; values are jackknife uncertainties over runs. An effect is called inconsistent
across runs when refitting it per run explains much more than one set of parameters for all
runs and that improvement is significant against the noise (&chi;&sup2; test).</p>
<p class="note">Noise level every test uses, per axis: {noise}.</p>
<h3>Residual tests (after)</h3>{diag}
{img(images['spectrum.png'], 'residual spectrum', link='spectrum.png')}
</details>
"""
    return page(f'Residual analysis: {short(res.campaign)}', analyze_answer(res), body)


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
        png = {'residual_states.png': _residual_states(res, tmp / 'residual_states.png', dpi),
               'spectrum.png': _spectrum(res, tmp / 'spectrum.png', dpi)}
        images = {}
        for i, run in enumerate(res.heldout_runs):
            name = f'{report_stem(i, run.name)}_after.png'
            png[name] = _run_plot(run, tmp / name, dpi)
            images[run.name] = name
        html = _html(res, png, images)
        (tmp / 'index.html').write_text(html, encoding='utf-8')
    return out / 'index.html'
