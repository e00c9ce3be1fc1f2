"""``feed-axis-energy serve`` refuses what it cannot serve before it starts anything: a clear
message and a non-zero exit, no node started (the running service:
test/nodes/test_serve_e2e.py); ``cell-client`` without a server or with bad options."""
from __future__ import annotations

import os
from pathlib import Path
import socket
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _serve(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT), env.get('PYTHONPATH', '')])
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'serve', *args],
                          capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT)


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def test_help_names_every_option():
    done = _serve('--help')
    assert done.returncode == 0, done.stderr
    for option in ('--program-root', '--machine', '--opcua-port', '--opcua-host', '--mqtt',
                   '--domain-id', '--opcua-cert', '--opcua-key', '--opcua-users', '--mode',
                   '--measured-live', '--mqtt-sparkplug', '--bridge-nice'):
        assert option in done.stdout


@pytest.fixture
def root(tmp_path: Path) -> Path:
    (tmp_path / 'programs').mkdir()
    return tmp_path / 'programs'


def test_program_root_missing(tmp_path):
    done = _serve('--program-root', str(tmp_path / 'nope'), '--opcua-port', str(_free_port()))
    assert done.returncode == 2
    assert 'nope: not a directory' in done.stderr and 'Traceback' not in done.stderr


@pytest.mark.parametrize('value', ['-1', '20'])
def test_bridge_nice_out_of_range(root, value):
    done = _serve('--program-root', str(root), '--opcua-port', str(_free_port()),
                  '--bridge-nice', value)
    assert done.returncode == 2
    assert f'--bridge-nice {value}: expected 0 ... 19' in done.stderr
    assert 'Traceback' not in done.stderr


def test_measured_live_needs_realtime(root):
    done = _serve('--program-root', str(root), '--opcua-port', str(_free_port()),
                  '--mode', 'fast', '--measured-live')
    assert done.returncode == 2
    assert '--measured-live needs --mode realtime' in done.stderr


def test_opcua_port_in_use(root):
    with socket.socket() as busy:
        busy.bind(('127.0.0.1', 0))
        busy.listen()
        port = busy.getsockname()[1]
        done = _serve('--program-root', str(root), '--opcua-port', str(port))
    assert done.returncode == 1
    assert f'cannot listen on 127.0.0.1:{port} for OPC UA' in done.stderr
    assert 'Traceback' not in done.stderr


def test_broker_unreachable(root):
    port = _free_port()
    done = _serve('--program-root', str(root), '--opcua-port', str(_free_port()),
                  '--mqtt', f'127.0.0.1:{port}')
    assert done.returncode == 1
    assert f'cannot reach the MQTT broker at 127.0.0.1:{port}' in done.stderr


@pytest.mark.parametrize('text', ['localhost', 'h:0', 'h:99999', ':1883', 'h:x'])
def test_bad_broker_text(root, text):
    done = _serve('--program-root', str(root), '--opcua-port', str(_free_port()),
                  '--mqtt', text)
    assert done.returncode == 2 and '--mqtt expects HOST:PORT' in done.stderr


def test_off_loopback_needs_certificate_and_users(root, tmp_path):
    done = _serve('--program-root', str(root), '--opcua-host', '0.0.0.0',
                  '--opcua-port', str(_free_port()))
    assert done.returncode == 2
    assert 'requires Basic256Sha256' in done.stderr
    assert 'a server certificate' in done.stderr and 'at least one user' in done.stderr
    users = tmp_path / 'users'
    users.write_text('operator\n')
    done = _serve('--program-root', str(root), '--opcua-users', str(users),
                  '--opcua-port', str(_free_port()))
    assert done.returncode == 2 and f'{users}:1' in done.stderr


def _client(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT), env.get('PYTHONPATH', '')])
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'cell-client', *args],
                          capture_output=True, text=True, timeout=60, env=env, cwd=ROOT)


def test_cell_client_without_a_server():
    port = _free_port()
    done = _client('--endpoint', f'opc.tcp://127.0.0.1:{port}/feed_axis_energy/', 'a.nc')
    assert done.returncode == 1 and 'Traceback' not in done.stderr
    assert f'cannot connect to opc.tcp://127.0.0.1:{port}/' in done.stderr
    assert 'is feed-axis-energy serve running?' in done.stderr


@pytest.mark.parametrize('args', [['--load-kg', 'nan', 'a.nc'], ['--timeout', '0', 'a.nc']])
def test_cell_client_bad_options(args):
    done = _client(*args)
    assert done.returncode == 2 and done.stderr.startswith('error: --')


@pytest.mark.parametrize('kind, words', [('link', 'a symbolic link'),
                                         ('file', 'not a directory')])
def test_record_must_be_a_directory_not_a_link(root, tmp_path, kind, words):
    (tmp_path / 'elsewhere').mkdir()
    target = tmp_path / 'rec'
    if kind == 'link':
        target.symlink_to(tmp_path / 'elsewhere')
    else:
        target.write_text('')
    done = _serve('--program-root', str(root), '--opcua-port', str(_free_port()), '--record',
                  str(target))
    assert done.returncode == 2, done.stderr
    assert words in done.stderr and 'Traceback' not in done.stderr
    assert os.listdir(tmp_path / 'elsewhere') == []


def test_record_reaches_the_graph_as_launch_gives_it(tmp_path):
    import argparse
    from feed_axis_energy.cli.launch import graph_parameters
    from feed_axis_energy.cli.cell import serve
    parser = argparse.ArgumentParser()
    serve.add_parser(parser.add_subparsers())
    args = parser.parse_args(['serve', '--program-root', str(tmp_path), '--record',
                              str(tmp_path / 'rec')])
    args.program, args.load_kg, args.plot_rate_hz, args.start_time = None, 0.0, None, None
    params = graph_parameters(args)
    assert params['mcap_recorder']['per_job'] is True
    assert params['gcode_trajectory']['record_root'] == str((tmp_path / 'rec').resolve())


def test_trusted_client_certificates_are_checked_and_passed_to_the_bridge(root, tmp_path):
    import argparse
    from feed_axis_energy.cli.cell.serve import add_parser, bridge_parameters
    missing = _serve('--program-root', str(root), '--opcua-port', str(_free_port()),
                     '--opcua-trust', str(tmp_path / 'nope.der'))
    assert missing.returncode == 2 and '--opcua-trust' in missing.stderr
    cert = tmp_path / 'client.der'
    cert.write_bytes(b'not checked here')
    plain = _serve('--program-root', str(root), '--opcua-port', str(_free_port()),
                   '--opcua-trust', str(cert))
    assert plain.returncode == 2 and 'needs --opcua-cert and --opcua-key' in plain.stderr
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    args = parser.parse_args(['serve', '--program-root', str(root), '--opcua-trust', str(cert),
                              '--opcua-trust', str(cert)])
    assert bridge_parameters(args)['opcua_trusted_clients'] == f'{cert.resolve()},{cert.resolve()}'
    args = parser.parse_args(['serve', '--program-root', str(root)])
    assert 'opcua_trusted_clients' not in bridge_parameters(args)


@pytest.mark.parametrize('extra, words', [
    (['--mqtt-sparkplug', 'plant1/cell3'], '--mqtt-sparkplug needs --mqtt'),
    (['--mqtt', '127.0.0.1:1883', '--mqtt-sparkplug', 'plant1'], 'GROUP_ID/EDGE_NODE_ID'),
    (['--mqtt', '127.0.0.1:1883', '--mqtt-sparkplug', 'a/b/c'], 'Sparkplug id'),
    (['--mqtt', '127.0.0.1:1883', '--mqtt-sparkplug', 'a/b#'], 'Sparkplug id'),
])
def test_sparkplug_option_is_checked_before_anything_starts(root, extra, words):
    done = _serve('--program-root', str(root), '--opcua-port', str(_free_port()), *extra)
    assert done.returncode == 2, done.stderr
    assert words in done.stderr and 'Traceback' not in done.stderr


def test_sparkplug_option_reaches_the_bridge(root):
    import argparse
    from feed_axis_energy.cli.cell.serve import add_parser, bridge_parameters
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    args = parser.parse_args(['serve', '--program-root', str(root), '--mqtt', 'h:1883',
                              '--mqtt-sparkplug', 'plant1/cell3', '--mqtt-machine', 'dmc'])
    params = bridge_parameters(args)
    assert params['sparkplug'] == 'plant1/cell3' and params['mqtt_machine'] == 'dmc'
    args = parser.parse_args(['serve', '--program-root', str(root), '--mqtt', 'h:1883'])
    assert 'sparkplug' not in bridge_parameters(args)
