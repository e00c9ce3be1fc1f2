"""``feed-axis-energy serve``: the node graph as a job service with OPC UA (and MQTT).

Starts the graph in job mode as ``launch --program-root`` does (the same
:func:`~feed_axis_energy.cli.launch.graph_commands` and
:class:`~feed_axis_energy.cli.launch.Supervisor`) plus the ``opcua_bridge`` node, prints the
endpoints once the bridge says it is ready, and runs until SIGINT/SIGTERM (every process
stopped, exit 0). A failure at start-up (program root missing, OPC UA port in use, broker
unreachable, off-loopback without certificate and users) or a node that dies later: a
message on stderr, every process stopped, exit 1 (2 for a usage error).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import shutil
import signal
import socket
import sys
import time

from feed_axis_energy.cli.launch import (check_job_record, graph_commands, node_environment,
                                         private_parameter_dir, Supervisor, write_params_file)

__all__ = ['add_parser', 'run', 'parse_broker', 'bridge_parameters']

READY_MARK = 'ready: '
BRIDGE_NICE = 5
"""Default scheduling niceness of the ``opcua_bridge`` process (``--bridge-nice``): with 20
OPC UA sessions on a 2-core PC the bridge took 18 % of a core and the graph's own latency
spread (p99 - p50) grew from 4.7 to 11.3 ms at niceness 0 (docs/cell.md, "Interleaved")."""


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'serve', help='run the node graph as a job service with an OPC UA server (and MQTT)',
        description='Start the node graph in job mode (docs/nodes.md, Jobs) with the '
                    'opcua_bridge node: an OPC UA server (StartJob, AbortJob, State, live '
                    'power, results; docs/cell.md) and, with --mqtt, the MQTT bridge. Prints '
                    'the endpoints when ready and runs until Ctrl-C or SIGTERM (exit 0).')
    p.add_argument('--program-root', type=Path, required=True, metavar='DIR',
                   help='jobs run programs inside DIR only (absolute or relative paths)')
    p.add_argument('--machine', type=Path, default=None, metavar='YAML',
                   help='machine config of the jobs (default: the demonstrator)')
    p.add_argument('--machine-root', type=Path, default=None, metavar='DIR',
                   help='a job may name a machine YAML inside DIR (ROS job interface)')
    p.add_argument('--mode', choices=('fast', 'realtime'), default='realtime',
                   help='realtime: jobs paced by the wall clock, live data stamped in '
                        'wall-clock time (default); fast: as fast as possible')
    p.add_argument('--opcua-host', default='127.0.0.1', metavar='H',
                   help='address the OPC UA server binds (default 127.0.0.1; anything but '
                        'loopback needs --opcua-cert, --opcua-key and --opcua-users)')
    p.add_argument('--opcua-port', type=int, default=4840, metavar='N',
                   help='OPC UA server port (default 4840)')
    p.add_argument('--opcua-cert', type=Path, default=None, metavar='FILE',
                   help='server certificate (DER or PEM): enables Basic256Sha256')
    p.add_argument('--opcua-key', type=Path, default=None, metavar='FILE',
                   help='private key of --opcua-cert (PEM)')
    p.add_argument('--opcua-users', type=Path, default=None, metavar='FILE',
                   help='users who may log in: one name:password a line')
    p.add_argument('--opcua-trust', type=Path, action='append', default=[], metavar='FILE',
                   help='a client certificate (DER or PEM) accepted on a secure channel; '
                        'repeatable; default: any client certificate (the password guards '
                        'the access)')
    p.add_argument('--mqtt', default=None, metavar='HOST:PORT',
                   help='MQTT broker: publish job state, live power and results, take '
                        'measured drive data (docs/cell.md); default: no MQTT')
    p.add_argument('--mqtt-prefix', default='feed_axis_energy', metavar='TOPIC',
                   help='first MQTT topic levels (default feed_axis_energy)')
    p.add_argument('--mqtt-machine', default='machine', metavar='NAME',
                   help='machine name, one MQTT topic level (default machine)')
    p.add_argument('--mqtt-sparkplug', default=None, metavar='GROUP_ID/EDGE_NODE_ID',
                   help='also publish job state, live power and results as a Sparkplug B edge '
                        'node on the --mqtt broker, the machine (--mqtt-machine) as its device '
                        '(spBv1.0/GROUP_ID/...; docs/cell.md, Sparkplug B)')
    p.add_argument('--measured-live', action='store_true',
                   help='also start measured_live: live measured drive data (measured/live, '
                        'from MQTT measured/<axis> with --mqtt) compared with each running '
                        'job\'s prediction on measured/comparison (docs/nodes.md, '
                        'measured_live; needs --mode realtime)')
    p.add_argument('--record', type=Path, default=None, metavar='DIR',
                   help='record every job to DIR/<job_id>/ (rosbag2/MCAP, as launch '
                        '--program-root --record; DIR may exist, a job whose recording '
                        'exists is refused)')
    p.add_argument('--domain-id', type=int, default=None, metavar='N',
                   help='ROS_DOMAIN_ID for the graph (default: inherited)')
    p.add_argument('--params', type=Path, default=None, metavar='YAML',
                   help='node parameter file (default: config/graph.yaml)')
    p.add_argument('--ready-timeout', type=float, default=120.0, metavar='S',
                   help='give up (exit 1) if not ready after this many seconds (default 120)')
    p.add_argument('--bridge-nice', type=int, default=BRIDGE_NICE, metavar='N',
                   help='scheduling niceness added to the opcua_bridge process, 0-19: the '
                        'bridge yields the CPU to the graph\'s nodes on a busy cell PC, so '
                        'OPC UA and MQTT clients wait before the graph does (default '
                        f'{BRIDGE_NICE}; 0 keeps the launcher\'s)')
    p.add_argument('--verbose', action='store_true', help="echo the nodes' log lines")
    p.set_defaults(run=run)


def parse_broker(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``[::1]:1883`` for IPv6) -> ``(host, port)``; ``ValueError`` if not."""
    host, colon, port = text.rpartition(':')
    host = host[1:-1] if host.startswith('[') and host.endswith(']') else host
    if not colon or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        msg = f'--mqtt expects HOST:PORT with a port 1...65535, got {text!r}'
        raise ValueError(msg)
    return host, int(port)


def bridge_parameters(args: argparse.Namespace) -> dict[str, object]:
    """The ``opcua_bridge`` node's parameters from the options."""
    params: dict[str, object] = {
        'opcua_host': args.opcua_host, 'opcua_port': int(args.opcua_port),
        'mqtt_prefix': args.mqtt_prefix, 'mqtt_machine': args.mqtt_machine}
    if args.machine is not None:
        params['machine'] = str(args.machine.resolve())
    for key, path in (('opcua_certificate', args.opcua_cert),
                      ('opcua_private_key', args.opcua_key),
                      ('opcua_users_file', args.opcua_users)):
        if path is not None:
            params[key] = str(path.resolve())
    if args.opcua_trust:
        params['opcua_trusted_clients'] = ','.join(str(p.resolve()) for p in args.opcua_trust)
    if args.mqtt is not None:
        host, port = parse_broker(args.mqtt)
        params.update(mqtt_host=host, mqtt_port=port)
    if getattr(args, 'mqtt_sparkplug', None):
        params['sparkplug'] = args.mqtt_sparkplug
    return params


def _fail(message: str, code: int = 1) -> int:
    print(f'error: {message}', file=sys.stderr)
    return code


def _check(args: argparse.Namespace) -> int:
    """Checks before anything starts: 0, or the exit code after the message."""
    if not args.program_root.is_dir():
        return _fail(f'--program-root {args.program_root}: not a directory', 2)
    if not 0 <= args.bridge_nice <= 19:
        return _fail(f'--bridge-nice {args.bridge_nice}: expected 0 ... 19', 2)
    if args.machine is not None and not args.machine.is_file():
        return _fail(f'--machine {args.machine}: no such file', 2)
    if args.machine_root is not None and not args.machine_root.is_dir():
        return _fail(f'--machine-root {args.machine_root}: not a directory', 2)
    if args.measured_live and args.mode != 'realtime':
        return _fail('--measured-live needs --mode realtime: only then are the predictions '
                     'stamped in wall-clock time, as live measured data are', 2)
    if args.record is not None:
        args.start_time = None
        problem = check_job_record(args)
        if problem:
            return _fail(problem, 2)
    if not 1 <= args.opcua_port <= 65535:
        return _fail(f'--opcua-port must be 1...65535, got {args.opcua_port}', 2)
    if not math.isfinite(args.ready_timeout) or args.ready_timeout <= 0:
        return _fail(f'--ready-timeout must be a positive number of seconds, got '
                     f'{args.ready_timeout}', 2)
    for option, path in (('--opcua-cert', args.opcua_cert), ('--opcua-key', args.opcua_key),
                         ('--opcua-users', args.opcua_users)):
        if path is not None and not path.is_file():
            return _fail(f'{option} {path}: no such file', 2)
    for path in args.opcua_trust:
        if not path.is_file():
            return _fail(f'--opcua-trust {path}: no such file', 2)
        if ',' in str(path.resolve()):
            return _fail(f'--opcua-trust {path}: a path with a comma cannot be passed on', 2)
    if args.opcua_trust and args.opcua_cert is None:
        return _fail('--opcua-trust needs --opcua-cert and --opcua-key: client certificates '
                     'are checked on a secure channel only', 2)
    from feed_axis_energy.bridge import OpcUaSecurity, read_users_file, security_plan
    from feed_axis_energy.errors import ConfigError
    try:
        users = read_users_file(args.opcua_users) if args.opcua_users is not None else {}
        security_plan(args.opcua_host, OpcUaSecurity(certificate=args.opcua_cert,
                                                     private_key=args.opcua_key, users=users))
    except ConfigError as err:
        return _fail(str(err), 2)
    family = socket.AF_INET6 if ':' in args.opcua_host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((args.opcua_host, args.opcua_port))
        except OSError as err:
            return _fail(f'cannot listen on {args.opcua_host}:{args.opcua_port} for OPC UA: '
                         f'{err.strerror or err}')
    if args.mqtt_sparkplug is not None:
        from feed_axis_energy.bridge import SparkplugTopics
        if args.mqtt is None:
            return _fail('--mqtt-sparkplug needs --mqtt HOST:PORT (the broker it publishes '
                         'on)', 2)
        try:
            SparkplugTopics.parse(args.mqtt_sparkplug, device_id=args.mqtt_machine)
        except ConfigError as err:
            return _fail(f'--mqtt-sparkplug: {err}', 2)
    if args.mqtt is not None:
        try:
            host, port = parse_broker(args.mqtt)
        except ValueError as err:
            return _fail(str(err), 2)
        try:
            socket.create_connection((host, port), timeout=5.0).close()
        except OSError as err:
            return _fail(f'cannot reach the MQTT broker at {args.mqtt}: {err.strerror or err}')
    return 0


def _tail(sup: Supervisor, name: str, lines: int = 8) -> str:
    logs = [line for line in sup.logs.get(name, []) if line.strip()]
    return '\n'.join(f'  [{name}] {line}' for line in logs[-lines:])


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    code = _check(args)
    if code:
        return code
    # the graph's options as launch takes them (job mode: no program; --record per job)
    args.program, args.load_kg = None, 0.0
    args.plot_rate_hz = args.start_time = None
    from feed_axis_energy.cli.launch import graph_parameters
    params = graph_parameters(args)
    params['opcua_bridge'] = bridge_parameters(args)
    private = private_parameter_dir()
    stop: list[str] = []

    def on_signal(signum, frame) -> None:
        stop.append(signal.Signals(signum).name)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    sup: Supervisor | None = None
    try:
        overrides = write_params_file(private, params)
        sup = Supervisor(graph_commands(args, overrides, extra=('opcua_bridge',)),
                         finishers=set(), env=node_environment(args.domain_id),
                         echo=args.verbose, niceness={'opcua_bridge': args.bridge_nice})
        return _serve(sup, args, stop)
    finally:
        if sup is not None:
            sup.stop(timeout_s=10.0)
        shutil.rmtree(private, ignore_errors=True)
        for s, handler in old.items():
            signal.signal(s, handler)
        if stop:
            print(f'stopped by {stop[0]}; all nodes shut down', file=sys.stderr)


def _serve(sup: Supervisor, args: argparse.Namespace, stop: list[str]) -> int:
    t0 = time.monotonic()
    sup.start()
    ready = False
    while not stop:
        state, reason = sup.poll()
        if state != 'running':
            failed = (reason or '').split(' ', 1)[0]
            tail = _tail(sup, failed) if failed in sup.logs else ''
            return _fail(f'{reason}; all nodes stopped' + (f'\n{tail}' if tail else ''))
        if not ready:
            line = next((ln for ln in sup.logs['opcua_bridge'] if READY_MARK in ln), None)
            if line is not None:
                ready = True
                where = line.split(READY_MARK, 1)[1]
                print(f'serving jobs from {args.program_root.resolve()} '
                      f'({args.mode} mode, ready in {time.monotonic() - t0:.1f} s)')
                for part in where.split('; '):
                    print(f'  {part}')
                print('Ctrl-C or SIGTERM stops it', flush=True)
            elif time.monotonic() - t0 > args.ready_timeout:
                return _fail(f'not ready within {args.ready_timeout:g} s; all nodes stopped'
                             f'\n{_tail(sup, "opcua_bridge")}')
        time.sleep(0.1)
    return 0
