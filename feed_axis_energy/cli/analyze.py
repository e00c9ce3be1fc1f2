"""``feed-axis-energy analyze``: which effect does the declared model miss (docs/analyze.md)."""
from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import sys

import yaml

from feed_axis_energy.cli.common import (add_quiet_option, format_table, metric_cells,
                                         METRIC_HEADER)
from feed_axis_energy.cli.progress import Progress
from feed_axis_energy.effects import split_coulomb
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify import AnalysisResult, analyze_campaign, AnalyzeOptions, HOLDOUTS
from feed_axis_energy.machine import load_machine, machine_to_dict
from feed_axis_energy.measured import load_campaign
from feed_axis_energy.outputs import (check_target, marked_or_empty, REPORT_MARKER, Rollback,
                                      write_text_atomic)

__all__ = ['add_parser', 'run']


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'analyze', help='find the catalog effect(s) the model misses; error before/after',
        description='Compare every run of MANIFEST with the declared model (as compare does), '
                    'regress the residual on the bases of the effect catalog, add effects by '
                    'forward selection scored on held-out runs (leave one run out, or the '
                    'manifest\'s calibrate/validate roles) and BIC, test what remains for '
                    'structure, and print the Table-1 metrics before and after on held-out '
                    'runs. See docs/analyze.md.')
    p.add_argument('manifest', type=Path, metavar='MANIFEST', help='campaign manifest (YAML)')
    p.add_argument('--json', action='store_true',
                   help='print one JSON object (keys in docs/analyze.md)')
    p.add_argument('--report', type=Path, metavar='DIR',
                   help='write an HTML report with plots to DIR (must not exist unless '
                        '--force; built in a hidden temporary directory and renamed into '
                        'place when complete)')
    p.add_argument('--out-machine', type=Path, metavar='YAML',
                   help='write the machine config with the selected effects added (must not '
                        'exist unless --force)')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --out-machine file and an earlier --report '
                        'DIR (or an empty one); never a symbolic link')
    p.add_argument('--runs', metavar='NAME,...', help='use only these runs (default: all)')
    p.add_argument('--machine', type=Path, metavar='YAML',
                   help="declared machine config (default: the manifest's machine)")
    p.add_argument('--holdout', choices=HOLDOUTS, default='loro',
                   help='held-out scheme: leave one run out (default) or the manifest roles')
    p.add_argument('--min-share', type=float, default=100 * AnalyzeOptions.min_share,
                   metavar='PCT',
                   help='share of the measured energy [%%] at which an effect matters in the '
                        'report (default %(default)g %%); smaller effects are still added '
                        'when the statistics support them, marked "detected, below PCT %% of '
                        'the energy"')
    p.add_argument('--noise-w', type=float, metavar='W',
                   help='noise level per sample [W] for every test, instead of the estimate '
                        'from the data (which is still printed)')
    p.add_argument('--state-memory', type=float, metavar='MIB',
                   default=AnalyzeOptions.state_memory_bytes / 2 ** 20,
                   help='memory [MiB] for the runs\' simulations during the analysis, '
                        'and as much again for their measured records (default %(default)g '
                        'MiB each); what is beyond it is written to a private temporary '
                        'directory (TMPDIR) and read back memory-mapped: the same result, '
                        'less memory on long runs at high rates')
    add_quiet_option(p)
    p.set_defaults(run=run)


def _print(res: AnalysisResult) -> None:
    print(f'campaign  {res.campaign} ({res.manifest})')
    where = f' ({res.machine_file})' if res.machine_file else ''
    print(f'machine   {res.machine.name}{where}')
    noise = ', '.join(f'{a} {s:.3g} {res.residual_unit}'
                      for a, s in res.noise_sigma_w.items())
    print(f'held out  {res.holdout}; noise level {noise}')
    sizes = sorted(set(res.samples_per_bin.values()))
    per = 'per sample'
    if sizes and sizes != [1]:
        # fast data are analysed on bins (identify/grid.py): say what a level is per
        per = (f'per bin of {"/".join(str(k) for k in sizes)} samples (analysis period '
               f'{1000 * res.analysis_period_s:g} ms)')
    for a, n in res.noise.items():
        unit = res.residual_unit
        print(f'  noise {a}: {n.sigma_w:.3g} {unit} {per} for every test '
              f'({_noise_method(n, unit)})')
    print()
    print(f'status: {res.status}: {res.message}')
    print()
    if res.effects:
        finding = {m: n for n, g in enumerate(res.ambiguous, start=1) for m in g.selected}
        print('effects added (uncertainty: jackknife over runs; ranked by their share of the '
              f'energy, "matters" at {100 * res.min_share:g} % and above):')
        print(_effect_table(res.effects, finding, res.min_share))
        for e in res.effects:
            if e.correction is not None:
                print(correction_line(e.id, e.axis, e.correction))
            if e.id == 'coulomb':
                _print_coulomb_split(e)
        _print_ambiguous(res)
    else:
        print('effects added: none')
    if res.offered:
        print()
        print('offered, not attributed to one effect (a loss of this shape improves the '
              'held-out error; it is in --out-machine; see unexplained for why it is not '
              'named):')
        print(_effect_table(res.offered, {}, res.min_share))
    if res.unexplained:
        print()
        print('unexplained structure:')
        for u in res.unexplained:
            print(f'  [{u["diagnostic"]}] {u["message"]}')
    if res.candidates:
        print()
        cap = ', cap reached' if res.cap_reached else ''
        print(f'every candidate (consistency loop: {res.rounds} round(s){cap}):')
        for f in res.candidates:
            print(f'  {f.effect}@{f.axis}: {f.fate}: {f.reason}')
    print()
    rows = []
    for r in res.heldout_runs:
        rows.append([r.name, f'{r.load_kg:g}', 'before'] + metric_cells(r.before))
        rows.append(['', '', 'after'] + metric_cells(r.after))
    for load, b, a in res.by_load():
        rows.append([f'load {load:g} kg', '', 'before'] + metric_cells(b))
        rows.append(['', '', 'after'] + metric_cells(a))
    rows.append(['all held-out runs', '', 'before'] + metric_cells(res.before))
    rows.append(['', '', 'after'] + metric_cells(res.after))
    print('held-out runs, before and after (after: effects fitted without the run):')
    print(format_table(['run', 'load [kg]', ''] + METRIC_HEADER, rows))
    _print_alignment(res)


def _print_coulomb_split(e) -> None:
    """An asymmetric Coulomb friction is symmetric friction plus a constant force (the
    catalog's exact alias, docs/effects.md): say both readings."""
    values = e.values()
    fc, f0 = split_coulomb(values.get('f_pos_n', 0.0), values.get('f_neg_n', 0.0))
    if f0 != 0.0:
        print(f'coulomb@{e.axis}: F+ {values.get("f_pos_n", 0.0):.4g} N, F- '
              f'{values.get("f_neg_n", 0.0):.4g} N = symmetric friction {fc:.4g} N + a '
              f'constant force (offset_force) {f0:.4g} N: power cannot tell the two apart '
              '(a force or torque trace at rest can: fit-loss --method samples --friction '
              'extended)')


def _noise_method(n, unit: str = 'W') -> str:
    if n.method == 'declared':
        return f'declared; estimated {n.white_w:.3g} {unit} white, {n.slow_w:.3g} {unit} slow'
    what = ('sample-to-sample scatter' if n.method == 'white' else
            f'slow noise: means of up to {n.block_samples} samples vary as the data do')
    slow = f'{n.slow_w:.3g} {unit}' if math.isfinite(n.slow_w) else '-'
    return (f'{what}; white {n.white_w:.3g} {unit}, slow {slow}, correlation '
            f'{n.correlation:.3g}')


def _effect_table(effects, finding: dict, min_share: float) -> str:
    rows = []
    for e in sorted(effects, key=lambda e: -e.energy_share if math.isfinite(e.energy_share)
                    else 0.0):
        name = f'{e.id}@{e.axis}'
        if name in finding:
            name += f' (finding {finding[name]})'
        size = (f'{100 * e.energy_share:.3g}' if math.isfinite(e.energy_share) else '-')
        mark = 'matters' if e.matters else f'below {100 * min_share:g} %'
        for p in e.params:
            unc = f'{p.uncertainty:.3g}' if p.uncertainty is not None else '-'
            value = f'{p.value:.5g}' + ('' if p.at_bound is None else f' ({p.at_bound} bound)')
            rows.append([name, p.name, value, unc, p.unit, size, mark,
                         f'{100 * e.share_of_structured:.1f}',
                         f'{100 * e.heldout_gain_rel:.1f}', ', '.join(e.aliases)])
            name = size = mark = ''
    return format_table(['effect', 'parameter', 'value', '+-', 'unit', 'energy [%]', 'size',
                         'share of structure [%]', 'held-out gain [%]', 'aliases'], rows)


def _print_ambiguous(res: AnalysisResult) -> None:
    if not res.ambiguous:
        return
    print()
    print('ambiguous findings (one power shape, several equivalent forms: the data cannot '
          'tell them apart; the effect above is one form, not a finding of that effect):')
    for n, g in enumerate(res.ambiguous, start=1):
        print(f'  {n}. {g.message}')
        for f in g.forms:
            values = '; '.join(f'{m} ' + ', '.join(f'{k} {v:.4g}' for k, v in vals.items())
                               for m, vals in f.parameters.items())
            print(f'     {" + ".join(f.replaces)} = {" + ".join(f.members)}: differ by '
                  f'{100 * f.relative_residual:.2f} % of its power (limit '
                  f'{100 * f.limit:.2f} %), fit the data worse by {f.data_increase:.1f} '
                  f'sigma² (limit {f.data_limit:.1f}); {values}')


def _offset_cells(offset: dict | None) -> list[str]:
    if offset is None:
        return ['-', '-', '-']
    runner = offset.get('runner_up')
    rival = (f'{runner["offset_s"]:+.3f} ({runner["rms_w"]:.3g} W)' if runner else '-')
    rms = offset.get('rms_w')
    used = f'{offset["used_s"]:+.3f}'
    if rms is not None and math.isfinite(rms):
        used += f' ({rms:.3g} W)'
    return [used, offset['status'], rival]


def _print_alignment(res: AnalysisResult) -> None:
    print()
    print('alignment (offset used and residual RMS; after: offset estimated anew with the '
          'effects; runner-up: best distant lag):')
    rows = [[r.name] + _offset_cells(r.offset_before) + _offset_cells(r.offset_after)
            for r in res.runs]
    print(format_table(['run', 'before [s]', 'status', 'runner-up [s]', 'after [s]', 'status',
                        'runner-up [s]'], rows))
    notes = [f'  {r.name} ({which}): {o["message"]}' for r in res.runs
             for which, o in (('before', r.offset_before), ('after', r.offset_after))
             if o is not None and o['status'] not in ('ok', 'fixed')]
    notes += [f'  {w}' for w in res.alignment_warnings if 'instrument model' in w]
    if notes:
        print('alignment and instrument warnings:')
        print('\n'.join(notes))


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    if args.report is not None:
        check_target(args.report, option='--report', force=args.force, kind='directory',
                     replaceable=marked_or_empty(REPORT_MARKER))
    if args.out_machine is not None:
        # refused before the analysis runs, not after it
        check_target(args.out_machine, option='--out-machine', force=args.force)
    campaign = load_campaign(args.manifest)
    names = None
    if args.runs is not None:
        names = [n.strip() for n in args.runs.split(',') if n.strip()]
        if not names:
            raise ConfigError('--runs needs at least one run name', file='command line',
                              key='runs')
    if not (math.isfinite(args.min_share) and 0.0 <= args.min_share < 100.0):
        msg = f'--min-share must be a percentage in [0, 100), got {args.min_share:g}'
        raise ConfigError(msg, file='command line', key='min-share')
    if args.noise_w is not None and not (math.isfinite(args.noise_w) and args.noise_w > 0.0):
        msg = f'--noise-w must be a level > 0 W, got {args.noise_w:g}'
        raise ConfigError(msg, file='command line', key='noise-w')
    if not (math.isfinite(args.state_memory) and args.state_memory >= 0.0):
        msg = f'--state-memory must be a size >= 0 MiB, got {args.state_memory:g}'
        raise ConfigError(msg, file='command line', key='state-memory')
    machine = load_machine(args.machine) if args.machine is not None else None
    options = AnalyzeOptions(holdout=args.holdout, min_share=args.min_share / 100.0,
                             noise_w=args.noise_w,
                             state_memory_bytes=int(args.state_memory * 2 ** 20))
    progress = Progress('analyze', enabled=not args.quiet)
    result = analyze_campaign(campaign, machine=machine, runs=names, options=options,
                              progress=progress)
    progress.done()
    for w in result.warnings:
        print(f'warning: {w}', file=sys.stderr)
    extra = {}
    # both outputs or neither: the first is removed if the second fails (unless it
    # replaced an earlier one with --force, which cannot be brought back)
    made = None if args.out_machine is None else args.out_machine.parent
    with Rollback(created=made) as written:
        if args.out_machine is not None:
            text = yaml.safe_dump(machine_to_dict(result.augmented_machine()), sort_keys=False)
            new = not os.path.lexists(args.out_machine)
            write_text_atomic(args.out_machine, text, option='--out-machine', force=args.force)
            if new:
                written.add(args.out_machine)
            extra['out_machine'] = str(args.out_machine)
        if args.report is not None:
            # imported here: matplotlib is only needed for reports
            from feed_axis_energy.report import write_analyze_report
            extra['report'] = str(write_analyze_report(result, args.report, force=args.force))
    if args.json:
        out = result.to_dict()
        out.update(extra)
        print(json.dumps(out, indent=2, allow_nan=False))
        return 0
    _print(result)
    for key, value in extra.items():
        print(f'{key.replace("_", " ")}: {value}')
    return 0


def correction_line(effect_id: str, axis: str, corr: dict) -> str:
    """One line: a catalog effect read as a change of the declared drive (docs/electrical.md)."""
    parts = [f'{n} {corr["declared"][n]:.4g} -> {corr["corrected"][n]:.4g}'
             for n in corr['declared']]
    if 'resistance_ohm' in corr:
        r = corr['resistance_ohm']
        parts.append(f'winding resistance ({r["between"]}) {r["declared"]:.4g} -> '
                     f'{r["corrected"]:.4g} ohm')
    return (f'  {effect_id}@{axis} corrects the declared drive (value = change): '
            + '; '.join(parts))
