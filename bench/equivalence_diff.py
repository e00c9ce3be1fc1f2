#!/usr/bin/env python3
"""Compare two output directories of equivalence.py file by file; exit 1 on any difference.

    equivalence_diff.py OUT_A OUT_B [--max N]

Every file (stdout, stderr, exit code, argv, the fitted machine YAML) must be byte-identical,
so numbers are bit-identical (JSON floats are printed as the shortest repr that round-trips).
The ONLY things ignored:

* ``meta.json`` (wall-clock timings, start time, commit, the paths of the run);
* the absolute path of the checkout (``--repo``) and of the out dir (``--out``), each
  replaced by ``<REPO>`` / ``<OUT>`` before comparing (they appear as "machine",
  "machine_file" and "out_machine" in the umich JSON).

Exit status: 0 identical, 1 different, 2 usage error.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import re
import sys


def load_meta(out: Path) -> dict:
    try:
        return json.loads((out / 'meta.json').read_text())
    except (OSError, ValueError):
        sys.exit(f'equivalence_diff.py: {out} has no meta.json '
                 '(not an equivalence.py output, or incomplete)')


def normaliser(meta: dict):
    subs = []
    for key, token in (('out', '<OUT>'), ('repo', '<REPO>')):
        paths = {meta[key], os.path.realpath(meta[key])}
        for p in sorted(paths, key=len, reverse=True):
            # the path itself, not a longer name that starts with it
            subs.append((re.compile(re.escape(p.encode()) + rb'(?![\w.-])'),
                         token.encode()))

    def norm(data: bytes) -> bytes:
        for rx, token in subs:
            data = rx.sub(token, data)
        return data
    return norm


def files(out: Path) -> set[str]:
    return {str(p.relative_to(out)) for p in out.rglob('*') if p.is_file()}


def json_diffs(a, b, path='$', acc=None, limit=10):
    acc = [] if acc is None else acc
    if len(acc) >= limit:
        return acc
    if type(a) is not type(b):
        acc.append(f'{path}: {a!r} != {b!r}')
    elif isinstance(a, dict):
        if list(a) != list(b):
            acc.append(f'{path}: keys {list(a)} != {list(b)}')
        for k in a:
            if k in b:
                json_diffs(a[k], b[k], f'{path}.{k}', acc, limit)
    elif isinstance(a, list):
        if len(a) != len(b):
            acc.append(f'{path}: length {len(a)} != {len(b)}')
        for i, (x, y) in enumerate(zip(a, b)):
            json_diffs(x, y, f'{path}[{i}]', acc, limit)
    elif a != b or repr(a) != repr(b):      # repr: 0.0 vs -0.0, nan
        acc.append(f'{path}: {a!r} != {b!r}')
    return acc


def explain(a: bytes, b: bytes) -> list[str]:
    try:
        ja, jb = json.loads(a), json.loads(b)
    except ValueError:
        ja = jb = None
    if ja is not None:
        found = json_diffs(ja, jb)
        if found:
            return found
    la, lb = a.decode(errors='replace').splitlines(), b.decode(errors='replace').splitlines()
    for i in range(max(len(la), len(lb))):
        x = la[i] if i < len(la) else '<end>'
        y = lb[i] if i < len(lb) else '<end>'
        if x != y:
            return [f'line {i + 1}:', f'  A: {x[:300]}', f'  B: {y[:300]}']
    return ['(differ only in trailing bytes / line endings)']


def main(argv: list[str]) -> int:
    args = [a for a in argv if not a.startswith('--')]
    if len(args) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    a, b = Path(args[0]).resolve(), Path(args[1]).resolve()
    na, nb = normaliser(load_meta(a)), normaliser(load_meta(b))
    fa = {f for f in files(a) if f != 'meta.json'}
    fb = {f for f in files(b) if f != 'meta.json'}
    problems = 0
    for f in sorted(fa - fb):
        print(f'ONLY IN A: {f}')
        problems += 1
    for f in sorted(fb - fa):
        print(f'ONLY IN B: {f}')
        problems += 1
    same = 0
    for f in sorted(fa & fb):
        da, db = na((a / f).read_bytes()), nb((b / f).read_bytes())
        if da == db:
            same += 1
            continue
        problems += 1
        print(f'DIFFERS: {f}')
        for line in explain(da, db):
            print(f'    {line}')
    print(f'equivalence_diff.py: {same} files identical, {problems} differences '
          f'({len(fa)} files in A, {len(fb)} in B; ignored: meta.json, checkout and out-dir '
          f'paths)')
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
