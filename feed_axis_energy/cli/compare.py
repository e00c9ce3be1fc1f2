"""``feed-axis-energy compare``: measured runs of a campaign against the simulation (Table 1)."""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys

from feed_axis_energy.cli.common import (add_quiet_option, format_table, metric_cells,
                                         METRIC_HEADER)
from feed_axis_energy.cli.progress import Progress
from feed_axis_energy.machine import load_machine, machine_warnings
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify import range_uses
from feed_axis_energy.measured import (CampaignComparison, compare_campaign, DEFAULT_MAX_LAG_S,
                                       load_campaign, load_run, quantity_of)
from feed_axis_energy.outputs import check_target, marked_or_empty, REPORT_MARKER

__all__ = ['add_parser', 'run']


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'compare', help='compare measured runs of a campaign with the simulation (Table 1)',
        description='Load every run of the campaign MANIFEST, simulate it (from its NC program '
                    'or from the positions in its data) with its load, find the time offset '
                    'of the measured record by cross-correlation, average the simulated power '
                    'over each measuring interval and print the paper\'s Table-1 metrics '
                    '(average/maximum differential [W] and percentual [%] error), the energy '
                    'error and the RMSE per run and per load. A drive trace (instrument.measures: '
                    'current, torque or force) is compared with the motor torque / kt, '
                    '1 or lead/2pi, with RMSE, bias and R2 per axis in its unit and the Table-1 '
                    'rows of I*kt*omega in W. See docs/compare.md.')
    p.add_argument('manifest', type=Path, metavar='MANIFEST', help='campaign manifest (YAML)')
    p.add_argument('--json', action='store_true',
                   help='print one JSON object instead of the tables (keys in docs/compare.md)')
    p.add_argument('--report', type=Path, metavar='DIR',
                   help='write plots (power, energy, error per run) and index.html to DIR '
                        '(must not exist unless --force; built in a hidden temporary '
                        'directory and renamed into place when complete)')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --report DIR if it holds an earlier report (or '
                        'is empty); never a symbolic link or another directory')
    p.add_argument('--runs', metavar='NAME,...',
                   help='compare only these runs, in this order (default: all)')
    p.add_argument('--role', choices=('calibrate', 'validate'),
                   help='compare only the runs with this role')
    p.add_argument('--machine', type=Path, metavar='YAML',
                   help="machine config (default: the manifest's machine)")
    p.add_argument('--max-lag-s', type=float, default=DEFAULT_MAX_LAG_S, metavar='S',
                   help=f'largest time offset searched, either way [s] '
                        f'(default: {DEFAULT_MAX_LAG_S:g})')
    p.add_argument('--pct-floor', type=float, default=0.05, metavar='FRACTION',
                   help='percentual errors are taken only where |measured power| >= this '
                        "fraction of the run's peak |measured power| (default: 0.05)")
    add_quiet_option(p)
    p.set_defaults(run=run)


def _selected(args: argparse.Namespace, campaign) -> list[str] | None:
    names = None
    if args.runs is not None:
        names = [n.strip() for n in args.runs.split(',') if n.strip()]
        if not names:
            raise ConfigError('--runs needs at least one run name', file='command line',
                              key='runs')
    if args.role is not None:
        with_role = [r.name for r in campaign.runs_with_role(args.role)]
        names = with_role if names is None else [n for n in names if n in with_role]
        if not names:
            msg = f'no selected run has role {args.role!r}'
            raise ConfigError(msg, file=str(campaign.file), key='role')
    return names


def _print_tables(cmp: CampaignComparison) -> None:
    print(f'campaign  {cmp.campaign} ({cmp.manifest})')
    print(f'machine   {cmp.machine}' + (f' ({cmp.machine_file})' if cmp.machine_file else ''))
    print()
    rows = []
    for r in cmp.runs:
        found = f'{r.offset.offset_s:+.3f}' if math.isfinite(r.offset.offset_s) else '-'
        runner = (f'{r.offset.runner_up_s:+.3f} ({r.offset.runner_up_rms_w:.3g} W)'
                  if math.isfinite(r.offset.runner_up_s) else '-')
        rows.append([r.name, f'{r.load_kg:g}', found, r.offset.status,
                     f'{r.offset_used_s:+.3f}', runner] + metric_cells(r.metrics))
    print('per run (sum of the measured axes; dP = measured - simulated power, '
          'dE = simulated - measured energy):')
    print(format_table(['run', 'load [kg]', 'offset [s]', 'status', 'used [s]',
                        'runner-up [s] (resid. RMS)'] + METRIC_HEADER, rows))
    spread = [f'{r.name} ±{r.energy_sd_pct:.2g} %' for r in cmp.runs
              if math.isfinite(r.energy_sd_pct)]
    if spread:
        print('energy uncertainty from the loss functions (one standard uncertainty of the '
              f'simulated energy, loss_covariance): {", ".join(spread)}')
    works = [r for r in cmp.runs if r.work_offset is not None]
    if works:
        print('work offset (machine - program positions, at the time offset used; '
              'spread: RMS left after the translation):')
        for r in works:
            w = r.work_offset
            assert w is not None
            cells = ', '.join(f'{a} {1e3 * u:+.3f} mm (spread {1e3 * s:.3g} mm)'
                              for a, u, s in zip(w.axes, w.used_m, w.spread_m))
            print(f'  {r.name}: {cells} [{w.status}]')
    _print_quantity(cmp)
    print()
    rows = [[f'{g.load_kg:g}', str(len(g.runs))] + metric_cells(g.metrics) for g in cmp.groups]
    print('per load (runs pooled):')
    print(format_table(['load [kg]', 'runs'] + METRIC_HEADER, rows))
    print()
    _print_states(cmp)
    if cmp.warnings:
        print()
        print('offset and instrument warnings (compared anyway):')
        for w in cmp.warnings:
            print(f'  {w}')


def _print_quantity(cmp: CampaignComparison) -> None:
    """Drive traces (current, torque, force): per run and axis, in the trace's unit."""
    drive = [r for r in cmp.runs if not quantity_of(r.measures).is_power]
    if not drive:
        return
    for measures in dict.fromkeys(r.measures for r in drive):
        qty = quantity_of(measures)
        u = qty.unit
        gain = {'current': 'kt [N·m/A]', 'torque': 'g [N·m/N·m]', 'force': 'lead/2pi [m]'}
        rows = []
        for r in drive:
            if r.measures != measures:
                continue
            for a, m in r.signal_metrics.items():
                g = (r.torque_per_unit or {}).get(a, math.nan)
                rows.append([r.name, a, f'{m.rms_meas:.4g}', f'{m.rmse:.4g}', f'{m.bias:+.4g}',
                             f'{m.max_abs_error:.4g}', _num(m.r2, '.4f'),
                             _num(m.correlation, '+.3f'), f'{g:.4g}'])
        print()
        print(f'{measures} per axis ({qty.words}; d = measured - simulated, bias = mean of '
              f'simulated - measured; the table above is in W via {qty.symbol}*g*omega):')
        print(format_table(['run', 'axis', f'RMS meas. [{u}]', f'RMSE [{u}]', f'bias [{u}]',
                            f'max |d| [{u}]', 'R2', 'r', gain[measures]], rows))


def _num(value: float, fmt: str) -> str:
    return format(value, fmt) if math.isfinite(value) else '-'


def _print_states(cmp: CampaignComparison) -> None:
    rows = []
    for st in cmp.residual_by_state:
        d = st.to_dict()
        rows.append([d['state'], str(d['n_samples'])]
                    + [f'{d[k]:{f}}' if math.isfinite(d[k]) else '-'
                       for k, f in (('samples_pct', '.1f'), ('mean_w', '+.3f'), ('rms_w', '.3f'),
                                    ('squared_error_pct', '.1f'))])
    print('residual dP by motion state, runs pooled (standstill; steady motion; transient: '
          'mean |a| over a period > 0.05 m/s^2 within one sample):')
    print(format_table(['state', 'samples', 'samples [%]', 'mean dP [W]', 'RMS dP [W]',
                        'share of dP^2 [%]'], rows))


def _range_warnings(campaign, machine, names: list[str]) -> list[str]:
    """Losses and effects used outside the speeds/loads/positions they were fitted on."""
    machine = load_machine(campaign.machine) if machine is None else machine
    if not (any(a.loss_calibrated for a in machine.axes)
            or any(e.calibrated for e in machine.effects)):
        return []
    return machine_warnings(machine, range_uses([load_run(campaign.run(n)) for n in names]))


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    if not (math.isfinite(args.max_lag_s) and args.max_lag_s >= 0.0):
        msg = f'--max-lag-s must be a number >= 0, got {args.max_lag_s}'
        raise ConfigError(msg, file='command line', key='max-lag-s')
    if not (math.isfinite(args.pct_floor) and 0.0 <= args.pct_floor < 1.0):
        msg = f'--pct-floor must be a fraction in [0, 1), got {args.pct_floor}'
        raise ConfigError(msg, file='command line', key='pct-floor')
    if args.report is not None:
        # refused before the comparison runs, not after it
        check_target(args.report, option='--report', force=args.force, kind='directory',
                     replaceable=marked_or_empty(REPORT_MARKER))
    campaign = load_campaign(args.manifest)
    names = _selected(args, campaign)
    machine = load_machine(args.machine) if args.machine is not None else None
    progress = Progress('compare', enabled=not args.quiet)
    result = compare_campaign(campaign, machine=machine, runs=names, max_lag_s=args.max_lag_s,
                              floor_fraction=args.pct_floor, progress=progress)
    progress.done()
    warnings = _range_warnings(campaign, machine, [r.name for r in result.runs])
    for w in warnings:
        print(f'warning: {w}', file=sys.stderr)
    index = None
    if args.report is not None:
        # imported here: matplotlib is only needed for reports
        from feed_axis_energy.report import write_report
        index = write_report(result, args.report, force=args.force)
    if args.json:
        out = result.to_dict()
        out['loss_range_warnings'] = warnings
        if index is not None:
            out['report'] = str(index)
        print(json.dumps(out, indent=2, allow_nan=False))
        return 0
    _print_tables(result)
    if index is not None:
        print()
        print(f'report: {index}')
    return 0
