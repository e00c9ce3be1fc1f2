"""The report's ``index.html``: summary tables first, then one section per run with its plots."""
from __future__ import annotations

from html import escape
import math

from feed_axis_energy.core.measured.compare import CampaignComparison, RunComparison
from feed_axis_energy.core.measured.metrics import Metrics

__all__ = ['METRIC_ROWS', 'render_index']

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

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; }
th { background: #f1f3f5; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.warn td { background: #fff4e6; }
.status-ok { color: #2b8a3e; } .status-weak, .status-edge, .status-ambiguous { color: #c92a2a; }
img { max-width: 100%; border: 1px solid #eee; margin: 0.3em 0; }
section { border-top: 2px solid #dee2e6; margin-top: 2em; }
.note { color: #555; font-size: 0.9em; }
"""


def _num(value: float, fmt: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return '&ndash;'
    return format(value, fmt)


def _td(value: float, fmt: str) -> str:
    return f'<td class="num">{_num(value, fmt)}</td>'


def _status(run: RunComparison) -> str:
    s = escape(run.offset.status)
    return f'<span class="status-{s}" title="{escape(run.offset.message)}">{s}</span>'


def _summary_table(cmp: CampaignComparison) -> str:
    head = ['run', 'role', 'load [kg]', 'offset found [s]', 'status', 'offset used [s]']
    head += [label for label, _, _ in METRIC_ROWS]
    rows = []
    for r in cmp.runs:
        m = r.metrics
        cls = '' if r.offset.status in ('ok', 'fixed') else ' class="warn"'
        cells = [f'<td><a href="#{_anchor(r.name)}">{escape(r.name)}</a></td>',
                 f'<td>{escape(r.role or "")}</td>', _td(r.load_kg, 'g'),
                 _td(r.offset.offset_s, '+.3f'), f'<td>{_status(r)}</td>',
                 _td(r.offset_used_s, '+.3f')]
        cells += [_td(getattr(m, attr), fmt) for _, attr, fmt in METRIC_ROWS]
        rows.append(f'<tr{cls}>{"".join(cells)}</tr>')
    ths = ''.join(f'<th>{escape(h)}</th>' for h in head)
    return f'<table><tr>{ths}</tr>\n' + '\n'.join(rows) + '\n</table>'


def _metrics_by_column(columns: list[tuple[str, Metrics]], first: str) -> str:
    """Rows = metrics (the paper's Table-1 layout), columns = the given metrics sets."""
    ths = f'<th>{escape(first)}</th>' + ''.join(f'<th>{escape(c)}</th>' for c, _ in columns)
    rows = [f'<tr>{ths}</tr>']
    for label, attr, fmt in METRIC_ROWS:
        cells = ''.join(_td(getattr(m, attr), fmt) for _, m in columns)
        rows.append(f'<tr><th style="text-align:left">{escape(label)}</th>{cells}</tr>')
    counts = ''.join(f'<td class="num">{m.n_samples} / {m.n_pct_samples}</td>'
                     for _, m in columns)
    rows.append(f'<tr><th style="text-align:left">samples / above the % floor</th>{counts}</tr>')
    return '<table>' + '\n'.join(rows) + '</table>'


def _anchor(name: str) -> str:
    return 'run-' + ''.join(c if c.isalnum() or c in '-_' else '_' for c in name)


def _run_section(r: RunComparison, images: dict[str, str]) -> str:
    columns = [('sum of ' + ', '.join(r.axes) if len(r.axes) > 1 else r.axes[0], r.metrics)]
    if len(r.axes) > 1:
        columns += [(f'axis {a}', r.axis_metrics[a]) for a in r.axes]
    prov = [
        ('data file', r.data_file),
        ('motion from', r.motion_source),
        ('load', f'{r.load_kg:g} kg'),
        ('role', r.role or '-'),
        ('rows excluded by the manifest filter', str(r.excluded_rows)),
        ('measured / simulated duration',
         f'{r.t[-1] - r.t[0]:.2f} s / {r.sim_duration_s:.2f} s'),
        ('measuring interval (averaging window)', f'{r.window_s * 1e3:.1f} ms'),
        ('offset', f'found {r.offset.offset_s:+.4f} s, used {r.offset_used_s:+.4f} s, '
                   f'status {r.offset.status}: {r.offset.message}'),
        ('percentual-error floor', f'{r.metrics.pct_floor_w:.3g} W'),
    ]
    prov_rows = ''.join(f'<tr><th style="text-align:left">{escape(k)}</th>'
                        f'<td>{escape(v)}</td></tr>' for k, v in prov)
    imgs = ''.join(f'<p><a href="{escape(f)}"><img src="{escape(f)}" alt="{escape(r.name)} '
                   f'{escape(kind)}"></a></p>' for kind, f in images.items())
    return (f'<section id="{_anchor(r.name)}"><h2>Run {escape(r.name)} '
            f'(load {r.load_kg:g} kg)</h2>\n<table>{prov_rows}</table>\n'
            f'{_metrics_by_column(columns, "metric")}\n{imgs}</section>')


def render_index(cmp: CampaignComparison, images: dict[str, dict[str, str]]) -> str:
    """Return the HTML page.

    Parameters
    ----------
    cmp
        The campaign comparison.
    images
        Run name -> {plot kind -> PNG file name relative to the page}.

    Returns
    -------
    str
        A complete, self-styled HTML document.
    """
    groups = [(f'{g.load_kg:g} kg ({len(g.runs)} run{"s" if len(g.runs) != 1 else ""})',
               g.metrics) for g in cmp.groups]
    warnings = ''.join(f'<li>{escape(w)}</li>' for w in cmp.offset_warnings)
    warn_html = (f'<p><b>Offset warnings</b> (compared anyway):</p><ul>{warnings}</ul>'
                 if warnings else '')
    sections = '\n'.join(_run_section(r, images.get(r.name, {})) for r in cmp.runs)
    machine = escape(cmp.machine) + (f' ({escape(cmp.machine_file)})' if cmp.machine_file
                                     else '')
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>Measured vs simulated power: {escape(cmp.campaign)}</title>
<style>{_CSS}</style></head>
<body>
<h1>Measured vs simulated power: {escape(cmp.campaign)}</h1>
<p class="note">Manifest {escape(cmp.manifest)}; machine {machine}; offset searched within
&plusmn;{cmp.max_lag_s:g} s. Simulated power is averaged over each measuring interval and
shifted by the offset used. Percentual errors are taken only where |P_meas| is above a floor
(a fraction of the run's peak, given per run). Metrics are of the sum of the measured axes.</p>
<h2>Per load (the paper's Table 1 layout)</h2>
{_metrics_by_column(groups, 'load')}
<h2>Per run</h2>
{_summary_table(cmp)}
{warn_html}
{sections}
</body></html>
"""
