"""``feed-axis-energy launch``: run the node graph as separate processes, without ros2 launch.

Starts ``gcode_trajectory``, ``axis_dynamics``, ``energy_estimator`` (and ``mcap_recorder``
with ``--record``) as ``python -m feed_axis_energy.nodes.<name> --ros-args ...`` with
``config/graph.yaml`` plus the options given here, waits until the energy estimator has
published the block energies (and the recorder has closed its bag), then stops the rest.
If any node dies, every other node is stopped and the exit code is 1.

The nodes die with the launcher: they run in one process group of their own (so Ctrl-C in a
terminal reaches only the launcher, which stops them in order, and a last SIGKILL of the group
catches whatever is left) and each has ``prctl(PR_SET_PDEATHSIG, SIGTERM)`` armed
(:mod:`feed_axis_energy.lifeline`), so even a SIGKILL of the launcher stops every node: they
get SIGTERM and shut down as on Ctrl-C.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import json
import math
import os
from pathlib import Path
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

from feed_axis_energy import lifeline
from feed_axis_energy.cli.common import plot_rate_option, start_time_option
from feed_axis_energy.paths import config_dir, program_path

__all__ = ['add_parser', 'run', 'node_command', 'params_yaml', 'write_params_file',
           'graph_parameters', 'graph_commands', 'check_job_record',
           'remove_stale_parameter_dirs',
           'private_parameter_dir', 'node_environment', 'Supervisor']

NODES = ('mcap_recorder', 'axis_dynamics', 'energy_estimator', 'gcode_trajectory')
_IDENTIFIER = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')
_PRIVATE_PREFIX = 'fae-launch-'


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'launch', help='run the ROS 2 node graph on an NC program (separate processes)',
        description='Start the node graph (gcode_trajectory -> axis_dynamics -> '
                    'energy_estimator, optionally mcap_recorder) on PROGRAM, wait for the '
                    'program to finish and print where the recording is and what it holds.')
    p.add_argument('--program', type=Path, default=None, metavar='NC',
                   help='NC program (default: config/programs/demonstrator_f100.nc)')
    p.add_argument('--machine', type=Path, default=None, metavar='YAML',
                   help='machine config (default: the demonstrator)')
    p.add_argument('--load-kg', type=float, default=0.0, metavar='KG',
                   help='workpiece mass on the load axis [kg] (default: 0)')
    p.add_argument('--mode', choices=('fast', 'realtime'), default='fast',
                   help='fast: simulated time, as fast as possible (default); '
                        'realtime: paced by the wall clock')
    p.add_argument('--record', type=Path, default=None, metavar='DIR',
                   help='record the graph into this rosbag2/MCAP directory (must not exist); '
                        'with --program-root one recording per job, DIR/<job_id>/ (DIR may '
                        'exist; a job whose recording exists is refused)')
    p.add_argument('--plot-rate-hz', type=plot_rate_option, default=None, metavar='HZ',
                   help='display rate of the recording\'s plot topics (/plot/power, /plot/axes; '
                        '0: every sample; default: the recorder\'s plot_rate_hz, 20); needs '
                        '--record')
    p.add_argument('--start-time', type=_start_time_text, default=None, metavar='now|ISO-8601',
                   help='stamp the recording in wall-clock time from this start (no offset: '
                        'UTC) instead of simulation time from 0; needs --record')
    p.add_argument('--domain-id', type=int, default=None, metavar='N',
                   help='ROS_DOMAIN_ID for the graph (default: inherited)')
    p.add_argument('--params', type=Path, default=None, metavar='YAML',
                   help='node parameter file (default: config/graph.yaml)')
    p.add_argument('--timeout', type=float, default=None, metavar='S',
                   help='give up (exit 1) after this many seconds')
    p.add_argument('--program-root', type=Path, default=None, metavar='DIR',
                   help='run jobs instead of one program: the graph stays up and takes '
                        'start/abort/result commands on job/command for programs inside DIR '
                        '(docs/nodes.md, Jobs) until Ctrl-C; excludes --program')
    p.add_argument('--machine-root', type=Path, default=None, metavar='DIR',
                   help='with --program-root: a job may name a machine YAML inside DIR '
                        '(default: jobs run on --machine)')
    p.add_argument('--measured-live', action='store_true',
                   help='with --program-root: also start measured_live, which compares live '
                        'measured data (measured/live) with each running job\'s prediction '
                        '(job/live; wall-clock stamps need --mode realtime) and publishes '
                        'measured/comparison (docs/nodes.md, measured_live)')
    p.set_defaults(run=run)


def _start_time_text(text: str) -> str:
    """``--start-time``: checked as ``simulate``'s; the recorder gets the text itself."""
    start_time_option(text)
    return text


def _package_root() -> str:
    return str(Path(__file__).resolve().parent.parent.parent)


def node_command(name: str, *, params_files: list[Path]) -> list[str]:
    """Command line that starts one node: ``python -m feed_axis_energy.nodes.<name> ...``.

    Parameters reach the node only through parameter files (later files override earlier
    ones), never as ``-p key:=value``: ROS reads such a value as YAML, so a path holding
    `` #`` lost its tail and one holding ``: `` did not parse at all.
    """
    cmd = [sys.executable, '-u', '-m', f'feed_axis_energy.nodes.{name}', '--ros-args']
    for path in params_files:
        cmd += ['--params-file', str(path)]
    return cmd


def _yaml_scalar(value: object) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            msg = f'parameter value {value} is not a finite number'
            raise ValueError(msg)
        return repr(value)
    if isinstance(value, str):
        # a JSON string is a YAML double-quoted scalar: always a string to the rcl parser,
        # whatever it holds (#, :, quotes, "true", digits); non-ASCII and controls escaped
        return json.dumps(value)
    msg = f'unsupported parameter type {type(value).__name__}'
    raise TypeError(msg)


def params_yaml(params: dict[str, dict[str, object]]) -> str:
    """``{node: {name: value}}`` as a ROS 2 parameter file (``ros__parameters`` per node)."""
    lines = ['# written by feed-axis-energy launch for this run; removed when it ends']
    for node, values in params.items():
        if not _IDENTIFIER.fullmatch(node):
            msg = f'bad node name {node[:60]!r}'
            raise ValueError(msg)
        lines += [f'{node}:', '  ros__parameters:']
        for key, value in values.items():
            if not _IDENTIFIER.fullmatch(key):
                msg = f'bad parameter name {key[:60]!r}'
                raise ValueError(msg)
            lines.append(f'    {key}: {_yaml_scalar(value)}')
    return '\n'.join(lines) + '\n'


def write_params_file(directory: Path, params: dict[str, dict[str, object]]) -> Path:
    """Write :func:`params_yaml` as a new file ``launch_params.yaml`` in ``directory``."""
    path = directory / 'launch_params.yaml'
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    with os.fdopen(fd, 'w', encoding='utf-8') as stream:
        stream.write(params_yaml(params))
    return path


def remove_stale_parameter_dirs() -> int:
    """Remove parameter directories of launchers that are gone (a SIGKILL skips ``finally``).

    Only directories this user owns, named ``fae-launch-<pid>-*`` with no running ``<pid>``.
    """
    removed = 0
    base = Path(tempfile.gettempdir())
    try:
        entries = list(base.glob(f'{_PRIVATE_PREFIX}*-*'))
    except OSError:
        return 0
    for path in entries:
        pid = path.name[len(_PRIVATE_PREFIX):].split('-', 1)[0]
        try:
            owned = path.lstat().st_uid == os.getuid() and path.is_dir() and not path.is_symlink()
        except OSError:
            continue
        if not pid.isdigit() or not owned or lifeline.alive(int(pid)):
            continue
        shutil.rmtree(path, ignore_errors=True)
        removed += 1
    return removed


def graph_parameters(args: argparse.Namespace) -> dict[str, dict[str, object]]:
    """The parameters the command-line options set, per node."""
    machine = {'machine': str(args.machine.resolve())} if args.machine is not None else {}
    program = args.program if args.program is not None else program_path(
        'demonstrator_f100.nc')
    # Nodes stamp from the data and their timers run on the steady clock, so use_sim_time
    # is not needed (it works if set in the parameter file).
    params: dict[str, dict[str, object]] = {
        'gcode_trajectory': {**machine, 'program': str(Path(program).resolve()),
                             'mode': args.mode, 'ack_recorder': args.record is not None},
        'axis_dynamics': {**machine, 'load_kg': float(args.load_kg)},
        'energy_estimator': {**machine, 'load_kg': float(args.load_kg), 'exit_at_end': True,
                             'live_clock': 'wall' if args.mode == 'realtime' else 'simulation'},
    }
    root = getattr(args, 'program_root', None)
    if root is not None:
        # jobs: no program of its own, nothing finishes; each job brings its load
        params['gcode_trajectory'].update(program='', program_root=str(root.resolve()))
        if getattr(args, 'machine_root', None) is not None:
            params['gcode_trajectory']['machine_root'] = str(args.machine_root.resolve())
        params['energy_estimator']['exit_at_end'] = False
        if getattr(args, 'measured_live', False):
            params['measured_live'] = {**machine, 'source': 'job_live'}
    if args.record is not None:
        params['mcap_recorder'] = {'output': str(args.record.resolve()), 'exit_at_end': True}
        if root is not None:      # one recording per job, record/<job_id>/
            params['mcap_recorder'].update(exit_at_end=False, per_job=True)
            params['gcode_trajectory']['record_root'] = str(args.record.resolve())
        if getattr(args, 'plot_rate_hz', None) is not None:
            params['mcap_recorder']['plot_rate_hz'] = float(args.plot_rate_hz)
        if getattr(args, 'start_time', None) is not None:
            params['mcap_recorder']['start_time'] = args.start_time
    return params


def graph_commands(args: argparse.Namespace, overrides: Path, *,
                   extra: tuple[str, ...] = ()) -> dict[str, list[str]]:
    """The command of every node of the graph (and of the ``extra`` nodes, ``serve``'s
    ``opcua_bridge``): ``--params`` (or graph.yaml), then ``overrides`` (the file
    :func:`write_params_file` made from the options)."""
    params_file = args.params if args.params is not None else config_dir() / 'graph.yaml'
    files = ([params_file] if params_file.is_file() else []) + [overrides]
    return {name: node_command(name, params_files=files)
            for name in [*graph_parameters(args), *extra]}


def node_environment(domain_id: int | None) -> dict[str, str]:
    """The nodes' environment: this package first on ``PYTHONPATH``, the domain id."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [_package_root()] + ([env['PYTHONPATH']] if env.get('PYTHONPATH') else []))
    if domain_id is not None:
        env['ROS_DOMAIN_ID'] = str(domain_id)
    return env


def private_parameter_dir() -> Path:
    """A new private directory (mode 0700) for this run's parameter file; the caller
    removes it. Directories of launchers that died without removing theirs go first."""
    remove_stale_parameter_dirs()
    return Path(tempfile.mkdtemp(prefix=f'{_PRIVATE_PREFIX}{os.getpid()}-'))


def _niced(arm: Callable[[], None], niceness: int) -> Callable[[], None]:
    """``arm``, then the niceness raised by ``niceness`` (in the child, before exec)."""
    if niceness <= 0:
        return arm

    def _arm() -> None:
        arm()
        os.nice(niceness)
    return _arm


class Supervisor:
    """Child processes of the graph: start, watch, stop.

    Parameters
    ----------
    commands
        ``{name: argv}``.
    finishers
        Names whose exit with code 0 means "done"; any other exit is a failure.
    env
        Environment of the children.
    niceness
        ``{name: n}``: children started with their scheduling niceness raised by ``n``
        (before their program runs, so every thread of theirs has it).
    """

    FINISH_GRACE_S = 10.0

    def __init__(self, commands: dict[str, list[str]], *, finishers: set[str],
                 env: dict[str, str], echo: bool = True,
                 niceness: dict[str, int] | None = None) -> None:
        self.commands = commands
        self.niceness = dict(niceness or {})
        self.finishers = set(finishers)
        self.env = env
        self.echo = echo
        self.procs: dict[str, subprocess.Popen] = {}
        self.pgid: int | None = None
        self._finished_at: dict[str, float] = {}
        self.logs: dict[str, list[str]] = {name: [] for name in commands}
        self._threads: list[threading.Thread] = []

    def start(self) -> None:
        """Start every child in one new process group that dies with the launcher.

        All children are started before the first log thread: ``preexec_fn`` (which arms
        the parent-death signal) is not safe while other threads run.
        """
        env = dict(self.env)
        env[lifeline.ENV] = str(os.getpid())
        arm = lifeline.preexec(os.getpid())
        for name, cmd in self.commands.items():
            self.procs[name] = self._spawn(cmd, env, _niced(arm, self.niceness.get(name, 0)))
        for name, proc in self.procs.items():
            thread = threading.Thread(target=self._pump, args=(name, proc), daemon=True)
            thread.start()
            self._threads.append(thread)

    def _spawn(self, cmd: list[str], env: dict[str, str], arm) -> subprocess.Popen:
        group = 0 if self.pgid is None else self.pgid
        try:
            proc = subprocess.Popen(cmd, env=env, stdin=subprocess.DEVNULL,
                                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                    process_group=group, preexec_fn=arm)
        except (OSError, subprocess.SubprocessError):
            if group == 0:
                raise
            # setpgid refused: the group's first process is gone already (it failed at
            # once and was reaped); start a new group (a real start failure raises again).
            self.pgid = None
            return self._spawn(cmd, env, arm)
        if self.pgid is None:
            self.pgid = proc.pid
        return proc

    def _pump(self, name: str, proc: subprocess.Popen) -> None:
        for line in proc.stdout:
            line = line.rstrip('\n')
            self.logs[name].append(line)
            if self.echo:
                print(f'[{name}] {line}', flush=True)

    def poll(self) -> tuple[str, str | None]:
        """``('running', None)``, ``('done', None)`` or ``('failed', reason)``.

        The finishers end within moments of each other (the recorder closes when the energy
        estimator's summary arrives, the estimator exits when it is acknowledged); one that
        exited cleanly :attr:`FINISH_GRACE_S` before the others was stopped from outside
        (SIGINT/SIGTERM of that node alone), and the rest would wait for it until a stall
        timeout: that is a failure at once.
        """
        finished = []
        for name, proc in self.procs.items():
            code = proc.poll()
            if code is None:
                continue
            if code != 0:
                return 'failed', f'{name} exited with code {code}'
            if name not in self.finishers:
                return 'failed', f'{name} exited before the program finished'
            finished.append(name)
            self._finished_at.setdefault(name, time.monotonic())
        if self.finishers and len(finished) == len(self.finishers):
            return 'done', None
        if finished and time.monotonic() - min(
                self._finished_at.values()) > self.FINISH_GRACE_S:
            waiting = sorted(self.finishers - set(finished))
            return 'failed', (f'{finished[0]} exited but {", ".join(waiting)} did not finish '
                              f'within {self.FINISH_GRACE_S:g} s (was it stopped?)')
        return 'running', None

    def stop(self, *, timeout_s: float = 5.0) -> None:
        """SIGINT every running child, then SIGKILL the group if any is left after ``timeout_s``.

        The group is signalled only while one of its children is unreaped, so its id cannot
        have been reused by an unrelated process.
        """
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + timeout_s
        for proc in self.procs.values():
            try:
                proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                self._kill_group()
                proc.kill()
                proc.wait()
        for thread in self._threads:
            thread.join(timeout=1.0)

    def _kill_group(self) -> None:
        if self.pgid is None:
            return
        try:
            os.killpg(self.pgid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass


def _describe_bag(path: Path) -> None:
    from feed_axis_energy.record import bagio
    topics = bagio.bag_topics(path)
    print(f'recording: {path}')
    wide = max((len(t) for t in topics), default=0)
    wide_type = max((len(m) for m, _ in topics.values()), default=0)
    for topic, (msgtype, count) in sorted(topics.items()):
        print(f'  {topic:<{wide}}  {msgtype:<{wide_type}}  {count} messages')
    if bagio.TOPIC_POWER in topics:
        power = bagio.read_series(path, bagio.TOPIC_POWER)
        if power.t.shape[0]:
            energies = ', '.join(f'{n} {e:.3f} J' for n, e in
                                 zip(power.names, power.positions[-1]))
            print(f'  {power.t.shape[0]} samples, {power.t[-1] - power.t[0]:.3f} s; '
                  f'energy: {energies}')
    blocks = bagio.read_block_energy(path) if bagio.TOPIC_BLOCK_ENERGY in topics else []
    if blocks:
        print(f'  block energy of {len(blocks)} source lines (topic /block_energy)')


def _supervise(sup: Supervisor, *, timeout: float | None):
    """Start the graph and wait: ``(state, reason, stop signals, start time)``."""
    stop_reason: list[str] = []

    def on_signal(signum, frame) -> None:
        stop_reason.append(signal.Signals(signum).name)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    t0 = time.monotonic()
    state, reason = 'running', None
    try:
        sup.start()
        while True:
            state, reason = sup.poll()
            if state != 'running' or stop_reason:
                break
            if timeout is not None and time.monotonic() - t0 > timeout:
                state, reason = 'failed', f'timeout after {timeout:g} s'
                break
            time.sleep(0.1)
    finally:
        sup.stop()
        for s, handler in old.items():
            signal.signal(s, handler)
    return state, reason, stop_reason, t0


def check_job_record(args: argparse.Namespace) -> str | None:
    """What is wrong with ``--record`` (and ``--start-time``) for jobs, or ``None``
    (``launch --program-root`` and ``serve``)."""
    if os.path.islink(args.record):
        return f'--record {args.record}: a symbolic link; give the directory itself'
    if os.path.lexists(args.record) and not args.record.is_dir():
        return f'--record {args.record}: exists and is not a directory'
    if args.start_time is not None and args.start_time.strip().lower() != 'now':
        return ('--start-time with --program-root: only "now" (each job\'s recording starts '
                'when the job does)')
    return None


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    if args.program_root is not None and args.record is not None:
        problem = check_job_record(args)
        if problem:
            print(f'error: {problem}', file=sys.stderr)
            return 2
    elif args.record is not None and os.path.lexists(args.record):
        # lexists: a dangling symlink counts (the recorder would refuse it after start-up)
        msg = f'{args.record} exists already; choose a new output directory'
        raise FileExistsError(msg)
    if args.program is not None and not args.program.is_file():
        print(f'error: {args.program}: no such program file', file=sys.stderr)
        return 1
    if args.record is None and (args.plot_rate_hz is not None or args.start_time is not None):
        print('error: --plot-rate-hz and --start-time apply to the recording; give --record',
              file=sys.stderr)
        return 2
    if args.program_root is not None:
        if args.program is not None:
            print('error: --program-root runs jobs; it excludes --program', file=sys.stderr)
            return 2
        if not args.program_root.is_dir():
            print(f'error: --program-root {args.program_root}: not a directory', file=sys.stderr)
            return 2
    elif args.machine_root is not None or args.measured_live:
        option = '--machine-root' if args.machine_root is not None else '--measured-live'
        print(f'error: {option} applies to jobs; give --program-root', file=sys.stderr)
        return 2
    if not math.isfinite(args.load_kg) or args.load_kg < 0:
        print(f'error: --load-kg must be a finite mass >= 0 kg, got {args.load_kg}',
              file=sys.stderr)
        return 2
    env = node_environment(args.domain_id)
    finishers = {'energy_estimator'} | ({'mcap_recorder'} if args.record is not None else set())
    if args.program_root is not None:
        finishers = set()      # a job graph runs until it is stopped
    # the options' parameter file lives in a private directory (mode 0700) for this run only
    private = private_parameter_dir()
    try:
        overrides = write_params_file(private, graph_parameters(args))
        state, reason, stop_reason, t0 = _supervise(
            Supervisor(graph_commands(args, overrides), finishers=finishers, env=env),
            timeout=args.timeout)
    finally:
        shutil.rmtree(private, ignore_errors=True)
    if stop_reason:
        print(f'stopped by {stop_reason[0]}; all nodes shut down', file=sys.stderr)
        if args.program_root is not None and args.record is not None:
            print(f'recordings: {args.record}/<job_id>/')
        elif args.record is not None and (args.record / 'metadata.yaml').is_file():
            _describe_bag(args.record)
        return 130
    if state == 'failed':
        print(f'error: {reason}; all nodes stopped', file=sys.stderr)
        return 1
    if args.record is not None:
        # A recorder stopped alone near the end exits 0 like a finished one; its bag must
        # hold what the end marker says was sent, or the launch is not a success.
        from feed_axis_energy.graph import recording_gaps
        gaps = recording_gaps(args.record)
        if gaps:
            print(f'error: {args.record}: incomplete recording: {"; ".join(gaps)}',
                  file=sys.stderr)
            return 1
    print(f'graph finished in {time.monotonic() - t0:.2f} s')
    if args.record is not None:
        _describe_bag(args.record)
    return 0
