"""The compare report's ``index.html``: the answer, summary tables, then one section per run.

Plots are embedded (``data:`` URIs), so the report is one file. Tables stay narrow enough for
a 1 000 px page: the per-run table holds what a reader compares across runs (energy, power
error, alignment status); the full Table-1 metrics and the alignment details are per run
and in a details section.
"""
from __future__ import annotations

from html import escape
import math

import numpy as np

from feed_axis_energy.measured import CampaignComparison, Metrics, quantity_of, RunComparison
from feed_axis_energy.physics import two_digits

from .page import fmt_duration, fmt_pct, fmt_si, img, page, short, table

__all__ = ['METRIC_ROWS', 'compare_answer', 'render_index']

# (label, attribute, format) - the paper's four Table-1 rows first
METRIC_ROWS: tuple[tuple[str, str, str], ...] = (
    ('Average differential error [W]', 'avg_diff_error_w', '.2f'),
    ('Average percentual error [%]', 'avg_pct_error_pct', '.2f'),
    ('Maximum differential error [W]', 'max_diff_error_w', '.2f'),
    ('Maximum percentual error [%]', 'max_pct_error_pct', '.2f'),
    ('Energy measured [J]', 'energy_meas_j', '.1f'),
    ('Energy simulated [J]', 'energy_sim_j', '.1f'),
    ('Energy error [J]', 'energy_error_j', '+.1f'),
    ('Energy error [%]', 'energy_error_pct', '+.2f'),
    ('RMSE [W]', 'rmse_w', '.2f'),
)


def _num(value: float, fmt: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return '&ndash;'
    return format(value, fmt)


def _td(text: str) -> str:
    return f'<td class="num">{text}</td>'


def _status(run: RunComparison) -> str:
    s = escape(run.offset.status)
    return f'<span class="status-{s}" title="{escape(short(run.offset.message, 200))}">{s}</span>'


def compare_answer(cmp: CampaignComparison) -> str:
    """The one-line answer: how close the simulated energy is, over all runs and at worst."""
    errs = [(r.name, r.metrics.energy_error_pct) for r in cmp.runs
            if math.isfinite(r.metrics.energy_error_pct)]
    if not errs:
        return 'No run could be compared (no energy measured).'
    mags = np.abs([e for _, e in errs])
    worst_name, worst = errs[int(np.argmax(mags))]
    pcts = [r.metrics.avg_pct_error_pct for r in cmp.runs
            if math.isfinite(r.metrics.avg_pct_error_pct)]
    n = len(cmp.runs)
    text = (f'Over {n} run{"s" if n != 1 else ""} the simulated energy is within '
            f'<b>{fmt_pct(float(mags.max()))}</b> of the measured energy (median '
            f'{fmt_pct(float(np.median(mags)))}; worst: run {escape(short(worst_name, 40))}, '
            f'{fmt_pct(worst, signed=True)})')
    if pcts:
        text += f'; the power differs by {fmt_pct(float(np.median(pcts)))} on average (median)'
    spread = [r.energy_sd_pct for r in cmp.runs if math.isfinite(r.energy_sd_pct)]
    if spread:
        text += (f'; ±{two_digits(float(np.median(spread)))} % of the simulated energy from the '
                 'loss-function uncertainty (median)')
    return text + '.'


def _summary_table(cmp: CampaignComparison) -> str:
    head = ['run', 'load', 'energy measured', 'energy simulated', 'energy error',
            'power error (average)', 'RMSE', 'time shift', 'alignment']
    rows, classes = [], []
    for r in cmp.runs:
        m = r.metrics
        rows.append([f'<a href="#{_anchor(r.name)}">{escape(short(r.name, 40))}</a>',
                     _td(f'{r.load_kg:g} kg'), _td(fmt_si(m.energy_meas_j, 'J')),
                     _td(fmt_si(m.energy_sim_j, 'J')),
                     _td(fmt_pct(m.energy_error_pct, signed=True)),
                     _td(fmt_pct(m.avg_pct_error_pct)), _td(fmt_si(m.rmse_w, 'W')),
                     _td(fmt_si(r.offset_used_s, 's', signed=True)), _status(r)])
        classes.append('' if r.offset.status in ('ok', 'fixed') else 'warn')
    return table(head, rows, classes=classes)


def _metrics_by_column(columns: list[tuple[str, Metrics]], first: str) -> str:
    """Rows = metrics (the paper's Table-1 layout), columns = the given metrics sets."""
    rows = []
    for label, attr, fmt in METRIC_ROWS:
        rows.append([escape(label)] + [_td(_num(getattr(m, attr), fmt)) for _, m in columns])
    rows.append(['samples / above the % floor']
                + [_td(f'{m.n_samples} / {m.n_pct_samples}') for _, m in columns])
    return table([escape(first)] + [escape(c) for c, _ in columns], rows, row_head=True)


def _anchor(name: str) -> str:
    return 'run-' + ''.join(c if c.isalnum() or c in '-_' else '_' for c in name)


def _run_section(r: RunComparison, images: dict[str, bytes]) -> str:
    columns = [('sum of ' + ', '.join(r.axes) if len(r.axes) > 1 else r.axes[0], r.metrics)]
    if len(r.axes) > 1:
        columns += [(f'axis {a}', r.axis_metrics[a]) for a in r.axes]
    prov = [
        ('data file', short(r.data_file, 100)),
        ('motion from', short(r.motion_source, 100)),
        ('load', f'{r.load_kg:g} kg'),
        ('role', r.role or '-'),
        ('rows excluded by the manifest filter', str(r.excluded_rows)),
        ('measured / simulated duration',
         f'{fmt_duration(r.t[-1] - r.t[0])} / {fmt_duration(r.sim_duration_s)}'),
        ('measuring interval (averaging window)', fmt_si(r.window_s, 's')),
        ('time shift (offset)', f'found {r.offset.offset_s:+.3f} s, used '
                                f'{r.offset_used_s:+.3f} s, status {r.offset.status}: '
                                f'{short(r.offset.message, 160)}'),
        ('percentual-error floor', fmt_si(r.metrics.pct_floor_w, 'W')),
    ]
    prov_rows = [[escape(k), escape(v)] for k, v in prov]
    imgs = ''.join(img(png, f'{r.name} {kind}') for kind, png in images.items())
    return (f'<section id="{_anchor(r.name)}"><h2>Run {escape(short(r.name))} '
            f'(load {r.load_kg:g} kg)</h2>\n{table([], prov_rows, row_head=True)}\n'
            f'{_signal_table(r)}{_metrics_by_column(columns, "metric")}\n{imgs}</section>')


def _signal_table(r: RunComparison) -> str:
    """A drive trace's agreement per axis in its own unit (empty for a power run)."""
    qty = quantity_of(r.measures)
    if qty.is_power:
        return ''
    u = qty.unit
    rows = [[escape(a), fmt_si(m.rms_meas, u), fmt_si(m.rmse, u), fmt_si(m.bias, u, signed=True),
             _num(m.r2, '.3f'), _num(m.correlation, '+.3f'),
             fmt_si((r.torque_per_unit or {}).get(a), 'N·m/' + u)]
            for a, m in r.signal_metrics.items()]
    note = (f'<p class="note">Measured {escape(qty.words)} [{u}] against the prediction '
            f'(motor torque / g); the Table-1 metrics below are in W via '
            f'{qty.symbol}·g·&omega;.</p>')
    return note + table(['axis', 'RMS measured', 'RMSE', 'bias (sim &minus; meas)', 'R²', 'r',
                         'g (torque per unit)'], rows) + '\n'


def render_index(cmp: CampaignComparison, images: dict[str, dict[str, bytes]]) -> str:
    """Return the HTML page.

    Parameters
    ----------
    cmp
        The campaign comparison.
    images
        Run name -> {plot kind -> PNG bytes}, embedded in the page.

    Returns
    -------
    str
        A complete, self-styled HTML document.
    """
    groups = [(f'{g.load_kg:g} kg ({len(g.runs)} run{"s" if len(g.runs) != 1 else ""})',
               g.metrics) for g in cmp.groups]
    warnings = ''.join(f'<li>{escape(short(w, 200))}</li>'
                       for w in cmp.offset_warnings + cmp.sign_warnings)
    what = 'Time-shift and sign warnings' if cmp.sign_warnings else 'Time-shift warnings'
    warn_html = (f'<p><b>{what}</b> (compared anyway):</p><ul>{warnings}</ul>'
                 if warnings else '')
    sections = '\n'.join(_run_section(r, images.get(r.name, {})) for r in cmp.runs)
    machine = escape(cmp.machine) + (f' ({escape(short(cmp.machine_file, 100))})'
                                     if cmp.machine_file else '')
    body = f"""
<p>Each measured run is compared with the simulation of the same motion on machine
{machine}. The simulated power is shifted in time to line up with the measurement (the
shift is searched within &plusmn;{cmp.max_lag_s:g} s) and averaged over each measuring
interval, as the instrument does. "Power error" is the average of 100 |measured &minus;
simulated| / |measured| where the measured power is above a floor (a fraction of the run's
peak, given per run); "energy error" compares the energy over the whole run. Figures are for
the sum of the measured axes.</p>
<h2>Per run</h2>
{_summary_table(cmp)}
{warn_html}
<h2>Per load (the paper's Table 1 layout)</h2>
{_metrics_by_column(groups, 'load')}
<details><summary>Details: manifest and method</summary>
<p class="note">Manifest {escape(short(cmp.manifest, 120))}. The time shift is found by
cross-correlating measured and simulated power; "alignment" is <i>ok</i> when the
correlation peak is clear, <i>weak</i> (compared at shift 0), <i>edge</i> (best shift at the
end of the search range) or <i>ambiguous</i> (another shift fits almost as well). The
percentual-error plots end their scale at 1.1 times the 99th percentile of their samples;
samples above it are drawn on the top edge and counted in the legend.</p></details>
{sections}
"""
    return page(f'Measured vs simulated power: {short(cmp.campaign)}', compare_answer(cmp),
                body)
