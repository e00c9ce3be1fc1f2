"""The report of ``feed-axis-energy sweep``: one self-contained ``index.html``.

For each program: a one-line answer (the variant with the least energy, against the
baseline), energy against cycle time with the Pareto front joined and the baseline marked
(a PNG embedded as a ``data:`` URI, so the page opens offline and alone), and the table.
"""
from __future__ import annotations

from html import escape
import math
import os
from pathlib import Path
from typing import Sequence

from feed_axis_energy.sim import SweepRow
from feed_axis_energy.physics import two_digits

from .page import figure_png, img, page, table

__all__ = ['write_sweep_report', 'render_sweep']


def _variant(row: SweepRow, names: Sequence[str]) -> str:
    if row.values is None:
        return 'the machine as configured'
    return ', '.join(f'{n}={v:g}' if isinstance(v, float) else f'{n}={v}'
                     for n, v in zip(names, row.values))


def _answer(rows: Sequence[SweepRow], names: Sequence[str]) -> str:
    ok = [r for r in rows if r.ok]
    if not ok:
        return 'every run of this program failed (errors in the table)'
    best = min(ok, key=lambda r: (r.energy_j, r.cycle_time_s))
    spread = ''
    if math.isfinite(best.energy_sd_j) and best.energy_j > 0.0:
        spread = (f' ±{two_digits(100.0 * best.energy_sd_j / best.energy_j)} % from the '
                  'loss-function uncertainty')
    text = (f'least energy: {best.energy_j:,.1f} J per run ({best.energy_per_part_j:,.1f} J per '
            f'part{spread}) in {best.cycle_time_s:,.2f} s with {escape(_variant(best, names))}')
    if not best.baseline and math.isfinite(best.d_energy_pct):
        text += (f': {best.d_energy_pct:+.1f} % energy and {best.d_time_pct:+.1f} % time '
                 f'against the baseline')
    return text


def _plot(rows: Sequence[SweepRow], title: str) -> bytes:
    """Energy against cycle time as PNG bytes (Agg canvas, no display)."""
    from matplotlib.figure import Figure
    ok = [r for r in rows if r.ok]
    fig = Figure(figsize=(7.0, 4.2))
    ax = fig.add_subplot(1, 1, 1)
    ax.scatter([r.cycle_time_s for r in ok], [r.energy_j for r in ok], s=18,
               color='#868e96', label='variant')
    front = sorted((r for r in ok if r.pareto), key=lambda r: r.cycle_time_s)
    if front:
        ax.plot([r.cycle_time_s for r in front], [r.energy_j for r in front], '-o',
                color='#2b8a3e', markersize=5, label='Pareto front')
    base = [r for r in ok if r.baseline]
    if base:
        ax.scatter([base[0].cycle_time_s], [base[0].energy_j], marker='*', s=160,
                   color='#e8590c', zorder=3, label='baseline')
    ax.set_xlabel('cycle time [s]')
    ax.set_ylabel('energy [J]')
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc='best', fontsize=8)
    fig.tight_layout()
    return figure_png(fig)


def _num(value: float, fmt: str) -> str:
    return format(value, fmt) if math.isfinite(value) else '&ndash;'


def _table(rows: Sequence[SweepRow], names: Sequence[str]) -> str:
    spread = any(r.ok and math.isfinite(r.energy_sd_j) for r in rows)
    head = [escape(h) for h in list(names) + [
        'cycle time [s]', 'energy [J]', 'energy per part [J]', 'energy change [%]',
        'time change [%]', 'on the front'] + (['uncertainty [J]'] if spread else [])]
    body, classes = [], []
    for r in rows:
        classes.append('base' if r.baseline else 'front' if r.pareto else '')
        if r.values is None:
            cells = [f'<td colspan="{len(names)}">baseline (as configured)</td>'] if names else []
        else:
            cells = [f'<td class="num">{v:g}</td>' if isinstance(v, float)
                     else f'<td>{escape(str(v))}</td>' for v in r.values]
        if r.ok:
            cells += [f'<td class="num">{_num(r.cycle_time_s, ",.3f")}</td>',
                      f'<td class="num">{_num(r.energy_j, ",.1f")}</td>',
                      f'<td class="num">{_num(r.energy_per_part_j, ",.1f")}</td>',
                      f'<td class="num">{_num(r.d_energy_pct, "+.1f")}</td>',
                      f'<td class="num">{_num(r.d_time_pct, "+.1f")}</td>',
                      f'<td>{"yes" if r.pareto else ""}</td>']
            if spread:
                cells.append(f'<td class="num">±{two_digits(r.energy_sd_j)}</td>'
                             if math.isfinite(r.energy_sd_j) else '<td>not known</td>')
        else:
            cells += [f'<td colspan="{6 + spread}">failed: {escape(r.error[:300])}</td>']
        body.append(cells)
    return table(head, body, classes=classes)


def render_sweep(rows: Sequence[SweepRow], names: Sequence[str]) -> str:
    """The HTML page (plots embedded; style and layout of :mod:`.page`)."""
    programs: dict[str, list[SweepRow]] = {}
    for r in rows:
        programs.setdefault(r.program, []).append(r)
    points = sorted({r.energy_point for r in rows if r.ok} - {'shaft'})
    what = ('the mechanical energy of all feed axes (braking as the machine config says)'
            if not points else f'the electrical energy at the {escape(" / ".join(points))} '
            'point of the declared motors and drives')
    parts = [f'<p class="note">Varied: {escape(", ".join(names))}. A variant is on the Pareto '
             'front when no other run of the same program needs at most as much energy and '
             f'time and less of one. Energy is {what}.</p>']
    for program, prog_rows in programs.items():
        parts.append(f'<section><h2>{escape(program)}</h2>')
        parts.append(f'<p class="answer">{_answer(prog_rows, names)}</p>')
        if any(r.ok for r in prog_rows):
            parts.append(img(_plot(prog_rows, program[-80:]),
                             f'energy against cycle time of {program}'))
        parts.append(_table(prog_rows, names))
        parts.append('</section>')
    failed = sum(1 for r in rows if not r.ok)
    answer = (f'{len(rows)} runs of {len(programs)} program(s), {failed} failed; the variant '
              'with the least energy of each program is named in its section')
    return page('What-if sweep: energy against cycle time', answer, '\n'.join(parts))


def write_sweep_report(rows: Sequence[SweepRow], names: Sequence[str],
                       out_dir: str | os.PathLike[str], *, force: bool = False) -> Path:
    """Write ``index.html`` into ``out_dir``, all or nothing (as the compare report).

    Returns
    -------
    pathlib.Path
        The ``index.html`` file.

    Raises
    ------
    OutputError
        ``out_dir`` exists (without ``force``), or must not be written.
    """
    from .staging import staged_report
    out = Path(out_dir)
    text = render_sweep(rows, names)
    with staged_report(out, written_by='feed-axis-energy sweep --report', force=force) as tmp:
        (tmp / 'index.html').write_text(text, encoding='utf-8')
    return out / 'index.html'
