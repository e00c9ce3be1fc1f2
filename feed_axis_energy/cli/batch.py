"""``feed-axis-energy batch``: a campaign of programs x machines x loads, in parallel.

Each job is one ``simulate`` run, with a recording under ``--out DIR`` if asked
(:func:`feed_axis_energy.sim.batch.run_job`; each worker writes its own jobs' bags); the jobs
run in this process (``--jobs 1``), in local worker processes (``--jobs N``,
``concurrent.futures.ProcessPoolExecutor``) or on a Dask cluster (``--scheduler ADDRESS``,
``distributed.Client(ADDRESS).get_executor()``), with identical results. A job that fails
is a row with its error; the exit code is then 1.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import re
import sys
import time

from feed_axis_energy.cli.common import (add_method_option, add_program_options, add_quiet_option,
                                         non_negative_int, program_options)

__all__ = ['add_parser', 'run', 'parse_loads', 'check_address', 'add_executor_options',
           'check_executor_options']

_HELP = 'simulate many programs x machines x loads in parallel; one table, JSON or CSV'
_CONNECT_TIMEOUT_S = 10.0
_ADDRESS_RE = re.compile(r'(?:(?:tcp|tls|ws|wss)://)?'
                         r'(?P<host>[A-Za-z0-9._-]{1,253}|\[[0-9A-Fa-f:.]{2,45}\]):'
                         r'(?P<port>[0-9]{1,5})')


def parse_loads(text: str) -> list[float]:
    """``--load-kg`` value: masses [kg] separated by commas (argparse ``type``)."""
    loads = []
    for part in text.split(','):
        try:
            value = float(part)
        except ValueError:
            msg = f'expected masses [kg] separated by commas, got {part.strip()[:60]!r}'
            raise argparse.ArgumentTypeError(msg) from None
        if not 0.0 <= value <= 1.0e6:
            msg = f'a mass must be a number of 0 to 1e6 kg, got {part.strip()[:60]!r}'
            raise argparse.ArgumentTypeError(msg)
        loads.append(value)
    return loads


def add_executor_options(p: argparse.ArgumentParser) -> None:
    """``--jobs N | --scheduler ADDRESS`` and ``--connect-timeout`` (``batch``, ``sweep``);
    :func:`check_executor_options` checks them and :func:`execute_jobs` uses them."""
    where = p.add_mutually_exclusive_group()
    where.add_argument('--jobs', type=non_negative_int, default=1, metavar='N',
                       help='local worker processes (default 1: in this process; 0: one per '
                            'CPU core)')
    where.add_argument('--scheduler', metavar='ADDRESS',
                       help='run the jobs on a Dask cluster (tcp://host:8786; needs the '
                            '"distributed" package, and this package and the program and '
                            'machine files at the same paths on every worker)')
    p.add_argument('--connect-timeout', type=float, default=_CONNECT_TIMEOUT_S, metavar='S',
                   help=f'seconds to wait for the --scheduler (default {_CONNECT_TIMEOUT_S:g})')


def check_executor_options(args: argparse.Namespace) -> None:
    """Refuse a ``--connect-timeout`` outside (0, 3600] s (ConfigError naming the option)."""
    from feed_axis_energy.errors import ConfigError
    if not 0.0 < args.connect_timeout <= 3600.0:
        msg = f'--connect-timeout must be > 0 and <= 3600 s, got {args.connect_timeout}'
        raise ConfigError(msg, file='command line', key='connect-timeout')


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'batch', help=_HELP,
        description='Simulate every PROGRAM on every --machine at every --load-kg (or the '
                    'jobs of a --batch-file YAML) as independent jobs, each one "simulate" run '
                    '(with its recording under --out DIR), and print one table (or --json, '
                    '--csv). A job that fails is a row with its error. Exit 0 when every job '
                    'succeeded, 1 when a job failed or the input is bad, 2 on a usage error.')
    p.add_argument('programs', nargs='*', metavar='PROGRAM',
                   help='NC program files, quoted globs ("parts/*.nc") or directories (their '
                        '*.nc, *.ngc, *.gcode, *.tap, *.cnc files); *.csv: a trajectory')
    p.add_argument('--batch-file', type=Path, metavar='YAML',
                   help='batch file (programs, machines, loads_kg, rate_hz, profile; '
                        'README "batch"); options given on the command line replace its values')
    p.add_argument('--machine', type=Path, metavar='YAML', action='append',
                   help='machine config; repeat for several machines (default: the paper\'s '
                        'demonstrator, config/demonstrator.yaml)')
    p.add_argument('--load-kg', type=parse_loads, action='append', metavar='KG[,KG...]',
                   help='masses clamped on the table [kg], 0 to 1e6, comma-separated or '
                        'repeated (default: 0)')
    p.add_argument('--rate-hz', type=float, default=None, metavar='HZ',
                   help='sampling rate [Hz] (default: each machine config\'s; at most 1e6)')
    p.add_argument('--profile', choices=('jerk', 'trapezoid'), default=None,
                   help='velocity profile (default: each machine config\'s)')
    add_executor_options(p)
    p.add_argument('--json', action='store_true',
                   help='print one JSON object instead of the table (keys in README)')
    p.add_argument('--csv', type=Path, metavar='FILE',
                   help='also write the table as CSV (one row per job, full precision)')
    p.add_argument('--out', type=Path, metavar='DIR',
                   help='write one recording per job into DIR (a rosbag2/MCAP directory as '
                        '"simulate --out", named NNN-PROGRAM[-MACHINE][-LOADkg] by job number; '
                        'README "batch"); a job that fails leaves no recording')
    p.add_argument('--compression', choices=('zstd', 'none'), default='zstd',
                   help='MCAP chunk compression of the --out recordings (default zstd)')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --csv file and existing recordings in --out '
                        '(bag directories only)')
    p.add_argument('--top', type=non_negative_int, default=0, metavar='N',
                   help='blocks with the most energy listed per job in --json (default 0)')
    p.add_argument('--max-samples', type=non_negative_int, default=0, metavar='N',
                   help='a job needing more samples fails before it is simulated '
                        '(default 0: no limit)')
    add_program_options(p)
    add_method_option(p)
    add_quiet_option(p)
    p.set_defaults(run=run)


def _jobs(args: argparse.Namespace) -> list:
    """The campaign's jobs from the command line and the batch file; checks machines."""
    from feed_axis_energy.sim import expand_programs, load_batch_file, make_jobs
    from feed_axis_energy.errors import ConfigError
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.paths import default_machine
    if args.batch_file is not None and args.programs:
        msg = 'give programs either on the command line or in --batch-file, not both'
        raise ConfigError(msg, file='command line', key='batch-file')
    if args.batch_file is None and not args.programs:
        msg = 'no programs: name PROGRAM files, globs or directories, or a --batch-file'
        raise ConfigError(msg, file='command line', key='programs')
    if args.rate_hz is not None and not 0.0 < args.rate_hz <= 1.0e6:
        msg = f'--rate-hz must be > 0 and <= 1e6 Hz, got {args.rate_hz}'
        raise ConfigError(msg, file='command line', key='rate-hz')
    check_executor_options(args)
    if args.batch_file is not None:
        spec = load_batch_file(args.batch_file)
        programs, machines = list(spec.programs), list(spec.machines)
        loads, rate, profile = list(spec.loads_kg), spec.rate_hz, spec.profile
    else:
        programs = expand_programs(args.programs)
        machines, loads, rate, profile = [], [], None, None
    if args.machine:
        machines = [(str(m), os.path.abspath(m)) for m in args.machine]
    if not machines:
        default = default_machine()
        machines = [(str(default), str(default))]
    if args.load_kg:
        loads = [x for group in args.load_kg for x in group]
    loads = loads or [0.0]
    rate = args.rate_hz if args.rate_hz is not None else rate
    profile = args.profile if args.profile is not None else profile
    # a bad machine config is bad input for the whole campaign: refuse before any job runs
    for _, path in dict.fromkeys(machines):
        load_machine(path)
    return make_jobs(programs, machines, loads, rate_hz=rate, profile=profile,
                     top_blocks=args.top, max_samples=args.max_samples, out_dir=args.out,
                     force=args.force, compression=args.compression, method=args.method,
                     **program_options(args))


def _check_out(args: argparse.Namespace, jobs: list) -> list[Path]:
    """Refuse existing recordings (unless --force) before any job runs; create --out.

    Returns the directories created here, deepest first (removed again if they stay empty).
    """
    from feed_axis_energy.errors import OutputError
    from feed_axis_energy.outputs import check_target, is_bag_directory
    out = args.out
    if out.is_symlink() and not out.is_dir():
        raise OutputError('is a dangling symbolic link', path=out, option='--out')
    if out.exists() and not out.is_dir():
        raise OutputError('exists and is not a directory', path=out, option='--out')
    for job in jobs:
        check_target(job.out, option='--out', force=args.force, kind='directory',
                     replaceable=is_bag_directory)
    if out.is_dir():
        return []
    created = [Path(os.path.abspath(out))]
    while not os.path.lexists(created[-1].parent) and created[-1].parent != created[-1]:
        created.append(created[-1].parent)
    try:
        out.mkdir(parents=True)
    except OSError as err:
        _remove_if_empty(created)
        msg = f'cannot create the directory: {err.strerror or err}'
        raise OutputError(msg, path=out, option='--out') from None
    return created


class JobProgress:
    """``[batch] 12/100 jobs, 1 failed, 3.4 s`` on stderr, at most every 0.5 s (and at the end)."""

    def __init__(self, *, enabled: bool, interval_s: float = 0.5, label: str = 'batch'):
        self.enabled = enabled
        self.label = label
        self.interval_s = interval_s
        self.t0 = time.monotonic()
        self._last = -1.0e9
        self.failed = 0

    def __call__(self, done: int, total: int, result) -> None:
        self.failed += 0 if result.ok else 1
        now = time.monotonic()
        if not self.enabled or (done < total and now - self._last < self.interval_s):
            return
        self._last = now
        tty = sys.stderr.isatty()
        end = '\n' if done == total or not tty else ''
        start = '\r' if tty else ''
        sys.stderr.write(f'{start}[{self.label}] {done}/{total} jobs, '
                         f'{self.failed} failed, {now - self.t0:.1f} s{end}')
        sys.stderr.flush()


def execute_jobs(args: argparse.Namespace, jobs: list, progress: JobProgress) -> tuple[list, str]:
    """Run the jobs where asked; returns the results and a description of the workers.

    The jobs of one program that can share its read run in bundles, one per worker
    (:func:`feed_axis_energy.sim.run_batch` ``share``)."""
    from feed_axis_energy.sim import run_batch
    if args.scheduler is not None:
        client = _connect(args.scheduler, timeout_s=args.connect_timeout)
        try:
            threads = sum(client.nthreads().values()) or 1
            results = run_batch(jobs, executor=client.get_executor(pure=False),
                                progress=progress, share=threads)
        finally:
            client.close()
        return results, f'Dask scheduler {args.scheduler}'
    workers = args.jobs or os.cpu_count() or 1
    workers = min(workers, len(jobs))
    if workers <= 1:
        return run_batch(jobs, progress=progress, share=1), '1 process'
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(max_workers=workers, mp_context=_mp_context()) as pool:
        results = run_batch(jobs, executor=pool, progress=progress, share=workers)
    return results, f'{workers} worker processes'


def _remove_if_empty(directories: list[Path]) -> None:
    """Remove the directories this run created (deepest first) that stayed empty."""
    for directory in directories:
        try:
            directory.rmdir()
        except OSError:
            return


def check_address(address: str) -> str:
    """Return ``address`` if it has the form ``[tcp|tls|ws|wss://]HOST:PORT``, else raise.

    Checked here because ``distributed.Client`` given a malformed address fails with a
    ``ValueError`` and then prints a traceback when the half-made client is collected.
    """
    from feed_axis_energy.errors import ConfigError, shorten
    match = _ADDRESS_RE.fullmatch(address)
    if match is None or not 0 < int(match['port']) < 65536:
        msg = (f'expected a scheduler address tcp://HOST:PORT (or tls://, ws://, wss://), '
               f'got {shorten(address)!r}')
        raise ConfigError(msg, file='command line', key='scheduler')
    return address


def _mp_context():
    """How worker processes start: fork when this process runs one thread, else forkserver.

    fork is the fastest (about 1 s less than forkserver for two workers here) and safe in the
    command's own single-threaded process; a caller with threads (a Dask client, a node)
    gets forkserver, whose workers start from a clean server process that imports the
    simulation once for all of them.
    """
    import multiprocessing
    import threading
    methods = multiprocessing.get_all_start_methods()
    if 'fork' in methods and threading.active_count() == 1:
        return multiprocessing.get_context('fork')
    if 'forkserver' in methods:
        ctx = multiprocessing.get_context('forkserver')
        ctx.set_forkserver_preload(['feed_axis_energy.sim.batch', 'feed_axis_energy.gcode.load',
                                    'feed_axis_energy.sim.stream'])
        return ctx
    return multiprocessing.get_context('spawn')


def _connect(address: str, *, timeout_s: float):
    """A Dask client of the scheduler at ``address``, or a clear error."""
    from feed_axis_energy.errors import ConfigError, shorten
    check_address(address)
    try:
        from distributed import Client
    except ImportError:
        msg = ('needs the Python package "distributed" (Dask), which is not installed; '
               'pip install "distributed" (the version pinned in requirements-dev.txt)')
        raise ConfigError(msg, file='command line', key='scheduler') from None
    try:
        return Client(address, timeout=timeout_s, set_as_default=False)
    except Exception as err:  # noqa: B902 - OSError, TimeoutError, ValueError of a bad address
        msg = (f'cannot connect to the Dask scheduler {shorten(address)!r} within '
               f'{timeout_s:g} s: {shorten(f"{type(err).__name__}: {err}", limit=160)}')
        raise ConfigError(msg, file='command line', key='scheduler') from None


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    import json
    from feed_axis_energy.cli.batchout import check_csv_target, csv_text, print_table, write_csv
    jobs = _jobs(args)
    if args.csv is not None:
        check_csv_target(args.csv, force=args.force)
    created = [] if args.out is None else _check_out(args, jobs)
    progress = JobProgress(enabled=not args.quiet)
    try:
        results, where = execute_jobs(args, jobs, progress)
    finally:
        _remove_if_empty(created)
    failed = sum(1 for r in results if not r.ok)
    if not args.quiet:
        print(f'[batch] {len(jobs)} jobs ({failed} failed) in '
              f'{time.monotonic() - progress.t0:.1f} s on {where}', file=sys.stderr)
    if args.csv is not None:
        write_csv(args.csv, csv_text(results), force=args.force)
    if args.json:
        doc = {'jobs': len(results), 'failed': failed,
               'results': [r.to_dict() for r in results]}
        print(json.dumps(doc, indent=2, allow_nan=False))
    else:
        print_table(results)
        if args.csv is not None:
            print(f'csv: {args.csv}')
    return 1 if failed else 0
