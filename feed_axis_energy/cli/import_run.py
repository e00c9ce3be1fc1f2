"""``feed-axis-energy import``: measured runs of a campaign (CSV) -> rosbag2/MCAP bags."""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

from feed_axis_energy.cli.common import add_quiet_option, format_table
from feed_axis_energy.cli.progress import Progress
from feed_axis_energy.measured import import_campaign, load_campaign

__all__ = ['add_parser', 'run', 'split_names']


def split_names(text: str | None) -> list[str] | None:
    """Split ``'a,b'`` into names (``None`` stays ``None``)."""
    if text is None:
        return None
    return [n.strip() for n in text.split(',') if n.strip()]


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'import', help='turn the measured runs of a campaign into rosbag2/MCAP bags',
        description='Load every run of MANIFEST (CSV, columns and units as the manifest maps '
                    'them), convert to SI and write one rosbag2 directory (MCAP storage) per '
                    'run into DIR: /measured/power (W, cumulative J), /measured/kinematics, '
                    '/measured/command, /measured/electrical, stamped in seconds from the run '
                    'start, with the source and units in the bag metadata. A manifest '
                    'listing the bags (DIR/campaign.yaml) is written last. Nothing is '
                    'written if a run name or the manifest name is not a plain file name, '
                    'a run cannot be loaded or a destination exists; if anything fails '
                    'part-way (or SIGTERM/SIGINT arrive), every bag of this import is '
                    'removed again.')
    p.add_argument('manifest', type=Path, help='campaign manifest (YAML)')
    p.add_argument('--out', type=Path, required=True, metavar='DIR',
                   help='output directory (created if needed); each run becomes DIR/<run '
                        'name>, which must not exist (no --force)')
    p.add_argument('--runs', metavar='NAME,...', help='runs to import (default: all)')
    p.add_argument('--start-s', type=float, default=0.0, metavar='S',
                   help='import an excerpt starting at this run time [s] (default: 0)')
    p.add_argument('--duration-s', type=float, default=None, metavar='S',
                   help='length of the excerpt [s] (default: to the end)')
    p.add_argument('--manifest-name', default='campaign.yaml', metavar='FILE',
                   help='file name of the manifest written into DIR (default: '
                        'campaign.yaml); a plain name, not a path, and no run name')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    add_quiet_option(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    campaign = load_campaign(args.manifest)
    try:
        result = import_campaign(
            campaign, args.out, runs=split_names(args.runs), start_s=args.start_s,
            duration_s=args.duration_s, manifest_name=args.manifest_name,
            progress=Progress('import', enabled=not args.quiet))
    except KeyError as err:
        print(f'error: {err.args[0]}', file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps({
            'manifest': str(result.manifest),
            'runs': [{'name': r.name, 'bag': str(r.bag), 'samples': r.samples,
                      'duration_s': r.duration_s, 'messages': r.messages,
                      'size_bytes': r.size_bytes} for r in result.runs]}, indent=2))
        return 0
    rows = [[r.name, str(r.samples), f'{r.duration_s:.1f}', f'{r.size_bytes / 1024:.0f}',
             str(r.bag)] for r in result.runs]
    print(format_table(['run', 'samples', 'duration [s]', 'size [KiB]', 'bag'], rows))
    print(f'manifest: {result.manifest}')
    return 0
