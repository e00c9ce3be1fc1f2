"""Write feed_axis_energy/core/yaml_snapshots.py from config/*.yaml (see core/yamlsnap.py).

Usage: python scripts/yaml_snapshots.py [--check]

Run after changing a shipped config: until then that config is parsed by PyYAML at every
start (correct, only slower) and test/core/test_yamlsnap.py fails. ``--check`` writes
nothing and exits 1 if the module is out of date.
"""
import argparse
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from feed_axis_energy.core.outputs import write_text_atomic  # noqa: E402
from feed_axis_energy.core.safeyaml import read_text_file  # noqa: E402
from feed_axis_energy.core.yamlsnap import render_table  # noqa: E402

TARGET = ROOT / 'feed_axis_energy' / 'core' / 'yaml_snapshots.py'


def current_source() -> str:
    """The module's source as it should be for the configs in the tree."""
    docs = {f'config/{p.name}': read_text_file(p, what='config')
            for p in sorted((ROOT / 'config').glob('*.yaml'))}
    return render_table(docs)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--check', action='store_true', help='only check; exit 1 if stale')
    args = ap.parse_args()
    src = current_source()
    old = TARGET.read_text(encoding='utf-8') if TARGET.exists() else ''
    if args.check:
        print('up to date' if src == old else f'{TARGET} is out of date')
        return 0 if src == old else 1
    if src != old:
        write_text_atomic(TARGET, src, option='yaml_snapshots', force=True)
    print(f'wrote {TARGET.relative_to(ROOT)}' if src != old else 'up to date')
    return 0


if __name__ == '__main__':
    sys.exit(main())
