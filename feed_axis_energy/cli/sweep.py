"""``feed-axis-energy sweep``: what-if studies, energy against cycle time.

Every combination of the ``--vary`` values is a variant of the machine (or of the run:
feed and rapid override, load); each program runs on each variant and once on the machine as
configured (the baseline), as independent jobs on the executors of ``batch``
(:mod:`feed_axis_energy.cli.batch`). The grammar of ``--vary`` and the Pareto front are in
:mod:`feed_axis_energy.sim.sweep`.
"""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import sys
import time

from feed_axis_energy.cli.common import add_method_option, add_quiet_option

__all__ = ['add_parser', 'run']

_HELP = 'what-if: energy against cycle time on variants of the machine and run'


def _parts(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text[:60]!r}') from None
    if not 0.0 < value <= 1.0e6:
        raise argparse.ArgumentTypeError(f'expected a number > 0 and <= 1e6, got {text[:60]!r}')
    return value


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    from feed_axis_energy.cli.batch import add_executor_options
    from feed_axis_energy.cli.common import add_program_options
    from feed_axis_energy.sim import ALIASES
    aliases = ', '.join(f'{k} ({v})' for k, v in ALIASES.items())
    p = sub.add_parser(
        'sweep', help=_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description='Simulate every PROGRAM on every combination of the --vary values (and '
                    'once on the machine as configured, the baseline) and print energy '
                    'against cycle time, the change against the baseline and the Pareto '
                    'front (variants no other beats in both energy and time).\n\n'
                    'PARAM=V1,V2,...   the values\n'
                    'PARAM=START:STOP:N   N values evenly spaced\n'
                    'PARAM*=F1,F2,...   factors on the configured value(s)\n\n'
                    'PARAM is feed_override (0-10], rapid_override (0-1], load_kg, a short '
                    f'name: {aliases}; or any machine-config key by its dotted path, * for '
                    'every key at that level (axes.Z.table_mass_kg, axes.*.screw.lead_m).\n\n'
                    'Exit 0 when every job succeeded, 1 when one failed or the input is bad, '
                    '2 on a usage error.')
    p.add_argument('programs', nargs='+', metavar='PROGRAM',
                   help='NC program files, quoted globs or directories (as "batch")')
    p.add_argument('--vary', action='append', required=True, metavar='PARAM=VALUES',
                   help='a parameter and its values (repeat for several; every combination '
                        'runs); grammar above')
    p.add_argument('--machine', type=Path, metavar='YAML',
                   help='machine config (default: the paper\'s demonstrator)')
    p.add_argument('--load-kg', type=float, default=0.0, metavar='KG',
                   help='mass clamped on the table [kg] unless load_kg is varied (default 0)')
    p.add_argument('--parts', type=_parts, default=1.0, metavar='N',
                   help='parts one run of a program makes, for the energy per part '
                        '(default 1)')
    p.add_argument('--rate-hz', type=float, default=None, metavar='HZ',
                   help='sampling rate [Hz] (default: the machine config\'s)')
    add_program_options(p)
    add_executor_options(p)
    p.add_argument('--json', action='store_true',
                   help='print one JSON object instead of the table')
    p.add_argument('--csv', type=Path, metavar='FILE',
                   help='also write the rows as CSV (full precision)')
    p.add_argument('--report', type=Path, metavar='DIR',
                   help='also write an HTML report (index.html: energy against cycle time '
                        'per program with the Pareto front, and the table)')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --csv file or an earlier --report')
    add_method_option(p)
    add_quiet_option(p)
    p.set_defaults(run=run)


def _plan(args: argparse.Namespace):
    """Parameters, jobs and the (program, values) of each job; checks every variant first."""
    from feed_axis_energy.cli.batch import check_executor_options
    from feed_axis_energy.sim import (BatchJob, expand_programs, MAX_JOBS, parse_vary,
                                      resolve_paths, variant_machine, variants)
    from feed_axis_energy.errors import ConfigError
    from feed_axis_energy.machine import machine_to_dict
    from feed_axis_energy.paths import default_machine
    from feed_axis_energy.cli.common import program_options
    check_executor_options(args)
    reading = program_options(args)
    if not 0.0 <= args.load_kg <= 1.0e6:
        msg = f'--load-kg must be 0 to 1e6 kg, got {args.load_kg}'
        raise ConfigError(msg, file='command line', key='load-kg')
    if args.rate_hz is not None and not 0.0 < args.rate_hz <= 1.0e6:
        msg = f'--rate-hz must be > 0 and <= 1e6 Hz, got {args.rate_hz}'
        raise ConfigError(msg, file='command line', key='rate-hz')
    params = [parse_vary(v) for v in args.vary]
    names = [p.name + ('*' if p.relative else '') for p in params]
    keys = [p.key for p in params]
    if len(set(keys)) != len(keys):
        raise ConfigError('a parameter is varied twice', file='command line', key='vary')
    machine_file = str(args.machine) if args.machine is not None else str(default_machine())
    machine_path = os.path.abspath(machine_file)
    as_dict = machine_to_dict(variant_machine(machine_path, ()))   # read once, cached
    for p in params:
        if not p.is_run_key:
            resolve_paths(p.key, as_dict)
    combos = variants(params)
    programs = expand_programs(args.programs)
    total = len(programs) * (len(combos) + 1)
    if total > MAX_JOBS:
        msg = (f'{len(programs)} programs x ({len(combos)} variants + baseline) = {total} jobs, '
               f'more than {MAX_JOBS}')
        raise ConfigError(msg, file='command line', key='vary')
    settings = []
    for values in [None] + combos:
        run = {'load_kg': args.load_kg, 'feed_override': 1.0, 'rapid_override': 1.0}
        overrides = []
        for p, v in zip(params, values or ()):
            if p.is_run_key:
                run[p.key] = v
            else:
                overrides.append((p.key, v, p.relative))
        overrides_t = tuple(overrides)
        variant_machine(machine_path, overrides_t)    # a bad variant is refused before any job
        settings.append((values, run, overrides_t))
    jobs, labels = [], []
    for shown, path in programs:
        for values, run, overrides in settings:
            jobs.append(BatchJob(index=len(jobs), program=shown, program_path=path,
                                 machine=machine_file, machine_path=machine_path,
                                 load_kg=run['load_kg'], rate_hz=args.rate_hz,
                                 overrides=overrides, feed_override=run['feed_override'],
                                 rapid_override=run['rapid_override'], method=args.method,
                                 figures='energy', **reading))
            labels.append((shown, values))
    return params, names, jobs, labels


def _cell(value) -> str:
    return f'{value:.6g}' if isinstance(value, float) else str(value)


def _signed(value: float) -> str:
    return '-' if not math.isfinite(value) else f'{value:+.1f}'


def print_table(rows, names: list[str]) -> None:
    """One line per program and variant; failures listed below."""
    from feed_axis_energy.cli.common import format_table
    from feed_axis_energy.errors import shorten
    header = ['program'] + names + ['cycle time [s]', 'energy [J]', 'energy/part [J]',
                                    'dE [%]', 'dt [%]', 'front']
    # the loss-function uncertainty only where some run knows it
    spread = any(r.ok and math.isfinite(r.energy_sd_j) for r in rows)
    from feed_axis_energy.physics import two_digits
    if spread:
        header.insert(len(names) + 3, 'u(E) [J]')
    table = []
    for r in rows:
        cells = [shorten(r.program)]
        cells += ['(baseline)' if r.values is None and i == 0 else ('' if r.values is None
                  else _cell(r.values[i])) for i in range(len(names))]
        if r.ok:
            cells += [f'{r.cycle_time_s:.3f}', f'{r.energy_j:.1f}',
                      f'{r.energy_per_part_j:.1f}', _signed(r.d_energy_pct),
                      _signed(r.d_time_pct), '*' if r.pareto else '']
        else:
            cells += ['-', '-', '-', '-', '-', 'failed']
        if spread:
            sd = r.energy_sd_j if r.ok else math.nan
            cells.insert(len(names) + 3, f'±{two_digits(sd)}' if math.isfinite(sd) else '-')
        table.append(cells)
    print(format_table(header, table))
    points = sorted({r.energy_point for r in rows if r.ok} - {'shaft'})
    if points:
        print(f'energy: electrical, at the {" / ".join(points)} point of the declared drives '
              '(supply.measured_at; docs/electrical.md)')
    if spread:
        print('u(E): one standard uncertainty of the energy from the covariance of the loss '
              'functions (loss_covariance in the machine config; first order)')
    failed = [r for r in rows if not r.ok]
    if failed:
        print()
        print(f'{len(failed)} of {len(rows)} runs failed:')
        for r in failed:
            print(f'{r.program}: {r.error}')


def csv_text(rows, names: list[str]) -> str:
    """CSV of the rows (full precision; empty cells where a number is not known)."""
    import csv
    import io
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator='\n')
    w.writerow(['program', 'baseline'] + names + [
        'status', 'cycle time [s]', 'energy [J]', 'energy per part [J]', 'energy change [%]',
        'time change [%]', 'pareto', 'error', 'energy uncertainty [J]'])

    def num(v: float) -> str:
        return repr(float(v)) if math.isfinite(v) else ''
    for r in rows:
        vals = [''] * len(names) if r.values is None else [_cell(v) if isinstance(v, str)
                                                           else repr(v) for v in r.values]
        w.writerow([r.program, int(r.baseline)] + vals + [
            'ok' if r.ok else 'failed', num(r.cycle_time_s), num(r.energy_j),
            num(r.energy_per_part_j), num(r.d_energy_pct), num(r.d_time_pct),
            int(r.pareto), r.error, num(r.energy_sd_j)])
    return buf.getvalue()


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    import json
    from feed_axis_energy.cli.batch import execute_jobs, JobProgress
    from feed_axis_energy.cli.batchout import check_csv_target, write_csv
    from feed_axis_energy.outputs import check_target
    from feed_axis_energy.sim import sweep_rows
    params, names, jobs, labels = _plan(args)
    if args.csv is not None:
        check_csv_target(args.csv, force=args.force)
    if args.report is not None:
        from feed_axis_energy.outputs import marked_or_empty, REPORT_MARKER
        check_target(args.report, option='--report', force=args.force, kind='directory',
                     replaceable=marked_or_empty(REPORT_MARKER))
    progress = JobProgress(enabled=not args.quiet, label='sweep')
    results, where = execute_jobs(args, jobs, progress)
    rows = sweep_rows([(p, v, r) for (p, v), r in zip(labels, results)], parts=args.parts)
    failed = sum(1 for r in rows if not r.ok)
    if not args.quiet:
        print(f'[sweep] {len(jobs)} runs ({failed} failed) in '
              f'{time.monotonic() - progress.t0:.1f} s on {where}', file=sys.stderr)
    if args.csv is not None:
        write_csv(args.csv, csv_text(rows, names), force=args.force)
    if args.report is not None:
        from feed_axis_energy.report import write_sweep_report
        index = write_sweep_report(rows, names, args.report, force=args.force)
    if args.json:
        doc = {'parameters': [{'name': n, 'key': p.key, 'values': list(p.values),
                               'relative': p.relative} for n, p in zip(names, params)],
               'parts_per_run': args.parts, 'runs': len(rows), 'failed': failed,
               'rows': [r.to_dict(params) for r in rows]}
        print(json.dumps(doc, indent=2, allow_nan=False))
    else:
        print_table(rows, names)
        if args.csv is not None:
            print(f'csv: {args.csv}')
        if args.report is not None:
            print(f'report: {index}')
    return 1 if failed else 0
