"""``cell-client`` against a server off loopback (Basic256Sha256 SignAndEncrypt, user names
only): with ``--cert``/``--key``/``--user`` and the password in ``FAE_OPCUA_PASSWORD`` its
jobs run; anonymous, with a wrong password or without the password it is refused with a
message, exit 1 or 2, no traceback."""
from __future__ import annotations

import asyncio
import os
from pathlib import Path
import subprocess
import sys

from asyncua.crypto.cert_gen import setup_self_signed_certificate
from conftest import opcua_port
from cryptography.x509.oid import ExtendedKeyUsageOID
from fake_service import FakeJobService

from feed_axis_energy.bridge import OpcUaSecurity, OpcUaSettings, OpcUaThread

ROOT = Path(__file__).resolve().parents[2]


async def _certificate(folder: Path, name: str, uri: str, use) -> tuple[Path, Path]:
    key, cert = folder / f'{name}-key.pem', folder / f'{name}-cert.der'
    await setup_self_signed_certificate(key, cert, uri, 'localhost', [use],
                                        {'organizationName': 'feed_axis_energy tests'})
    return cert, key


def _client(url: str, *args: str, password: str | None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT), env.get('PYTHONPATH', '')])
    env.pop('FAE_OPCUA_PASSWORD', None)
    if password is not None:
        env['FAE_OPCUA_PASSWORD'] = password
    return subprocess.run([sys.executable, '-m', 'feed_axis_energy', 'cell-client',
                           '--endpoint', url, '--timeout', '60', *args],
                          capture_output=True, text=True, timeout=120, env=env, cwd=ROOT)


def test_cell_client_logs_in_with_certificate_and_password(program_root, tmp_path) -> None:
    server_cert, server_key = asyncio.run(_certificate(
        tmp_path, 'server', 'urn:feed-axis-energy:server', ExtendedKeyUsageOID.SERVER_AUTH))
    client_cert, client_key = asyncio.run(_certificate(
        tmp_path, 'client', 'urn:feed-axis-energy:cell-client', ExtendedKeyUsageOID.CLIENT_AUTH))
    security = OpcUaSecurity(certificate=server_cert, private_key=server_key,
                             users={'mes': 'correct horse'})
    service = FakeJobService(program_root)
    port = opcua_port()
    settings = OpcUaSettings(host='0.0.0.0', port=port, security=security)
    with OpcUaThread(service, settings):      # type: ignore[arg-type]
        url = f'opc.tcp://127.0.0.1:{port}/feed_axis_energy/'
        secure = ('--cert', str(client_cert), '--key', str(client_key), '--user', 'mes')
        done = _client(url, 'a.ngc', 'b.ngc', '--job-prefix', 'sec', *secure,
                       password='correct horse')
        assert done.returncode == 0, done.stderr
        assert 'job sec-1: ended' in done.stdout and 'job sec-2: ended' in done.stdout
        assert ' J (' in done.stdout and ' W' in done.stdout          # units shown
        anonymous = _client(url, 'a.ngc', '--job-prefix', 'anon', password=None)
        assert anonymous.returncode == 1
        assert 'refused the connection' in anonymous.stderr
        assert '--cert, --key and --user' in anonymous.stderr
        wrong = _client(url, 'a.ngc', '--job-prefix', 'wrong', *secure, password='nope')
        assert wrong.returncode == 1 and 'refused the connection' in wrong.stderr
        unset = _client(url, 'a.ngc', *secure, password=None)
        assert unset.returncode == 1 and 'FAE_OPCUA_PASSWORD' in unset.stderr
        for out in (anonymous, wrong, unset):
            assert 'Traceback' not in out.stderr
    service.wait()
    half = _client('opc.tcp://127.0.0.1:1/x', 'a.ngc', '--cert', str(client_cert),
                   password=None)
    assert half.returncode == 2 and '--cert and --key go together' in half.stderr
