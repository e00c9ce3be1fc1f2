#!/usr/bin/env python3
"""Regenerate the sample measured-run bags in this directory from the UMich CSV files.

Usage (from the repository root)::

    .venv/bin/python bags/make_samples.py [--force]

The first 60 s of experiments 01, 08 and 09 of the University of Michigan SMART lab "CNC
Mill Tool Wear" data set (see README.md here) are imported with the campaign manifest
``config/campaigns/umich_mill.yaml``; the result is ``bags/exp01``, ``bags/exp08``,
``bags/exp09`` and the manifest ``bags/umich_samples.yaml``. The same as::

    feed-axis-energy import config/campaigns/umich_mill.yaml --runs exp01,exp08,exp09 \\
        --duration-s 60 --out bags --manifest-name umich_samples.yaml
"""
from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import sys

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

from feed_axis_energy.measured import load_campaign  # noqa: E402
from feed_axis_energy.measured.importer import import_campaign  # noqa: E402

RUNS = ('exp01', 'exp08', 'exp09')
DURATION_S = 60.0
MANIFEST = 'umich_samples.yaml'


def main() -> int:
    """Write the sample bags; with ``--force`` replace existing ones first."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--force', action='store_true',
                        help='remove the existing sample bags and manifest first')
    args = parser.parse_args()
    targets = [HERE / name for name in RUNS] + [HERE / MANIFEST]
    if args.force:
        for target in targets:
            if target.is_dir():
                shutil.rmtree(target)
            elif target.exists():
                target.unlink()
    campaign = load_campaign(ROOT / 'config' / 'campaigns' / 'umich_mill.yaml')
    result = import_campaign(campaign, HERE, runs=RUNS, duration_s=DURATION_S,
                             manifest_name=MANIFEST)
    for run in result.runs:
        print(f'{run.bag.relative_to(ROOT)}: {run.samples} samples, {run.duration_s:.1f} s, '
              f'{run.size_bytes / 1024:.0f} KiB')
    print(f'manifest: {result.manifest.relative_to(ROOT)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
