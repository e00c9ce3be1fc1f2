"""``feed-axis-energy rig``: write a virtual measured campaign from a truth model.

Truth = declared machine + catalog effects (``--effects``) [+ an effect outside the catalog];
the instrument averages over 50 ms, adds noise, quantises and starts at an unknown offset.
See :mod:`feed_axis_energy.identify.rig.campaign` for the file layout.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from feed_axis_energy.cli.common import add_quiet_option, format_table
from feed_axis_energy.effects import EFFECTS
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.cli.progress import Progress
from feed_axis_energy.identify import (Instrument, make_campaign, OUTSIDE_KINDS, PAPER_FEEDS_MM_S,
                                       PAPER_LOADS_KG, parse_effects, RigConfig)
from feed_axis_energy.paths import default_machine

__all__ = ['add_parser', 'run', 'DEFAULT_EFFECTS']

DEFAULT_EFFECTS = 'load_friction=mu:0.1'


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'rig', help='write a virtual measured campaign (truth model + instrument artefacts)',
        description='Simulate "measured" runs from a truth model = the declared machine + '
                    'effects it does not declare, recorded by a 50 ms averaging power meter '
                    'with noise, quantisation and an unknown start offset. Writes a campaign '
                    'manifest, CSV files (time in ms, power in kW, position in mm, velocity '
                    'in mm/s), the stroke programs and truth.json (for tests only). Without '
                    "--effects: the paper's scenario, load-dependent friction "
                    f'({DEFAULT_EFFECTS}) at 0, 17.336 and 22.711 kg and 100..500 mm/s.')
    p.add_argument('--out', type=Path, default=None, metavar='DIR',
                   help='output directory (must not exist unless --force; built in a hidden '
                        'temporary directory and renamed into place when complete)')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --out directory if it holds an earlier rig '
                        'output (or is empty); never a symbolic link or another directory')
    p.add_argument('--machine', type=Path, default=None, metavar='YAML',
                   help='declared machine config (default: config/demonstrator.yaml)')
    p.add_argument('--effects', default=DEFAULT_EFFECTS, metavar='SPEC',
                   help='truth effects, ID=PARAM:VALUE,PARAM:VALUE,ID2=...; an ID alone takes '
                        'example values; "none" for no effect (default: %(default)s)')
    p.add_argument('--loads', default=','.join(f'{v:g}' for v in PAPER_LOADS_KG),
                   metavar='KG,...', help='loads on the table [kg] (default: %(default)s)')
    p.add_argument('--feeds', default=','.join(f'{v:g}' for v in PAPER_FEEDS_MM_S),
                   metavar='MM_S,...', help='feed rates [mm/s] (default: %(default)s)')
    p.add_argument('--seed', type=int, default=0, metavar='N', help='random seed (default: 0)')
    p.add_argument('--noise-w', type=float, default=2.0, metavar='W',
                   help='standard deviation of the meter noise [W] (default: 2)')
    p.add_argument('--quantum-w', type=float, default=1.0, metavar='W',
                   help='meter resolution [W], 0 for none (default: 1)')
    p.add_argument('--period-s', type=float, default=0.05, metavar='S',
                   help='meter period and averaging window [s] (default: 0.05)')
    p.add_argument('--offset-s', type=float, default=None, metavar='S',
                   help='start offset of every record [s] (default: random per run, 0.2-0.8)')
    p.add_argument('--drift', default=None, metavar='GAIN_PER_S[,W_PER_S]',
                   help='slow meter drift: relative gain per second and offset in W per second')
    p.add_argument('--outside-catalog', nargs='?', const='periodic', default=None,
                   choices=tuple(OUTSIDE_KINDS), metavar='KIND',
                   help='add an effect that is NOT in the catalog: periodic (20 W at 3.7 Hz, '
                        'the default) or position_step (25 W beyond 250 mm while moving)')
    p.add_argument('--record-window', default=None, metavar='LATE,EARLY',
                   help='the meter started LATE s after the record and stopped EARLY s before '
                        'its end, so records can miss the program\'s start and end '
                        '(default: 0,0, the whole record)')
    p.add_argument('--cycles', type=int, default=3, metavar='N',
                   help='back-and-forth strokes per run (default: 3)')
    p.add_argument('--bags', action='store_true',
                   help='also write each run as a rosbag2/MCAP bag (/measured/power, '
                        '/measured/kinematics)')
    add_quiet_option(p)
    p.add_argument('--list-effects', action='store_true',
                   help='print the effect catalog and exit')
    p.set_defaults(run=run)


def _numbers(text: str, option: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(',') if v.strip())
    except ValueError:
        msg = f'expected comma-separated numbers, got {text!r}'
        raise ConfigError(msg, file='command line', key=option) from None
    if not values:
        raise ConfigError('expected at least one number', file='command line', key=option)
    return values


def _list_effects() -> None:
    rows = []
    for effect_id, cls in EFFECTS.items():
        params = ', '.join(f'{p.name} [{p.unit}]' for p in cls.params)
        rows.append([effect_id, params, cls.description])
    print(format_table(['id', 'parameters', 'effect'], rows))


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    if args.list_effects:
        _list_effects()
        return 0
    if args.out is None:
        raise ConfigError('--out DIR is required', file='command line', key='out')
    try:
        effects = parse_effects(args.effects)
    except ConfigError as err:
        raise ConfigError(err.reason, file='command line', key='effects') from err
    loads = _numbers(args.loads, 'loads')
    if any(v < 0.0 for v in loads):
        raise ConfigError(f'loads must be >= 0 kg, got {args.loads}', file='command line',
                          key='loads')
    feeds = _numbers(args.feeds, 'feeds')
    drift = _numbers(args.drift, 'drift') if args.drift else (0.0, 0.0)
    if len(drift) > 2:
        raise ConfigError(f'expected GAIN_PER_S[,W_PER_S], got {args.drift}',
                          file='command line', key='drift')
    if args.cycles < 1:
        raise ConfigError(f'--cycles must be >= 1, got {args.cycles}', file='command line',
                          key='cycles')
    window = _numbers(args.record_window, 'record-window') if args.record_window else (0.0, 0.0)
    if len(window) != 2:
        raise ConfigError(f'expected LATE,EARLY, got {args.record_window}',
                          file='command line', key='record-window')
    instrument = Instrument(window_s=args.period_s, period_s=args.period_s,
                            noise_w=args.noise_w, quantum_w=args.quantum_w,
                            gain_drift_per_s=drift[0],
                            offset_drift_w_per_s=drift[1] if len(drift) > 1 else 0.0)
    machine = args.machine if args.machine is not None else default_machine()
    config = RigConfig(machine=machine, loads_kg=loads, feeds_mm_s=feeds, effects=effects,
                       instrument=instrument, seed=args.seed, offset_s=args.offset_s,
                       outside=args.outside_catalog, cycles=args.cycles,
                       bags=args.bags, record_window_s=(window[0], window[1]))
    progress = Progress('rig', enabled=not args.quiet)
    manifest = make_campaign(args.out, config, progress=progress, force=args.force)
    progress.done()
    shown = ', '.join(f'{e.id}({", ".join(f"{k}={v:g}" for k, v in e.params.items())})'
                      for e in effects) or 'none'
    print(f'virtual campaign: {manifest} ({len(loads) * len(feeds)} runs)')
    print(f'truth effects: {shown}; outside catalog: {args.outside_catalog or "none"}')
    print(f'truth for tests: {args.out / "truth.json"} (an analyser must not read it)')
    return 0
