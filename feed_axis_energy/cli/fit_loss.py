"""``feed-axis-energy fit-loss``: the paper's loss function (section 2.1) from measured runs."""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

import yaml

from feed_axis_energy.cli.common import format_table
from feed_axis_energy.cli.import_run import split_names
from feed_axis_energy.identify import (fit_drive_friction, fit_drive_samples, fit_loss,
                                       fit_loss_samples, machine_with_friction_fits,
                                       machine_with_losses, machine_with_sample_fits,
                                       range_uses, SampleFitOptions, SteadyOptions,
                                       VELOCITY_SOURCES)
from feed_axis_energy.machine import load_machine, machine_to_dict, range_warnings
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.measured import load_campaign, load_run, quantity_of, torque_per_unit
from feed_axis_energy.outputs import check_target, write_text_atomic

__all__ = ['add_parser', 'run']

_D = SteadyOptions()


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'fit-loss', help='fit the loss function y = a*x^b from no-load runs at several feeds',
        description='Find the steady-motion segments of the runs (constant speed, no '
                    'acceleration), average the actual power there, divide by the feed '
                    '(loss coefficient y [W/(mm/s)] at feed x [mm/s]) and fit the power '
                    'regression y = a*x^b per axis by least squares in log-log space '
                    '(paper, section 2.1). With --method samples, fit Coulomb + viscous loss '
                    'and the motor inertia to every moving sample instead. Exits 1 when an '
                    'axis has too few distinct feeds (or moving samples) or cannot be fitted.')
    p.add_argument('manifest', type=Path, help='campaign manifest (YAML)')
    p.add_argument('--runs', metavar='NAME,...',
                   help='runs to use (default: those with role calibrate, else all)')
    p.add_argument('--machine', type=Path, metavar='YAML',
                   help='machine config (default: the manifest\'s machine)')
    p.add_argument('--axes', metavar='AXIS,...', help='axes to fit (default: all with power)')
    p.add_argument('--out-machine', type=Path, metavar='YAML',
                   help='write the machine config with the fitted loss functions (only when '
                        'every fitted axis is ok; must not exist unless --force)')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --out-machine file (never through a symbolic '
                        'link)')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.add_argument('--fit-kt', action='store_true',
                   help='with --method samples on a current trace: fit the torque constants '
                        'even where the manifest or the machine config declares them (a '
                        'fitted kt is written into axes.<A>.drive.kt_nm_a with --out-machine)')
    p.add_argument('--fit-counterbalance', action='store_true',
                   help='with --method samples on a current, torque or force trace: on an '
                        'inclined axis fit the weight the drive carries as a counterbalance '
                        'against the configured mass\'s weight [N, >= 0] (written as '
                        'axes.<A>.counterbalance_n with --out-machine)')
    p.add_argument('--method', choices=('steady', 'samples'), default='steady',
                   help='steady (default): the paper\'s power regression on steady segments; '
                        'samples: Coulomb + viscous loss and the motor inertia fitted to every '
                        'moving sample (velocity and acceleration at its stamp), with the '
                        'kinematics each run\'s motion comes from (docs/measured.md)')
    p.add_argument('--friction', choices=('symmetric', 'extended'), default='symmetric',
                   help='with --method samples on a drive trace (force, torque, current with '
                        'a known kt): symmetric (default) = Coulomb + viscous; extended = also '
                        'the constant offset force (told from asymmetric Coulomb friction by '
                        'the resting samples), viscous asymmetry and a Stribeck excess, '
                        'written as catalog effects with --out-machine (docs/test-stand.md)')
    g = p.add_argument_group('steady segments (--velocity, --max-accel and --min-speed also '
                             'for --method samples)')
    g.add_argument('--velocity', choices=VELOCITY_SOURCES, default=_D.velocity,
                   help='velocity columns that define steady motion (default: auto = '
                        'commanded, else actual); with --method samples the kinematics of '
                        'every sample (auto: each run\'s motion source, else as above)')
    g.add_argument('--speed-tol', type=float, default=_D.rel_speed_tol, metavar='FRAC',
                   help=f'speeds within this fraction of the segment mean '
                        f'(default: {_D.rel_speed_tol:g})')
    g.add_argument('--max-accel', type=float, default=_D.max_accel_m_s2, metavar='M_S2',
                   help=f'largest |acceleration| [m/s^2] (default: {_D.max_accel_m_s2:g})')
    g.add_argument('--min-speed', type=float, default=_D.min_speed_m_s, metavar='M_S',
                   help=f'slowest speed that counts [m/s] (default: {_D.min_speed_m_s:g})')
    g.add_argument('--min-duration-s', type=float, default=_D.min_duration_s, metavar='S',
                   help=f'shortest segment [s] (default: {_D.min_duration_s:g})')
    g.add_argument('--trim-s', type=float, default=_D.trim_s, metavar='S',
                   help=f'cut from both ends of a segment [s] (default: {_D.trim_s:g})')
    g.add_argument('--min-power-w', type=float, default=_D.min_loss_power_w, metavar='W',
                   help=f'exclude segments with less loss power [W] '
                        f'(default: {_D.min_loss_power_w:g})')
    g.add_argument('--min-feeds', type=int, default=_D.min_feeds, metavar='N',
                   help=f'distinct feeds needed (default: {_D.min_feeds})')
    p.set_defaults(run=run)


def _options(args: argparse.Namespace) -> SteadyOptions:
    return SteadyOptions(rel_speed_tol=args.speed_tol, max_accel_m_s2=args.max_accel,
                         min_speed_m_s=args.min_speed, min_duration_s=args.min_duration_s,
                         trim_s=args.trim_s, min_loss_power_w=args.min_power_w,
                         min_feeds=args.min_feeds, velocity=args.velocity)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    options = _options(args)
    if args.out_machine is not None:
        # refused before anything is loaded or fitted
        check_target(args.out_machine, option='--out-machine', force=args.force)
    campaign = load_campaign(args.manifest)
    machine_path = args.machine if args.machine is not None else campaign.machine
    machine = load_machine(machine_path)
    names = split_names(args.runs)
    try:
        specs = ([campaign.run(n) for n in names] if names
                 else list(campaign.runs_with_role('calibrate') or campaign.runs))
    except KeyError as err:
        print(f'error: {err.args[0]}', file=sys.stderr)
        return 1
    runs = [load_run(s) for s in specs]
    axes = split_names(args.axes)
    for axis in axes or ():
        if axis not in machine.axis_names:
            print(f'error: machine {machine.name!r} has no axis {axis!r}', file=sys.stderr)
            return 1
    if args.fit_kt and (args.method != 'samples'
                        or any(s.instrument.measures != 'current' for s in specs)):
        print('error: --fit-kt fits torque constants with --method samples on runs whose '
              'instrument measures current', file=sys.stderr)
        return 1
    if args.friction == 'extended' and (args.method != 'samples' or args.fit_kt or any(
            quantity_of(s.instrument.measures).is_power for s in specs)):
        print('error: --friction extended fits a drive trace (force, torque or current with a '
              'declared kt) with --method samples; a power trace does not show a constant '
              'force at rest', file=sys.stderr)
        return 1
    if args.fit_counterbalance and (args.method != 'samples' or any(
            quantity_of(s.instrument.measures).is_power for s in specs)):
        print('error: --fit-counterbalance fits the weight an inclined axis carries with '
              '--method samples on a current, torque or force trace', file=sys.stderr)
        return 1
    if args.method == 'samples':
        return _run_samples(args, runs, specs, machine, machine_path, axes)
    drive = sorted({s.instrument.measures for s in specs
                    if not quantity_of(s.instrument.measures).is_power})
    if drive:
        print(f'error: the runs measure {", ".join(drive)}; --method steady fits power: fit a '
              'drive trace with --method samples', file=sys.stderr)
        return 1
    fits = fit_loss(runs, machine=machine, axes=axes, options=options)
    loaded = [r.name for r in runs if r.load_kg > 0]
    if not fits:
        print('error: no run has power for an axis of the machine', file=sys.stderr)
        return 1
    # the fitted runs also move outside the steady feeds the fit saw (rapids, slow moves)
    warnings = range_warnings({a: f.calibrated for a, f in fits.items() if f.ok},
                              range_uses(runs, velocity=args.velocity),
                              max_accel_m_s2=options.max_accel_m_s2,
                              min_speed_m_s=options.min_speed_m_s)
    for w in warnings:
        print(f'warning: {w}', file=sys.stderr)
    return _finish(args, fits, specs, machine_path, warnings,
                   fitted=lambda: machine_with_losses(machine, fits), what='loss functions',
                   show=lambda: _print(fits, specs, loaded))


def _finish(args: argparse.Namespace, fits: dict, specs: list, machine_path: Path,
            warnings: list[str], *, fitted, what: str, show, head: dict | None = None,
            more: dict | None = None) -> int:
    """Write the fitted machine (all axes ok), print the JSON or the tables; exit code.

    ``fitted()`` builds the machine to write, ``what`` names what was fitted (file header
    and the closing line), ``show()`` prints the tables; ``head``/``more``: JSON keys of the
    method before and after ``runs``.
    """
    all_ok = all(f.ok for f in fits.values())
    written = all_ok and args.out_machine is not None
    if written:
        _write_machine(args.out_machine, fitted(), runs=specs, manifest=args.manifest,
                       force=args.force, what=what)
    if args.json:
        print(json.dumps({'manifest': str(args.manifest), 'machine': str(machine_path),
                          **(head or {}), 'runs': [s.name for s in specs], **(more or {}),
                          'fits': {a: f.to_dict() for a, f in fits.items()},
                          'warnings': warnings,
                          'out_machine': str(args.out_machine) if written else None},
                         indent=2))
    else:
        show()
        if written:
            print(f'machine with the fitted {what.split(" (")[0]}: {args.out_machine}')
    if not all_ok:
        for axis, f in fits.items():
            if not f.ok:
                print(f'error: axis {axis}: fit {f.status}: {f.message}', file=sys.stderr)
        if args.out_machine is not None:
            print(f'error: {args.out_machine} not written', file=sys.stderr)
        return 1
    return 0


def _print(fits: dict, specs: list, loaded: list[str]) -> None:
    print(f'runs: {", ".join(s.name for s in specs)}')
    if loaded:
        print(f'note: runs with a load on the table: {", ".join(loaded)} (the paper fits '
              'no-load runs)')
    rows = []
    for axis, f in fits.items():
        num = (lambda v, fmt: '-' if v is None else format(v, fmt))
        excluded = ', '.join(f'{n} {r}' for r, n in f.excluded.items()) or '0'
        rows.append([axis, f.status, num(f.a, '.4g'), num(f.a_se, '.2g'), num(f.b, '.4g'),
                     num(f.b_se, '.2g'), num(f.r2_log, '.4f'),
                     num(f.r2_linear, '.4f'), str(len(f.used)), excluded,
                     ' '.join(f'{x:.3g}' for x in f.feeds_mm_s) or '-'])
    print(format_table(['axis', 'status', 'a', '+-', 'b', '+-', 'R2 log-log', 'R2 linear',
                        'segments', 'excluded', 'feeds [mm/s]'], rows))
    print('y = a*x^b: x = feed [mm/s], y = steady loss power / feed [W/(mm/s)]; +-: standard '
          'errors from the covariance of the log-log fit')
    for axis, f in fits.items():
        if f.calibrated is not None and f.ok:
            lo, hi = f.calibrated.feed_mm_s
            loads = ('' if f.calibrated.load_kg is None else
                     f', loads {f.calibrated.load_kg[0]:g}-{f.calibrated.load_kg[1]:g} kg')
            cov = (' and the covariance of a and b as loss_covariance'
                   if f.covariance() is not None else '')
            print(f'axis {axis}: calibrated at {lo:.3g}-{hi:.3g} mm/s{loads} '
                  f'(written as loss_calibrated{cov} with --out-machine)')


def _run_samples(args: argparse.Namespace, runs: list, specs: list, machine,
                 machine_path: Path, axes: list[str] | None) -> int:
    """``--method samples``: loss and inertia fitted to every moving sample."""
    # the kinematics the comparison simulates: the run's motion source, unless --velocity
    velocity = [s.motion_from_data or 'auto' if args.velocity == 'auto' else args.velocity
                for s in specs]
    options = SampleFitOptions(min_speed_m_s=args.min_speed, accel_m_s2=args.max_accel,
                               fit_counterbalance=args.fit_counterbalance)
    measures = sorted({s.instrument.measures for s in specs})
    if len(measures) == 1 and not quantity_of(measures[0]).is_power:
        gains = _gains(specs, machine, measures[0])
        if args.fit_kt:
            gains = {a: None for a in gains}
        if args.friction == 'extended':
            return _run_extended(args, runs, specs, machine, machine_path, axes, velocity,
                                 options, gains, measures[0])
        fits = fit_drive_samples(runs, machine=machine, measures=measures[0],
                                 gains=gains, axes=axes,
                                 velocity=velocity, invert=[s.instrument.invert for s in specs],
                                 options=options)
        show = (lambda: _print_drive(fits, specs, velocity, machine))
    elif any(not quantity_of(m).is_power for m in measures):
        msg = (f'the runs measure different quantities ({", ".join(measures)}); fit runs of '
               'one quantity at a time (--runs)')
        raise ConfigError(msg, file=str(args.manifest), key='instrument.measures')
    else:
        fits = fit_loss_samples(runs, machine=machine, axes=axes, velocity=velocity,
                                options=options)
        show = (lambda: _print_samples(fits, specs, velocity))
    if not fits:
        print(f'error: no run has {"power" if len(measures) != 1 else measures[0]} for an '
              'axis of the machine', file=sys.stderr)
        return 1
    uses = {}
    for run, source in zip(runs, velocity):
        for axis, use in range_uses([run], velocity=source).items():
            uses.setdefault(axis, []).extend(use)
    warnings = range_warnings({a: f.calibrated for a, f in fits.items() if f.ok}, uses,
                              max_accel_m_s2=args.max_accel, min_speed_m_s=args.min_speed)
    for w in warnings:
        print(f'warning: {w}', file=sys.stderr)
    return _finish(args, fits, specs, machine_path, warnings,
                   fitted=lambda: machine_with_sample_fits(machine, fits),
                   what='loss functions and inertias (fit-loss --method samples)',
                   show=show, head={'method': 'samples', 'measures': measures[0]},
                   more={'velocity': velocity})


def _run_extended(args: argparse.Namespace, runs: list, specs: list, machine,
                  machine_path: Path, axes: list[str] | None, velocity: list[str], options,
                  gains: dict, measures: str) -> int:
    """``--friction extended``: the richer friction model on a drive trace."""
    fits = fit_drive_friction(runs, machine=machine, measures=measures, gains=gains, axes=axes,
                              velocity=velocity, invert=[s.instrument.invert for s in specs],
                              options=options)
    if not fits:
        print(f'error: no run has {measures} for an axis of the machine', file=sys.stderr)
        return 1

    def show() -> None:
        num = (lambda v, fmt: '-' if v is None else format(v, fmt))
        rows = [[a, f.status, num(f.effective_mass_kg, '.4g'), num(f.coulomb_n, '.4g'),
                 num(f.coulomb_asymmetry_n, '+.4g'), num(f.offset_n, '.4g'),
                 num(f.viscous_n_s_m, '.4g'), num(f.viscous_asymmetry_n_s_m, '+.4g'),
                 num(f.stribeck_n, '.4g'),
                 num(None if f.stribeck_v_m_s is None else 1e3 * f.stribeck_v_m_s, '.3g'),
                 num(f.rmse, '.3g'), str(f.n_samples), str(f.n_rest)]
                for a, f in fits.items()]
        print(format_table(['axis', 'status', 'eq. mass [kg]', 'coulomb [N]', 'asym. [N]',
                            'offset [N]', 'viscous [N s/m]', 'asym. [N s/m]',
                            'stribeck [N]', 'vs [mm/s]', f'RMS [{quantity_of(measures).unit}]',
                            'moving', 'resting'], rows))
        print('F(v) = coulomb*sgn(v) + viscous*v + (offset + asym.)*1 + asym.[N s/m]*|v| + '
              'stribeck*exp(-(|v|/vs)^delta)*sgn(v) while moving, offset at rest '
              '(docs/test-stand.md)')
        for axis, f in fits.items():
            print(f'axis {axis}: {f.message}')

    return _finish(args, fits, specs, machine_path, [],
                   fitted=lambda: machine_with_friction_fits(machine, fits),
                   what='friction, offset force and inertias (fit-loss --method samples '
                        '--friction extended)',
                   show=show, head={'method': 'samples', 'friction': 'extended',
                                    'measures': measures}, more={'velocity': velocity})


def _gains(specs: list, machine, measures: str) -> dict[str, float | None]:
    """Torque per unit of the trace per axis; ``None`` where a torque constant is fitted."""
    out: dict[str, float | None] = {}
    for spec in specs:
        axes = spec.measured_axes
        gains = torque_per_unit(measures, machine, axes, declared_kt=spec.instrument.kt_by_axis,
                                manifest=spec.manifest, key=spec.key, required=False)
        for axis, g in zip(axes, gains):
            if axis in out and out[axis] != g:
                msg = (f'axis {axis}: the runs declare different torque constants '
                       f'({out[axis]} and {g} N·m/A)')
                raise ConfigError(msg, file=spec.manifest, key=f'{spec.key}.instrument.kt_nm_a')
            out[axis] = g
    return out


def _print_drive(fits: dict, specs: list, velocity: list[str], machine) -> None:
    kinds = ', '.join(f'{s.name} ({v})' for s, v in zip(specs, velocity))
    print(f'runs (kinematics): {kinds}')
    num = (lambda v, fmt: '-' if v is None else format(v, fmt))
    first = next(iter(fits.values()))
    qty = quantity_of(first.measures)
    gain = {'current': 'kt [N·m/A]', 'torque': 'g [-]', 'force': 'lead/2pi [m]'}[qty.name]
    rows = []
    for axis, f in fits.items():
        how = '-' if f.gain is None else ('fitted' if f.gain_fitted else 'declared')
        rows.append([axis, f.status, num(f.gain, '.4g'), num(f.gain_se, '.2g'), how,
                     num(f.coulomb_n, '.4g'), num(f.coulomb_se, '.2g'),
                     num(f.viscous_n_s_m, '.4g'), num(f.viscous_se, '.2g'),
                     num(f.motor_kg_m2, '.4g'), num(f.effective_mass_kg, '.4g'),
                     num(f.rmse, '.3g'), num(f.r2, '.4f'), str(f.n_samples)])
    print(format_table(['axis', 'status', gain, '+-', '', 'coulomb [N]', '+-',
                        'viscous [N s/m]', '+-', 'motor [kg m2]', 'eff. mass [kg]',
                        f'RMS [{qty.unit}]', 'R2', 'samples'], rows))
    print(f'{qty.symbol} = (J*alpha + k*r*(m*a + m*g*sin(incl) - balance + coulomb*sgn(v) + '
          'viscous*v)) / g '
          'per moving sample (r = lead/2pi, alpha = a/r, k = 1/eta driving, eta back-driven; '
          f'{qty.words}); +-: standard errors')
    for axis, f in fits.items():
        print(f'axis {axis}: {f.message}')
        if f.ok and f.gain_fitted and machine.axis(axis).drive is None:
            print(f'axis {axis}: kt = {f.gain:.4g} N·m/A fitted; the machine config has no '
                  f'drive block to hold it: declare instrument.kt_nm_a: {{{axis}: '
                  f'{f.gain:.4g}}} in the manifest')


def _print_samples(fits: dict, specs: list, velocity: list[str]) -> None:
    kinds = ', '.join(f'{s.name} ({v})' for s, v in zip(specs, velocity))
    print(f'runs (kinematics): {kinds}')
    num = (lambda v, fmt: '-' if v is None else format(v, fmt))
    rows = []
    for axis, f in fits.items():
        rows.append([axis, f.status, num(f.coulomb_n, '.4g'), num(f.coulomb_se, '.2g'),
                     num(f.viscous_n_s_m, '.4g'), num(f.viscous_se, '.2g'),
                     num(f.motor_kg_m2, '.4g'), num(f.motor_se, '.2g'),
                     num(f.effective_mass_kg, '.4g'), num(f.rmse_w, '.3g'), num(f.r2, '.4f'),
                     str(f.n_samples), str(f.n_accel)])
    print(format_table(['axis', 'status', 'coulomb [N]', '+-', 'viscous [N s/m]', '+-',
                        'motor [kg m2]', '+-', 'eff. mass [kg]', 'RMS [W]', 'R2', 'samples',
                        'accelerating'], rows))
    print('P = J*(2 pi/lead)^2*a*v + k*(m*a + m*g*sin(incl) + coulomb*sgn(v) + viscous*v)*v '
          'per moving sample (k = 1/eta driving, eta back-driven; J = motor + coupling + '
          'screw); +-: standard errors; eff. mass = m + J*(2 pi/lead)^2')
    for axis, f in fits.items():
        if f.ok and not f.inertia_fitted:
            print(f'axis {axis}: {f.message}')
        if f.calibrated is not None and f.ok:
            lo, hi = f.calibrated.feed_mm_s
            cov = (' and the covariance of coulomb and viscous as loss_covariance'
                   if f.covariance() is not None else '')
            print(f'axis {axis}: calibrated at {lo:.3g}-{hi:.3g} mm/s '
                  f'(written as loss_calibrated{cov} with --out-machine)')


def _write_machine(path: Path, machine, *, runs: list, manifest: Path, force: bool,
                   what: str = 'loss functions') -> None:
    head = (f'# Written by feed-axis-energy fit-loss: {what} fitted on runs '
            f'{", ".join(s.name for s in runs)} of {manifest}.\n')
    text = head + yaml.safe_dump(machine_to_dict(machine), sort_keys=False, width=99)
    write_text_atomic(path, text, option='--out-machine', force=force)
