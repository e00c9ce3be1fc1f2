#!/usr/bin/env python3
"""Behaviour-equivalence harness for feed_axis_energy.

Runs the CLI of a checkout (``DIR/.venv/bin/python -m feed_axis_energy``, cwd = DIR) on a
fixed set of inputs and stores every command's stdout, stderr and exit code in an output
directory, so that two checkouts can be compared with
``bench/equivalence_diff.py OUT_A OUT_B``
(a restructure must change no output):

    python bench/equivalence.py --repo DIR --out OUT [--jobs 2] [--corpus DIR]

What is run
-----------
* ``help/``: ``--help`` of the CLI and of every subcommand (COLUMNS fixed).
* ``corpus/<folder>/<file>.*``: ``simulate --json --quiet`` on every program of
  ``programs.csv`` of the shared G-code corpus, as ``bench/corpus.py --plan`` sets it up:
  machine ``config/three_axis_mill.yaml``, the program's own dialect when the CLI knows it
  (else the machine's default, linuxcnc), tool table T1..T999 with zero radius and length
  (``--tool N:0``, the reference run's table).
* ``umich/``: the README "Real data" workflow on ``config/campaigns/umich_mill.yaml``:
  ``fit-loss --method samples --out-machine umich_fitted.yaml --json`` (the YAML is kept),
  ``compare --json`` (all runs; ``--role validate``; ``--role validate --machine fitted``),
  ``analyze --json`` (declared machine; ``--machine fitted``).
* ``demo/``: ``simulate --json`` on ``config/programs/demonstrator_f300.nc`` (default
  machine, load 0 and 22.711 kg) and the README example ``three_axis_contour.nc`` on the
  3-axis mill with 50 kg.

Per command: ``NAME.cmd`` (argv, the checkout path as ``<REPO>``, the out dir as ``<OUT>``),
``NAME.stdout``, ``NAME.stderr``, ``NAME.rc``. ``meta.json`` holds the run's paths, commit
and timings (equivalence_diff.py ignores it). The environment is fixed (PYTHONHASHSEED=0, TZ=UTC,
C.UTF-8 locale, one BLAS/OpenMP thread, no FAE_* variables) so that runs are reproducible.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import csv
import json
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))
from shared_lookup import HINT, shared_path  # noqa: E402

DIALECTS = ('linuxcnc', 'fanuc', 'haas', 'grbl', 'mach3')   # simulate --dialect choices
N_TOOLS = 999                 # bench/corpus.py ORACLE_TOOLS: T1..T999, radius 0, length 0
CORPUS_MACHINE = 'config/three_axis_mill.yaml'
MANIFEST = 'config/campaigns/umich_mill.yaml'
SUBCOMMANDS = ('simulate', 'check', 'batch', 'sweep', 'demo', 'compare', 'launch', 'import',
               'fit-loss', 'rig', 'analyze')
TIMEOUT_S = 3600


def default_shared() -> Path:
    # the benches' one lookup rule: $FAE_SHARED, else ../shared beside the repository
    found = shared_path()
    if found is None:
        sys.exit(f'equivalence.py: no shared data ({HINT})')
    return found


def make_env(repo: Path, pycache: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(('FAE_', 'PYTHON', 'LC_', 'OMP_', 'OPENBLAS_', 'MKL_'))}
    env.update(PATH=f'{repo / ".venv" / "bin"}:{env.get("PATH", "/usr/bin:/bin")}',
               PYTHONPATH=str(repo), PYTHONHASHSEED='0', PYTHONPYCACHEPREFIX=str(pycache),
               LANG='C.UTF-8', LC_ALL='C.UTF-8', TZ='UTC', COLUMNS='100',
               OMP_NUM_THREADS='1', OPENBLAS_NUM_THREADS='1', MKL_NUM_THREADS='1')
    env.pop('VIRTUAL_ENV', None)
    return env


def run_one(name: str, argv: list[str], repo: str, out: str, env: dict[str, str]) -> tuple:
    """Run ``python -m feed_axis_energy ARGV`` in the checkout; store cmd/stdout/stderr/rc."""
    py = str(Path(repo) / '.venv' / 'bin' / 'python')
    base = Path(out) / name
    base.parent.mkdir(parents=True, exist_ok=True)
    shown = [a.replace(out, '<OUT>').replace(repo, '<REPO>') for a in argv]
    base.with_name(base.name + '.cmd').write_text(json.dumps(shown) + '\n')
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([py, '-m', 'feed_axis_energy', *argv], cwd=repo, env=env,
                              stdin=subprocess.DEVNULL, capture_output=True,
                              timeout=TIMEOUT_S)
        rc, so, se = str(proc.returncode), proc.stdout, proc.stderr
    except subprocess.TimeoutExpired as exc:
        rc, so, se = 'timeout', exc.stdout or b'', exc.stderr or b''
    dt = time.perf_counter() - t0
    base.with_name(base.name + '.stdout').write_bytes(so)
    base.with_name(base.name + '.stderr').write_bytes(se)
    base.with_name(base.name + '.rc').write_text(rc + '\n')
    return name, rc, dt


def run_chain(steps: list[tuple[str, list[str]]], repo: str, out: str,
              env: dict[str, str]) -> list[tuple]:
    """Run dependent commands in order (the fitted machine is used by the later ones)."""
    return [run_one(n, a, repo, out, env) for n, a in steps]


def check_manifest(repo: Path, shared: Path) -> None:
    """The manifest names its data relative to itself (``../../../shared``): it must resolve."""
    manifest = repo / MANIFEST
    missing = []
    for m in re.finditer(r'^\s*data:\s*(\S+)', manifest.read_text(), re.M):
        if not (manifest.parent / m.group(1)).exists():
            missing.append(m.group(1))
    if missing:
        sys.exit(f'equivalence.py: {MANIFEST} of {repo} names data that does not exist '
                 f'({missing[0]} ...): the shared data must be at {repo.parent / "shared"}; '
                 f'e.g. ln -s {shared} {repo.parent / "shared"}')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--repo', required=True, help='checkout with a .venv')
    ap.add_argument('--out', required=True, help='output directory (must not exist or be empty)')
    ap.add_argument('--jobs', type=int, default=2, help='processes in parallel (default 2)')
    ap.add_argument('--corpus', help='G-code corpus (default: corpus/gcode of the shared data)')
    args = ap.parse_args()
    repo = Path(args.repo).resolve()
    out = Path(args.out).resolve()
    shared = default_shared()
    corpus = Path(args.corpus).resolve() if args.corpus else shared / 'corpus' / 'gcode'
    if not (repo / '.venv' / 'bin' / 'python').exists():
        sys.exit(f'equivalence.py: no {repo}/.venv '
                 f'(cd {repo} && bash -c "source scripts/_venv.sh")')
    if out.exists() and any(out.iterdir()):
        sys.exit(f'equivalence.py: {out} exists and is not empty')
    check_manifest(repo, shared)
    out.mkdir(parents=True, exist_ok=True)
    pycache = Path(tempfile.mkdtemp(prefix='equiv-pycache-'))
    env = make_env(repo, pycache)
    R, OUT = str(repo), str(out)

    with open(corpus / 'programs.csv', encoding='utf-8', newline='') as fh:
        programs = list(csv.DictReader(fh))
    tools = [a for n in range(1, N_TOOLS + 1) for a in ('--tool', f'{n}:0')]

    tasks: list[tuple[float, str, object]] = []   # (expected cost, kind, payload)
    for row in programs:
        argv = ['simulate', '--json', '--quiet', '--machine', CORPUS_MACHINE]
        if row['dialect'] in DIALECTS:
            argv += ['--dialect', row['dialect']]
        argv += tools + [str(corpus / row['file'])]
        tasks.append((float(row.get('lines') or 0), 'one', ('corpus/' + row['file'], argv)))
    fitted = str(out / 'umich' / 'umich_fitted.yaml')
    umich = [
        ('umich/fit_loss_samples', ['fit-loss', MANIFEST, '--method', 'samples',
                                    '--out-machine', fitted, '--json']),
        ('umich/compare_all', ['compare', MANIFEST, '--json', '--quiet']),
        ('umich/compare_validate', ['compare', MANIFEST, '--role', 'validate', '--json',
                                    '--quiet']),
        ('umich/compare_validate_fitted', ['compare', MANIFEST, '--role', 'validate',
                                           '--machine', fitted, '--json', '--quiet']),
        ('umich/analyze', ['analyze', MANIFEST, '--json', '--quiet']),
        ('umich/analyze_fitted', ['analyze', MANIFEST, '--machine', fitted, '--json',
                                  '--quiet']),
    ]
    tasks.append((1e9, 'chain', umich))
    demo = [
        ('demo/demonstrator_f300', ['simulate', '--json', '--quiet',
                                    'config/programs/demonstrator_f300.nc']),
        ('demo/demonstrator_f300_22.711kg', ['simulate', '--json', '--quiet', '--load-kg',
                                             '22.711', 'config/programs/demonstrator_f300.nc']),
        ('demo/three_axis_contour_50kg', ['simulate', '--json', '--quiet', '--machine',
                                          'config/three_axis_mill.yaml', '--load-kg', '50',
                                          'config/programs/three_axis_contour.nc']),
    ]
    for name, argv in demo:
        tasks.append((0.0, 'one', (name, argv)))
    tasks.append((-1.0, 'one', ('help/main', ['--help'])))
    for sub in SUBCOMMANDS:
        tasks.append((-1.0, 'one', (f'help/{sub}', [sub, '--help'])))
    tasks.sort(key=lambda t: -t[0])   # longest first: better balance on the pool

    head = subprocess.run(['git', '-C', R, 'rev-parse', 'HEAD'], capture_output=True,
                          text=True).stdout.strip()
    dirty = subprocess.run(['git', '-C', R, 'status', '--porcelain', '--untracked-files=no'],
                           capture_output=True, text=True).stdout.strip()
    n_cmds = sum(len(p) if k == 'chain' else 1 for _, k, p in tasks)
    print(f'equiv: {R} (HEAD {head[:12]}{", DIRTY" if dirty else ""}) -> {OUT}: {n_cmds} '
          f'commands, {args.jobs} jobs', flush=True)
    t0 = time.perf_counter()
    results: list[tuple] = []
    done = 0
    with cf.ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futs = []
        for _, kind, payload in tasks:
            if kind == 'chain':
                futs.append(pool.submit(run_chain, payload, R, OUT, env))
            else:
                futs.append(pool.submit(run_one, *payload, R, OUT, env))
        for fut in cf.as_completed(futs):
            res = fut.result()
            for name, rc, dt in (res if isinstance(res, list) else [res]):
                done += 1
                results.append((name, rc, dt))
                print(f'[{done:3d}/{n_cmds}] rc={rc:<7s} {dt:7.2f} s  {name}', flush=True)
    wall = time.perf_counter() - t0
    shutil.rmtree(pycache, ignore_errors=True)

    corpus_res = [r for r in results if r[0].startswith('corpus/')]
    ok = sum(1 for r in corpus_res if r[1] == '0')
    other = [r for r in results if not r[0].startswith(('corpus/', 'help/')) and r[1] != '0']
    rcs: dict[str, int] = {}
    for r in corpus_res:
        rcs[r[1]] = rcs.get(r[1], 0) + 1
    meta = dict(repo=R, out=OUT, head=head, dirty=bool(dirty), corpus=str(corpus),
                shared=str(shared), jobs=args.jobs, wall_s=round(wall, 1),
                started=time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime(time.time() - wall)),
                corpus_rc=rcs, seconds={n: round(dt, 2) for n, _, dt in sorted(results)})
    (out / 'meta.json').write_text(json.dumps(meta, indent=1) + '\n')
    print(f'equiv: done in {wall:.1f} s; corpus {len(corpus_res)} programs: {ok} ok, '
          f'{len(corpus_res) - ok} refused (exit codes {rcs}); non-corpus failures: '
          f'{[(n, rc) for n, rc, _ in other] or "none"}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
