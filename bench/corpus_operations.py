"""The operation context of every corpus program: a before/after check of the CAM comment rules.

Run by hand from the repository root::

    PYTHONPATH=. .venv/bin/python bench/corpus_operations.py OUT.json [--corpus DIR]
    PYTHONPATH=. .venv/bin/python bench/corpus_operations.py --compare BEFORE.json AFTER.json

The first form reads every program of ``programs.csv`` with ``iter_moves`` (the program's
own dialect; programs the parser refuses are recorded as errors) and writes, per program, the
number of moves and its :class:`~feed_axis_energy.gcode.context.OperationContext`: the
table of ``(operation, subroutine, tool)`` contexts and the change marks, i.e. everything
the roll-ups per operation and tool use. Run it before and after a change of
``gcode/context.py`` and compare: the second form prints every program whose contexts
differ, with its generator, and the count.
"""
from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path
import sys

from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.gcode.load import iter_moves
from feed_axis_energy.gcode.dialect import DIALECTS
from shared_lookup import HINT, shared_path  # bench/shared_lookup.py


def _corpus(given: str | None) -> Path:
    if given and (Path(given) / 'programs.csv').is_file():
        return Path(given)
    found = shared_path('corpus', 'gcode', needs=('programs.csv',))
    if found is None:
        sys.exit(f'error: no corpus (programs.csv) found; give --corpus DIR or {HINT}')
    return found


def contexts(corpus: Path) -> dict:
    """``{file: {'moves', 'table', 'marks', 'generator'} or {'error'}}`` of every program."""
    out = {}
    with open(corpus / 'programs.csv', newline='', encoding='utf-8') as fh:
        rows = list(csv.DictReader(fh))
    for row in rows:
        dialect = row['dialect'] if row['dialect'] in DIALECTS else None
        stream = iter_moves(corpus / row['file'], dialect=dialect)
        try:
            n = sum(1 for _ in stream)
        except FeedAxisError as err:
            out[row['file']] = {'error': type(err).__name__, 'generator': row['generator']}
            continue
        ctx = stream.context
        out[row['file']] = {'moves': n, 'table': [list(c) for c in ctx.table],
                            'marks': [list(m) for m in ctx.marks],
                            'generator': row['generator']}
    return out


def main() -> int:
    """Write the contexts, or compare two files of them."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('files', nargs='+', metavar='JSON')
    ap.add_argument('--corpus', default=None, metavar='DIR')
    ap.add_argument('--compare', action='store_true',
                    help='compare BEFORE.json and AFTER.json instead of writing one')
    args = ap.parse_args()
    if args.compare:
        if len(args.files) != 2:
            ap.error('--compare needs BEFORE.json AFTER.json')
        before, after = (json.loads(Path(f).read_text(encoding='utf-8')) for f in args.files)
        changed = sorted(k for k in before if before[k] != after.get(k))
        for k in changed:
            print(f'{k} ({before[k].get("generator")}):')
            print(f'  before {before[k].get("table", before[k].get("error"))}')
            print(f'  after  {after.get(k, {}).get("table", after.get(k, {}).get("error"))}')
        parsed = sum(1 for v in before.values() if 'error' not in v)
        print(f'{len(changed)} of {len(before)} programs changed ({parsed} parsed)')
        return 1 if changed else 0
    found = contexts(_corpus(args.corpus))
    Path(args.files[0]).write_text(json.dumps(found, indent=0), encoding='utf-8')
    errors = sum(1 for v in found.values() if 'error' in v)
    print(f'{len(found)} programs, {errors} refused by the parser: {args.files[0]}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
