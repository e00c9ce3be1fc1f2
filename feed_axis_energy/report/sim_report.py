"""Report of ``simulate --report DIR``: one self-contained ``index.html`` plus its images.

The page embeds every plot as a ``data:`` URI (it opens offline as one file and prints on A4);
the same plots are written beside it as PNG files. Inputs are plain data: the summary dict of
:func:`feed_axis_energy.sim.simulate.summarize`, a :class:`.decimate.PowerTrace` fed with the
simulation's chunks, and ``(line, energy_j, duration_s)`` per source line. The breakdown by
cause and the roll-ups per operation and tool are read from the summary through
:func:`causes_from_summary`, :func:`causes_by_axis` and :func:`rollups_from_summary`, the one
place that knows their keys (those the ``cause`` branch publishes); without them the page says
what it shows instead.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from html import escape
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from feed_axis_energy.physics import UNCERTAINTY_KEY, uncertainty_words
from feed_axis_energy.units import axis_units

from .staging import staged_report
from .decimate import PowerTrace, Trace
from .page import fmt_duration, fmt_pct, fmt_si, img, page, short, table
from .sim_plots import plot_bbox_path, plot_blocks, plot_causes, plot_energy, plot_power

__all__ = ['CAUSE_KEY', 'CAUSE_WORDS', 'GROSS_KEY', 'ROLLUP_KEY', 'causes_by_axis',
           'causes_from_summary', 'rollups_from_summary', 'top_lines', 'write_sim_report']

CAUSE_KEY = 'energy_by_cause_j'
"""Summary key of the breakdown by cause (branch ``cause``, ``/work/wt/notes/cause-api.md``):
``{cause: {axis: J, ..., 'total': J}}`` with the causes in the order of ``summary['causes']``;
for every axis and the total the causes add up to ``energy_j``. A plain ``{cause: J}`` is read
as the total."""

CAUSE_WORDS = {
    'friction': 'friction (passive resistance)',
    'screw': 'ball-screw efficiency loss',
    'gravity_lift': 'lifting against gravity',
    'gravity_lower': 'lowering with gravity',
    'linear_inertia': 'accelerating the moved mass (net)',
    'rotary_inertia': 'accelerating screw and rotor (net)',
    'braking_burned': 'braking energy burned in the resistor',
}
"""Plain words for the cause names; ``effect:<id>[:<axis>]`` reads "declared effect <id>"."""

ROLLUP_KEY = 'rollups'
"""Summary key of the roll-ups: ``{'operation': [...], 'subroutine': [...], 'tool': [...],
'axis': [...]}``, each a list of ``{'name', 'energy_j', 'duration_s'}``."""

GROSS_KEY = 'gross_by_cause_j'
"""Summary key of what each cause took before giving back: ``{cause: {axis: J, 'total': J}}``
(shown as a column when present)."""

_ROLLUP_SHOWN = ('operation', 'subroutine', 'tool')    # per axis: the page's first table


def _cause_words(name: str) -> str:
    if name.startswith('effect:'):
        parts = name.split(':')
        return f'declared effect {parts[1]}' + (f' on {parts[2]}' if len(parts) > 2 else '')
    return CAUSE_WORDS.get(name, name.replace('_', ' '))


def _cause_total(value: Any) -> float | None:
    if isinstance(value, Mapping):
        value = value.get('total')
    return float(value) if _finite(value) else None


def causes_from_summary(summary: Mapping[str, Any]
                        ) -> tuple[list[tuple[str, float, bool]], bool]:
    """Energy by cause ``[(cause in words, J, part of the total)]`` and whether it is the full
    breakdown (the parts add up to the total).

    With :data:`CAUSE_KEY`: every cause in the order of ``summary['causes']`` (else as
    stored). Without it, the two figures every summary has: the energy spent on passive
    resistance (the loss function) and the braking energy, negative when returned to the
    supply (regenerative braking), else burned in the brake resistor and not part of the
    total.
    """
    full = summary.get(CAUSE_KEY)
    if isinstance(full, Mapping) and full:
        order = [c for c in summary.get('causes') or () if c in full]
        order += [c for c in full if c not in order]
        rows = [(_cause_words(str(c)), _cause_total(full[c]), True) for c in order]
        return [r for r in rows if r[1] is not None], True
    rows = []
    if _finite(summary.get('loss_energy_j')):
        rows.append(('friction and passive resistance (loss function)',
                     float(summary['loss_energy_j']), True))
    braking = summary.get('regenerated_energy_j')
    if _finite(braking) and braking > 0:
        if summary.get('braking') == 'regenerative':
            rows.append(('braking energy returned to the supply', -float(braking), True))
        else:
            rows.append(('braking energy burned in the brake resistor (not in the total)',
                         float(braking), False))
    return rows, False


def causes_by_axis(summary: Mapping[str, Any]) -> tuple[list[str], list[list[float]]]:
    """Axis names and, per cause (order of :func:`causes_from_summary`), the energy per axis
    [J]; empty when the breakdown has no per-axis values."""
    full = summary.get(CAUSE_KEY)
    axes = [a for a in summary.get('energy_j', {}) if a != 'total']
    if not (isinstance(full, Mapping) and full and axes
            and all(isinstance(v, Mapping) for v in full.values())):
        return [], []
    order = [c for c in summary.get('causes') or () if c in full]
    order += [c for c in full if c not in order]
    rows = [[float(full[c].get(a, math.nan)) for a in axes] for c in order
            if _cause_total(full[c]) is not None]
    return axes, rows


def rollups_from_summary(summary: Mapping[str, Any]) -> dict[str, list[tuple[str, float, float]]]:
    """Roll-ups per operation and per tool present in the summary: label -> ``[(name, energy J,
    duration s)]`` (:data:`ROLLUP_KEY`)."""
    out = {}
    found = summary.get(ROLLUP_KEY)
    if not isinstance(found, Mapping):
        return out
    for label in _ROLLUP_SHOWN:
        rows = found.get(label)
        if isinstance(rows, list) and rows:
            out[label] = [(str(r.get('name', '')), float(r.get('energy_j', math.nan)),
                           float(r.get('duration_s', math.nan))) for r in rows
                          if isinstance(r, Mapping)]
    return out


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


def top_lines(blocks: Iterable[tuple[int, float, float]], count: int
              ) -> list[tuple[int, float, float]]:
    """The ``count`` source lines with the largest ``|energy|``, largest first (ties: the
    lower line first). A :class:`~feed_axis_energy.sim.stream.LineEnergy` is read as its
    arrays; any other iterable of ``(line, energy_j, duration_s)`` once."""
    if all(hasattr(blocks, a) for a in ('lines', 'energy_j', 'duration_s')):
        lines = np.asarray(blocks.lines)
        energy = np.asarray(blocks.energy_j, dtype=float)
        duration = np.asarray(blocks.duration_s, dtype=float)
    else:
        rows = list(blocks)
        lines = np.array([r[0] for r in rows], dtype=np.int64)
        energy = np.array([r[1] for r in rows], dtype=float)
        duration = np.array([r[2] for r in rows], dtype=float)
    if lines.shape[0] == 0:
        return []
    order = np.lexsort((lines, -np.abs(energy)))[:max(0, int(count))]
    return [(int(lines[i]), float(energy[i]), float(duration[i])) for i in order]


def _answer(summary: Mapping[str, Any], causes: list[tuple[str, float, bool]]) -> str:
    total = summary['energy_j']['total']
    text = (f'This program: <b>{fmt_si(total, "J")} per part</b> on machine '
            f'{escape(short(summary["machine"]))} with {fmt_si(summary["load_kg"], "kg")} '
            f'load, cycle time {fmt_duration(summary["duration_s"])}')
    largest = max((c for c in causes if c[2] and c[1] > 0), key=lambda c: c[1], default=None)
    if largest is not None and total > 0:
        text += f'; {fmt_pct(100.0 * largest[1] / total)} of it {escape(largest[0])}'
    spread = uncertainty_words(summary, per_axis=False)
    if spread is not None:
        text += f'; {escape(spread)}'
    elec = summary.get('electrical')
    if isinstance(elec, Mapping) and elec.get('energy_j'):
        text += (f'; electrical energy at the {escape(str(elec.get("point", "")))}: '
                 f'<b>{fmt_si(elec["energy_j"].get("total"), "J")}</b>')
    return text + '.'


def _electrical_html(elec: Mapping[str, Any]) -> str:
    """The summary's ``electrical`` object (declared drives, ``docs/electrical.md``)."""
    motor, supply = elec['motor_energy_j'], elec['supply_energy_j']
    axes = [a for a in motor if a != 'total']
    cell = '<td class="num">{}</td>'.format
    rows = [[label] + [cell(fmt_si(energy.get(a), 'J', signed=True)) for a in axes]
            + [cell(fmt_si(energy['cabinet'], 'J') if 'cabinet' in energy else '–'),
               cell(fmt_si(energy['total'], 'J', signed=True)),
               cell(fmt_si(elec[peak].get('total'), 'W'))]
            for label, energy, peak in (('motor terminals', motor, 'motor_peak_power_w'),
                                        ('supply side', supply, 'supply_peak_power_w'))]
    head = (['point'] + [f'axis {escape(a)}' for a in axes]
            + ['cabinet', 'total', 'peak power'])
    total = supply['total']
    causes = [[escape(c)] + [cell(fmt_si(v.get(a), 'J', signed=True)) for a in axes]
              + [cell(fmt_si(v.get('cabinet'), 'J')), cell(fmt_si(v['total'], 'J', signed=True)),
                 cell(fmt_pct(100.0 * v['total'] / total) if total else '–')]
              for c, v in elec['energy_by_cause_j'].items()]
    return (f'<p class="note">The machine declares its motors and drives. The meter\'s point '
            f'is the {escape(str(elec["point"]))}. Motor terminals: shaft power plus copper '
            f'and iron losses; supply side: plus converter losses, standby and braking energy '
            f'the regeneration limit burns, and the cabinet\'s standby; '
            f'{fmt_si(elec["returned_j"], "J")} went back to the supply while braking.</p>'
            + table(head, rows, row_head=True)
            + '<h3>Electrical energy by cause, supply side</h3>'
            + table(['cause'] + [f'axis {escape(a)}' for a in axes]
                    + ['cabinet', 'total', 'share of total'], causes, row_head=True))


def _overview(summary: Mapping[str, Any]) -> str:
    energy, peak = summary['energy_j'], summary['peak_power_w']
    total = energy['total']
    spread = summary.get(UNCERTAINTY_KEY)
    sd = spread.get('energy_sd_j', {}) if isinstance(spread, Mapping) else None
    rows = []
    for axis in [a for a in energy if a != 'total'] + ['total']:
        share = 100.0 * energy[axis] / total if total else math.nan
        rows.append([escape(axis), f'<td class="num">{fmt_si(energy[axis], "J")}</td>',
                     f'<td class="num">{fmt_pct(share)}</td>',
                     f'<td class="num">{fmt_si(peak.get(axis), "W")}</td>'])
        if sd is not None:
            value = sd.get(axis)
            rows[-1].append(f'<td class="num">±{fmt_si(value, "J")}</td>' if _finite(value)
                            else '<td>not known</td>')
    head = ['axis', 'energy', 'share of total', 'peak power']
    note = ''
    if sd is not None:
        head.append('uncertainty from the loss function')
        note = ('<p class="note">One standard uncertainty of the energy from the covariance of '
                'the fitted loss parameters (<code>loss_covariance</code> in the machine '
                'config), propagated to first order; it does not cover effects the model '
                'misses.</p>')
    return table(head, rows, row_head=True) + note


def _blocks_table(rows: list[tuple[int, float, float]], texts: Mapping[int, str],
                  trace: PowerTrace, total: float) -> str:
    out = []
    for ln, e, d in rows:
        share = 100.0 * e / total if total else math.nan
        out.append([f'<td class="num">{ln}</td>',
                    f'<td class="code">{escape(short(texts.get(ln, ""), 60))}</td>',
                    f'<td class="num">{fmt_si(e, "J")}</td>',
                    f'<td class="num">{fmt_pct(share)}</td>',
                    f'<td class="num">{fmt_duration(d)}</td>',
                    f'<td class="num">{fmt_si(trace.first_time(ln), "s")}</td>'])
    return table(['line', 'block', 'energy', 'share', 'time in the block',
                  'first runs at'], out)


def _causes_html(summary: Mapping[str, Any], causes: list[tuple[str, float, bool]],
                 full: bool, total: float, png: bytes | None) -> str:
    if not causes:
        return '<p>No breakdown by cause in this simulation.</p>'
    axes, per_axis = causes_by_axis(summary) if full else ([], [])
    if len(per_axis) != len(causes):
        axes, per_axis = [], [[] for _ in causes]
    rows = [[escape(n)] + [f'<td class="num">{fmt_si(v, "J", signed=True)}</td>' for v in pa]
            + [f'<td class="num">{fmt_si(e, "J", signed=True)}</td>',
               f'<td class="num">{fmt_pct(100.0 * e / total) if total and part else "–"}</td>']
            for (n, e, part), pa in zip(causes, per_axis)]
    head = ['cause'] + [f'axis {escape(a)}' for a in axes] + ['total', 'share of total']
    gross = summary.get(GROSS_KEY) if full else None
    if isinstance(gross, Mapping) and gross:
        taken = {_cause_words(str(c)): _cause_total(v) for c, v in gross.items()}
        head.append('taken before giving back')
        for row, (n, _, _) in zip(rows, causes):
            row.append(f'<td class="num">{fmt_si(taken.get(n), "J")}</td>')
    returned = summary.get('braking_returned_j')
    extra = ''
    if full and _finite(returned):
        fate = ('returned to the supply' if summary.get('braking') == 'regenerative'
                else 'burned in the brake resistor')
        extra = (f'<p class="note">Negative parts are energy the axes give back (lowering, '
                 f'slowing down); in all they gave back {fmt_si(float(returned), "J")} while '
                 f'braking, {fate}.</p>')
    note = ('' if full else '<p class="note">Only the two parts every simulation reports so '
            'far; they do not add up to the total (gravity and inertia are missing). The full '
            'breakdown fills this section when the simulation provides it.</p>')
    return (note + table(head, rows, row_head=True) + extra
            + (img(png, 'energy by cause', link='causes.png') if png else ''))


def _electrical_section(summary: Mapping[str, Any]) -> str:
    elec = summary.get('electrical')
    if not isinstance(elec, Mapping) or not elec.get('energy_by_cause_j'):
        return ''
    return '<h2>Electrical energy (declared drives)</h2>' + _electrical_html(elec)


def _rollups_html(rollups: dict[str, list[tuple[str, float, float]]]) -> str:
    if not rollups:
        return ('<p class="note">No operations or tools found in the simulation (roll-ups '
                'per operation and tool appear here when the simulation provides them).</p>')
    parts = []
    for label, rows in rollups.items():
        cells = [[escape(short(n)), f'<td class="num">{fmt_si(e, "J")}</td>',
                  f'<td class="num">{fmt_duration(d)}</td>']
                 for n, e, d in sorted(rows, key=lambda r: -abs(r[1]))]
        parts.append(f'<h3>Per {escape(label)}</h3>'
                     + table([escape(label), 'energy', 'time'], cells, row_head=True))
    return ''.join(parts)


def _bbox_html(tr: Trace) -> str:
    rows = [[escape(a)] + [f'<td class="num">{_position(a, v)}</td>' for v in (lo, hi, hi - lo)]
            for a, lo, hi in zip(tr.axes, tr.pos_min, tr.pos_max)]
    return table(['axis', 'from', 'to', 'travel range'], rows, row_head=True)


def _position(axis: str, value: float) -> str:
    """A position in mm, or in degrees on a rotary axis (its positions are in rad)."""
    if axis_units(axis)[0] == 'rad':
        return f'{round(math.degrees(value), 3) + 0.0:.3f} °'
    return fmt_si(1e3 * value, 'mm')


def _details(summary: Mapping[str, Any], tr: Trace) -> str:
    rows = [['program', f'<td class="code">{escape(short(summary["program"], 80))}</td>'],
            ['samples', f'{summary["samples"]:,} at {fmt_si(summary["rate_hz"], "Hz")}'],
            ['braking rule', escape(summary['braking'])],
            ['plots', f'{tr.t_lo.shape[0]} time columns of {fmt_si(tr.width_s, "s")} each; '
                      'power drawn as the band from the smallest to the largest value of a '
                      'column, so single-sample peaks stay visible']]
    warnings = summary.get('warnings') or []
    if warnings:
        items = ''.join(f'<li>{escape(short(w, 200))}</li>' for w in warnings[:50])
        more = f'<li>… {len(warnings) - 50} more</li>' if len(warnings) > 50 else ''
        rows.append(['warnings', f'<ul>{items}{more}</ul>'])
    return table([], rows, row_head=True)


def write_sim_report(summary: Mapping[str, Any], trace: PowerTrace,
                     blocks: Iterable[tuple[int, float, float]],
                     out_dir: str | os.PathLike[str], *,
                     block_text: Callable[[list[int]], Mapping[int, str]] | None = None,
                     top: int = 20, dpi: int = 100, force: bool = False) -> Path:
    """Write ``index.html`` and its PNG images into ``out_dir``, all or nothing.

    Parameters
    ----------
    summary
        The simulation summary (keys of :func:`feed_axis_energy.sim.simulate.summarize`;
        optionally :data:`CAUSE_KEY`, ``causes``, ``braking_returned_j``, :data:`ROLLUP_KEY`
        and ``warnings``).
    trace
        The decimated series of the whole run.
    blocks
        ``(line, energy_j, duration_s)`` per source line (read once).
    out_dir
        Report directory: must not exist unless ``force`` (see :func:`.staged_report`).
    block_text
        Returns the source text of the given line numbers (missing lines are shown empty).
    top
        Blocks shown in the bar chart and table.
    dpi
        Resolution of the images.
    force
        Replace an earlier report (or an empty directory) in ``out_dir``.

    Returns
    -------
    pathlib.Path
        The ``index.html`` file.

    Raises
    ------
    OutputError
        If ``out_dir`` must not be written.
    """
    tr = trace.trace()
    total = float(summary['energy_j']['total'])
    rows = top_lines(blocks, top)
    texts = block_text([ln for ln, _, _ in rows]) if block_text and rows else {}
    causes, full = causes_from_summary(summary)
    images = {'power.png': plot_power(tr, [(ln, texts.get(ln, '')) for ln, _, _ in rows[:5]],
                                      dpi=dpi),
              'energy.png': plot_energy(tr, dpi=dpi),
              'path.png': plot_bbox_path(tr, dpi=dpi)}
    if rows:
        images['blocks.png'] = plot_blocks(
            [(ln, texts.get(ln, ''), e) for ln, e, _ in rows],
            title=f'the {len(rows)} blocks with the most energy', dpi=dpi)
    if causes:
        images['causes.png'] = plot_causes([(n, e) for n, e, _ in causes], dpi=dpi)
    body = f"""
<h2>Energy per axis</h2>{_overview(summary)}
<h2>Power over time</h2>{img(images['power.png'], 'power over time', link='power.png')}
<h2>Energy over time</h2>{img(images['energy.png'], 'cumulative energy', link='energy.png')}
<h2>Where the energy goes: by cause</h2>
{_causes_html(summary, causes, full, total, images.get('causes.png'))}
<h2>Where the energy goes: blocks</h2>
<p class="note">The blocks (source lines) with the most energy; a line that runs several times
(a loop, a subroutine) adds up. "First runs at" links the power plot's time axis to the block.</p>
{_blocks_table(rows, texts, trace, total) if rows else '<p>No source lines.</p>'}
{img(images['blocks.png'], 'energy per block', link='blocks.png') if rows else ''}
{_electrical_section(summary)}
<h2>Per operation and tool</h2>{_rollups_html(rollups_from_summary(summary))}
<h2>Path and bounding box</h2>{_bbox_html(tr)}
{img(images['path.png'], 'path coloured by power', link='path.png')}
<details><summary>Details</summary>{_details(summary, tr)}</details>
"""
    html = page(f'Simulated energy: {short(Path(str(summary["program"])).name)}',
                _answer(summary, causes), body)
    out = Path(out_dir)
    with staged_report(out, written_by='feed-axis-energy simulate --report',
                       force=force) as tmp:
        for name, png in images.items():
            (tmp / name).write_bytes(png)
        (tmp / 'index.html').write_text(html, encoding='utf-8')
    return out / 'index.html'
