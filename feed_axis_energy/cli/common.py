"""Options and output shared by the subcommands.

One rule per kind of option value (:func:`positive_int`, :func:`non_negative_int`, ...) and
the option adders the subcommands share; the G-code and record parsers an option value needs
are imported when it is checked.
"""
from __future__ import annotations

import argparse
from collections.abc import Iterable, Mapping
from dataclasses import replace
import math
from pathlib import Path

from feed_axis_energy.errors import ConfigError, shorten
from feed_axis_energy.machine import load_machine, Machine, PlannerOptions
from feed_axis_energy.gcode import DIALECTS, with_tools
from feed_axis_energy.paths import default_machine

__all__ = ['positive_int', 'non_negative_int', 'positive_float', 'tool_option', 'axes_option',
           'plot_rate_option', 'start_time_option', 'add_tool_option', 'add_quiet_option',
           'add_machine_options', 'load_machine_and_options', 'print_summary', 'cause_table',
           'rollup_table',
           'program_text_lines', 'format_table', 'METRIC_HEADER', 'metric_cells',
           'program_keywords', 'add_program_options', 'program_options',
           'apply_program_options']

# Column heads of the paper's Table-1 metrics plus energy error and RMSE, as printed by the
# commands that compare measured and simulated power (compare, analyze).
METRIC_HEADER = ['avg dP [W]', 'avg dP [%]', 'max dP [W]', 'max dP [%]', 'dE [J]', 'dE [%]',
                 'RMSE [W]']


def positive_int(text: str) -> int:
    """A whole number >= 1 (``--decimate``); a usage error otherwise."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f'expected an integer >= 1, got {shorten(text)!r}')
    return value


def non_negative_int(text: str) -> int:
    """A whole number >= 0, where 0 means "none" or "automatic" (``--jobs 0``: one per CPU
    core; ``--top``, ``--max-samples``); a usage error otherwise."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a whole number, got {text[:60]!r}') from None
    if value < 0:
        raise argparse.ArgumentTypeError(f'expected a number >= 0, got {value}')
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (``--export-rate-hz``); a usage error otherwise."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f'expected a number > 0, got {shorten(text)!r}')
    return value


def tool_option(text: str) -> tuple:
    """``--tool T:R[:L]`` (:func:`feed_axis_energy.gcode.parse_tool_option`)."""
    from feed_axis_energy.gcode import parse_tool_option
    try:
        return parse_tool_option(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def axes_option(text: str) -> tuple[str, ...]:
    """``--ignore-axes A,B``: letters among A, B, C, U, V, W separated by commas."""
    axes = tuple(a.strip().upper() for a in text.split(',') if a.strip())
    bad = [a for a in axes if a not in ('A', 'B', 'C', 'U', 'V', 'W')]
    if bad or not axes:
        shown = text[:60]
        msg = f'expected axis letters among A,B,C,U,V,W separated by commas, got {shown!r}'
        raise argparse.ArgumentTypeError(msg)
    return axes


def plot_rate_option(text: str) -> float:
    """``--plot-rate-hz``: a finite number >= 0 (a usage error otherwise)."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not math.isfinite(value) or value < 0:
        msg = f'expected a number of hertz >= 0 (0: every sample), got {text[:60]!r}'
        raise argparse.ArgumentTypeError(msg)
    return value


def start_time_option(text: str) -> int:
    """``--start-time``: ``now`` or ISO-8601 -> ns since the epoch (a usage error otherwise)."""
    from feed_axis_energy.record import parse_start_time
    try:
        return parse_start_time(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def add_tool_option(p: argparse.ArgumentParser) -> None:
    """``--tool T:R[:L]``, repeatable (``simulate`` and the commands sharing its machine
    options, ``check``)."""
    p.add_argument('--tool', type=tool_option, action='append', default=[], metavar='T:R[:L]',
                   help='tool T with radius R and length offset L in mm (default 0) for '
                        'G41/G42 and G43, added to the machine config\'s gcode.tools or '
                        'replacing its entry; repeat for more tools (e.g. --tool 1:3:45.2)')


def add_program_options(p: argparse.ArgumentParser) -> None:
    """``--strict-tools``, ``--allow-no-feed`` and ``--subroutine-path DIR`` (repeatable): how
    programs are read (``simulate``, ``check``, ``sweep``, ``batch``); each adds to the
    machine config's ``gcode`` settings of the same name."""
    p.add_argument('--strict-tools', action='store_true',
                   help='refuse a program using a tool the tool table lacks (the error names '
                        'file:line:column), as LinuxCNC with its table; default: such a tool '
                        'runs with length and radius 0, one warning per tool (machine config '
                        'gcode.strict_tools)')
    p.add_argument('--allow-no-feed', action='store_true',
                   help='preview a feed move with no F set at the machine\'s axis limits, with '
                        'one warning, as LinuxCNC\'s preview does; default: an error naming '
                        'file:line:column, as the control gives (machine config '
                        'gcode.allow_no_feed)')
    p.add_argument('--subroutine-path', action='append', default=[], metavar='DIR',
                   help='directory searched for subroutine files (o<name> call -> name.ngc) '
                        'after the program\'s own folder and the machine config\'s '
                        'gcode.subroutine_path, as LinuxCNC\'s SUBROUTINE_PATH; repeat for '
                        'more, searched in order')


def program_options(args: argparse.Namespace) -> dict:
    """The values of :func:`add_program_options`' options, the directories checked.

    Returns
    -------
    dict
        ``strict_tools``, ``allow_no_feed`` and ``subroutine_path`` (absolute directories).

    Raises
    ------
    ConfigError
        A ``--subroutine-path`` that is not an existing directory (naming the option).
    """
    from feed_axis_energy.gcode import check_subroutine_dir
    dirs = tuple(check_subroutine_dir(d, where='--subroutine-path', file='command line')
                 for d in getattr(args, 'subroutine_path', None) or ())
    return {'strict_tools': bool(getattr(args, 'strict_tools', False)),
            'allow_no_feed': bool(getattr(args, 'allow_no_feed', False)),
            'subroutine_path': dirs}


def apply_program_options(machine: Machine, args: argparse.Namespace) -> Machine:
    """``machine`` with the command line's program options added to its ``gcode``."""
    from feed_axis_energy.gcode import with_program_options
    return replace(machine, gcode=with_program_options(machine.gcode, **program_options(args)))


METHOD_HELP = ('how the summary\'s figures are integrated: "phases" (default) by quadrature on '
               'the planned motion phases, the exact figures of the model, cost by moves '
               '(machines with declared effects, trajectory CSVs: samples); '
               '"samples" by the trapezoid rule over the samples at the machine\'s rate (what a '
               'recording holds; differs by its discretization error)')


def add_method_option(p: argparse.ArgumentParser) -> None:
    """``--method phases|samples`` (the summary's ``method``)."""
    p.add_argument('--method', choices=('phases', 'samples'), default='phases',
                   help=METHOD_HELP)


def add_quiet_option(p: argparse.ArgumentParser, *,
                     help_text: str = 'no progress indication') -> None:
    """``--quiet``: no progress on stderr."""
    p.add_argument('--quiet', action='store_true', help=help_text)


def program_keywords(machine: Machine, args: argparse.Namespace) -> dict:
    """Keywords for ``load_gcode`` on ``machine`` with the command line's
    ``--ignore-axes``."""
    kw = dict(machine.gcode_keywords())
    if getattr(args, 'ignore_axes', None):
        kw['ignore_axes'] = args.ignore_axes
    return kw


def add_machine_options(p: argparse.ArgumentParser) -> None:
    """Add ``--machine``, ``--load-kg``, ``--rate-hz``, ``--profile``, ``--tool``, the
    program options (:func:`add_program_options`), ``--dialect`` and ``--ignore-axes``."""
    p.add_argument('--machine', type=Path, metavar='YAML', default=None,
                   help='machine config (default: the paper\'s demonstrator, '
                        'config/demonstrator.yaml)')
    p.add_argument('--load-kg', type=float, default=0.0, metavar='KG',
                   help='mass clamped on the table [kg] (default: 0; 0 to 1e6)')
    p.add_argument('--rate-hz', type=float, default=None, metavar='HZ',
                   help='sampling rate of the simulation [Hz] (default: machine config, 1000; '
                        'at most 1e6)')
    p.add_argument('--profile', choices=('jerk', 'trapezoid'), default=None,
                   help='velocity profile (default: machine config)')
    add_tool_option(p)
    add_program_options(p)
    p.add_argument('--dialect', choices=DIALECTS, default=None,
                   help='G-code dialect of the program (default: the machine config\'s '
                        'gcode.dialect, else linuxcnc; docs in gcode/dialect.py)')
    p.add_argument('--ignore-axes', type=axes_option, default=(), metavar='A,B',
                   help='drop the words of these axes (A, B, C, U, V, W) with one warning '
                        'each; without it a program moving such an axis is refused')


def load_machine_and_options(args: argparse.Namespace) -> tuple[Machine, PlannerOptions]:
    """Load the machine config and the planner options the command line asks for."""
    path = args.machine if args.machine is not None else default_machine()
    machine = load_machine(path)
    if not 0.0 <= args.load_kg <= 1.0e6:  # also refuses nan and inf
        msg = f'--load-kg must be a number of 0 to 1e6 kg, got {args.load_kg}'
        raise ConfigError(msg, file='command line', key='load-kg')
    options = machine.planner.options()
    if args.rate_hz is not None:
        # the machine config's bound: more would allocate beyond any memory
        if not 0.0 < args.rate_hz <= 1.0e6:
            msg = f'--rate-hz must be > 0 and <= 1e6 Hz, got {args.rate_hz}'
            raise ConfigError(msg, file='command line', key='rate-hz')
        options = replace(options, rate_hz=args.rate_hz)
    if args.profile is not None:
        options = replace(options, profile=args.profile)
    if getattr(args, 'tool', None):
        machine = replace(machine, gcode=with_tools(machine.gcode, dict(args.tool)))
    if getattr(args, 'dialect', None) is not None:
        machine = replace(machine, gcode=replace(machine.gcode, dialect=args.dialect))
    return apply_program_options(machine, args), options


def program_text_lines(path: Path, lines: Iterable[int]) -> dict[int, str]:
    """Return the texts of the given 1-based ``lines`` of a program (for showing block
    texts), reading the file line by line; {} if unreadable."""
    wanted = {int(n) for n in lines}
    out: dict[int, str] = {}
    if not wanted:
        return out
    last = max(wanted)
    try:
        with open(path, encoding='utf-8', errors='replace', newline=None) as fh:
            for n, text in enumerate(fh, 1):
                if n in wanted:
                    out[n] = text.rstrip('\n')
                if n >= last:
                    break
    except OSError:
        return {}
    return out


def _finite(value: float, fmt: str) -> str:
    return format(value, fmt) if math.isfinite(value) else '-'


def metric_cells(m) -> list[str]:
    """Cells of :data:`METRIC_HEADER` for a ``measured.metrics.Metrics`` ('-' where NaN)."""
    return [_finite(m.avg_diff_error_w, '.2f'), _finite(m.avg_pct_error_pct, '.2f'),
            _finite(m.max_diff_error_w, '.2f'), _finite(m.max_pct_error_pct, '.2f'),
            _finite(m.energy_error_j, '+.1f'), _finite(m.energy_error_pct, '+.2f'),
            _finite(m.rmse_w, '.2f')]


def format_table(header: list[str], rows: list[list[str]]) -> str:
    """Return a plain-text table with right-aligned numeric columns (no trailing blanks)."""
    widths = [max(len(str(r[i])) for r in [header] + rows) for i in range(len(header))]
    lines = ['  '.join(h.rjust(w) if i else h.ljust(w) for i, (h, w) in
                       enumerate(zip(header, widths)))]
    lines.append('  '.join('-' * w for w in widths))
    for r in rows:
        lines.append('  '.join(str(c).rjust(w) if i else str(c).ljust(w)
                               for i, (c, w) in enumerate(zip(r, widths))))
    return '\n'.join(line.rstrip() for line in lines)


def _quadrature_words(summary: dict) -> str:
    """The quadrature's estimated error as the power of ten above it, relative to the energy
    (its own digits are rounding noise)."""
    error = float(summary.get('quadrature_error_j', {}).get('total', 0.0))
    energy = abs(float(summary['energy_j'].get('total', 0.0)))
    if energy <= 0.0:
        return f'estimated quadrature error {error:.1g} J'
    exponent = max(math.ceil(math.log10(max(error / energy, 1e-16))), -16)
    return f'estimated quadrature error below 1e{exponent} of the energy'


def print_summary(summary: dict, *, source_lines: Mapping[int, str]) -> None:
    """Print a simulation summary (see README for the keys) as readable tables."""
    print(f'program   {summary["program"]}')
    print(f'machine   {summary["machine"]} (braking: {summary["braking"]})')
    print(f'load      {summary["load_kg"]:.3f} kg')
    if summary.get('method') == 'phases':
        print(f'duration  {summary["duration_s"]:.3f} s   (integrated by phase, '
              f'{_quadrature_words(summary)}; a recording at {summary["rate_hz"]:g} Hz '
              f'holds {summary["samples"]} samples)')
    else:
        print(f'duration  {summary["duration_s"]:.3f} s   '
              f'({summary["samples"]} samples at {summary["rate_hz"]:g} Hz)')
    print()
    axes = [k for k in summary['energy_j'] if k != 'total']
    rows = [[axis, f'{summary["energy_j"][axis]:.2f}', f'{summary["peak_power_w"][axis]:.1f}']
            for axis in axes + ['total']]
    print(format_table(['axis', 'energy [J]', 'peak power [W]'], rows))
    from feed_axis_energy.physics import uncertainty_words
    spread = uncertainty_words(summary)
    if spread is not None:
        print(f'energy uncertainty: {spread}')
    fate = ('returned to the supply' if summary['braking'] == 'regenerative'
            else 'burned in the brake resistor: drawn before to accelerate or lift, '
            'braking_burned below')
    print(f'passive-resistance (loss) energy {summary["loss_energy_j"]:.2f} J; '
          f'braking energy {summary["regenerated_energy_j"]:.2f} J ({fate})')
    by_cause = summary.get('energy_by_cause_j') or {}
    if by_cause:
        print()
        print(cause_table(summary, axes))
    if summary.get('electrical'):
        print()
        print(electrical_tables(summary['electrical'], axes))
    for group, title in (('operation', 'operation'), ('tool', 'tool'),
                         ('subroutine', 'subroutine')):
        items = (summary.get('rollups') or {}).get(group) or []
        if len(items) > 1 or (items and group == 'tool' and items[0]['name'] != 'no tool'):
            print()
            print(rollup_table(items, title=title, total=summary['energy_j']['total']))
    if summary.get('top_blocks'):
        print()
        print('blocks with the most energy:')
        rows = []
        supply = all('supply_energy_j' in b for b in summary['top_blocks'])
        for b in summary['top_blocks']:
            text = b.get('text', source_lines.get(b['line'], '')).strip()
            rows.append([str(b['line']), f'{b["energy_j"]:.2f}', f'{b["duration_s"]:.3f}',
                         _main_cause(b), text[:48]])
            if supply:
                rows[-1].insert(2, f'{b["supply_energy_j"]:.2f}')
        header = ['line', 'energy [J]', 'duration [s]', 'main cause', 'block']
        if supply:
            header.insert(2, 'supply energy [J]')
        print(format_table(header, rows))


def rollup_table(items: list[dict], *, title: str, total: float, rows: int = 10) -> str:
    """Energy and time per operation/tool/... (``summary['rollups'][group]``), the
    ``rows`` largest and the rest as one row; with declared drives the supply side too."""
    shown = items[:rows]
    supply = bool(items) and all('supply_energy_j' in it for it in items)
    body = [[str(it['name'])[:48], _joules(it['energy_j']),
             _finite(100.0 * it['energy_j'] / total, '.1f') if total > 0.0 else '-',
             f'{it["duration_s"]:.2f}'] for it in shown]
    if supply:
        for row, it in zip(body, shown):
            row.append(_joules(it['supply_energy_j']))
    rest = items[rows:]
    if rest:
        e = math.fsum(it['energy_j'] for it in rest)
        body.append([f'({len(rest)} more)', _joules(e),
                     _finite(100.0 * e / total, '.1f') if total > 0.0 else '-',
                     f'{math.fsum(it["duration_s"] for it in rest):.2f}'])
        if supply:
            body[-1].append(_joules(math.fsum(it['supply_energy_j'] for it in rest)))
    header = [title, 'energy [J]', 'share [%]', 'time [s]']
    if supply:
        header.append('supply energy [J]')
    return f'energy per {title}:\n' + format_table(header, body)


def _main_cause(block: dict) -> str:
    """The cause with the most energy in a top block, with its share ('-' if not known)."""
    causes = block.get('energy_by_cause_j')
    if not causes:
        return '-'
    name, value = max(causes.items(), key=lambda item: item[1])
    energy = block['energy_j']
    share = f' {100.0 * value / energy:.0f} %' if energy > 0.0 else ''
    return f'{name}{share}'


def cause_table(summary: dict, axes: list[str]) -> str:
    """The breakdown by cause (``docs/breakdown.md``) as a text table with a sum row."""
    by_cause = summary['energy_by_cause_j']
    gross = summary.get('gross_by_cause_j') or {}
    total = summary['energy_j']['total']
    rows = []
    for cause, values in by_cause.items():
        put_in = gross.get(cause, {}).get('total', math.nan)
        share = 100.0 * values['total'] / total if total > 0.0 else math.nan
        rows.append([cause] + [_joules(values[a]) for a in axes]
                    + [_joules(values['total']), _unsigned_zero(_finite(share, '.1f')),
                       _finite(put_in, '.2f')])
    rows.append(['sum'] + [_joules(math.fsum(v[a] for v in by_cause.values())) for a in axes]
                + [_joules(math.fsum(v['total'] for v in by_cause.values())), '', ''])
    header = (['cause'] + [f'{a} [J]' for a in axes]
              + ['total [J]', 'share [%]', 'put in [J]'])
    table = '\n'.join(line.rstrip() for line in format_table(header, rows).splitlines())
    return ('energy by cause (net; "put in": the positive power only; docs/breakdown.md):\n'
            + table)


def electrical_tables(electrical: dict, axes: list[str]) -> str:
    """The summary's ``electrical`` object (``docs/electrical.md``) as text: energy and peak
    power at both points, then the breakdown by cause at the supply side with a sum row."""
    e = electrical
    point = 'motor terminals' if e['measured_at'] == 'motor' else 'supply side'
    rows = []
    for label, key, peak in (('motor terminals', 'motor_energy_j', 'motor_peak_power_w'),
                             ('supply side', 'supply_energy_j', 'supply_peak_power_w')):
        energy = e[key]
        rows.append([label] + [_joules(energy[a]) for a in axes]
                    + [_joules(energy['cabinet']) if 'cabinet' in energy else '-',
                       _joules(energy['total']), _finite(e[peak]['total'], '.1f')])
    header = ['point'] + [f'{a} [J]' for a in axes] + ['cabinet [J]', 'total [J]',
                                                       'peak [W]']
    lines = ['electrical energy (declared drives; docs/electrical.md):',
             format_table(header, rows),
             f'the meter\'s point (supply.measured_at): {point}, the {e["point"]}',
             f'returned to the supply by braking drives: {_joules(e["returned_j"])} J; '
             f'cabinet standby {e["cabinet_standby_w"]:g} W']
    by_cause = e['energy_by_cause_j']
    total = e['supply_energy_j']['total']
    body = []
    for cause, values in by_cause.items():
        share = 100.0 * values['total'] / total if total > 0.0 else math.nan
        body.append([cause] + [_joules(values[a]) for a in axes]
                    + [_joules(values['cabinet']), _joules(values['total']),
                       _unsigned_zero(_finite(share, '.1f'))])
    body.append(['sum'] + [_joules(math.fsum(v[k] for v in by_cause.values()))
                           for k in axes + ['cabinet', 'total']] + [''])
    head = ['cause'] + [f'{a} [J]' for a in axes] + ['cabinet [J]', 'total [J]', 'share [%]']
    table = '\n'.join(line.rstrip() for line in format_table(head, body).splitlines())
    lines += ['', 'electrical energy by cause at the supply side (net; motor terminals = all '
              'but converter, standby, braking_burned):', table]
    return '\n'.join(lines)


def _joules(value: float) -> str:
    """``value`` with 2 decimals, without the sign of a value that rounds to zero."""
    return _unsigned_zero(_finite(value, '.2f'))


def _unsigned_zero(text: str) -> str:
    """``'-0.00'`` -> ``'0.00'`` (a tiny negative value rounded to zero)."""
    return text[1:] if text.startswith('-') and not text.strip('-0.') else text
