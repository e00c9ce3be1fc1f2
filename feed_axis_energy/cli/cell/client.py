"""``feed-axis-energy cell-client``: run programs as jobs on a ``serve`` and print the results.

An OPC UA client (asyncua) of the address space in docs/cell.md, as a cell controller would
use it: for each program ``StartJob(JobId, Program, LoadKg)``, then wait until
``Results/LastJob/JobId`` names the job, then ``Results/GetResult(JobId)``; the results are
printed with units (``--json``: one JSON object per job). Exit 1 when a job is refused, does
not end within ``--timeout`` or ends other than ``ended``; the message says which and why.
Anonymous, without encryption, by default: a server on loopback (``serve``'s default). A
server bound elsewhere takes only ``Basic256Sha256`` ``SignAndEncrypt`` with a user name
(docs/cell.md, "Security"): ``--cert``/``--key`` give the client's certificate (its
application URI is read from the certificate) and ``--user`` the name, whose password comes
from the environment variable ``FAE_OPCUA_PASSWORD`` (never from the command line, where
other users of the machine could read it).
"""
from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
from pathlib import Path
import sys
import time

__all__ = ['add_parser', 'run', 'format_result']

NAMESPACE = 'urn:feed-axis-energy:cell'
PASSWORD_ENV = 'FAE_OPCUA_PASSWORD'
J_PER_WH = 3600.0


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the subcommand."""
    p = sub.add_parser(
        'cell-client', help='run programs as jobs on a serve over OPC UA; print the results',
        description='Submit each PROGRAM as a job to a running "feed-axis-energy serve" '
                    'over OPC UA (StartJob), wait for its end and print its result with units.')
    p.add_argument('programs', nargs='+', metavar='PROGRAM',
                   help="program path as the server resolves it: relative to its "
                        "--program-root, or absolute inside it")
    p.add_argument('--endpoint', default='opc.tcp://127.0.0.1:4840/feed_axis_energy/',
                   metavar='URL', help='the server (default: %(default)s)')
    p.add_argument('--load-kg', type=float, default=0.0, metavar='KG',
                   help='workpiece mass of every job [kg] (default 0)')
    p.add_argument('--job-prefix', default=None, metavar='TEXT',
                   help='job ids are TEXT-1, TEXT-2, ... (default: job-<time>; an id must '
                        'not repeat one whose result the server keeps)')
    p.add_argument('--timeout', type=float, default=600.0, metavar='S',
                   help='longest wait for one job [s] (default 600)')
    p.add_argument('--user', default=None, metavar='NAME',
                   help='log in as NAME; the password is read from the environment variable '
                        f'{PASSWORD_ENV} (a server off loopback requires a user)')
    p.add_argument('--cert', type=Path, default=None, metavar='FILE',
                   help='client certificate (DER or PEM): connect with Basic256Sha256 '
                        'SignAndEncrypt (needs --key)')
    p.add_argument('--key', type=Path, default=None, metavar='FILE',
                   help='private key of --cert (PEM)')
    p.add_argument('--json', action='store_true', help='one JSON result per line')
    p.set_defaults(run=run)


def format_result(result: dict) -> str:
    """One result as text with units (the keys of docs/cell.md)."""
    energy = float(result['energy_j'])
    lines = [f"job {result['job_id']}: {result['status']} ({result.get('message', '')})",
             f"  program      {result.get('program', '?')}",
             f"  load         {float(result.get('load_kg', 0.0)):g} kg",
             f"  duration     {float(result['duration_s']):.3f} s",
             f"  energy       {energy:.3f} J ({energy / J_PER_WH:.5f} Wh), mechanical, all axes",
             f"  peak power   {float(result['peak_power_w']):.2f} W"]
    by_axis = result.get('energy_by_axis_j') or {}
    if by_axis:
        lines.append('  per axis     ' + ', '.join(f'{axis} {float(value):.3f} J'
                                                   for axis, value in by_axis.items()))
    electrical = result.get('electrical')
    if isinstance(electrical, dict) and 'supply_energy_j' in electrical:
        supply = float(electrical['supply_energy_j']['total'])
        lines.append(f'  supply side  {supply:.3f} J (drives declared)')
    return '\n'.join(lines)


class _Failed(Exception):
    pass


def _application_uri(cert: Path) -> str:
    """The URI in a certificate's subject alternative name (what the server checks the
    client's application URI against)."""
    from cryptography import x509
    data = cert.read_bytes()
    try:
        loaded = (x509.load_pem_x509_certificate(data) if data.lstrip().startswith(b'-----')
                  else x509.load_der_x509_certificate(data))
        names = loaded.extensions.get_extension_for_class(x509.SubjectAlternativeName)
        uris = names.value.get_values_for_type(x509.UniformResourceIdentifier)
    except (ValueError, x509.ExtensionNotFound) as err:
        raise _Failed(f'--cert {cert}: not a certificate with an application URI '
                      f'({err})') from None
    if not uris:
        raise _Failed(f'--cert {cert}: the certificate names no application URI')
    return str(uris[0])


async def _secure(client, args: argparse.Namespace) -> None:
    """User name and password, certificate and encryption as the options ask."""
    if args.user is not None:
        password = os.environ.get(PASSWORD_ENV)
        if password is None:
            raise _Failed(f'--user {args.user}: set the password in the environment variable '
                          f'{PASSWORD_ENV}')
        client.set_user(args.user)
        client.set_password(password)
    if args.cert is not None:
        from asyncua import ua
        from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256
        client.application_uri = _application_uri(args.cert)
        await client.set_security(SecurityPolicyBasic256Sha256, str(args.cert), str(args.key),
                                  mode=ua.MessageSecurityMode.SignAndEncrypt)


async def _run_jobs(args: argparse.Namespace) -> int:
    from asyncua import Client
    prefix = args.job_prefix or f'job-{time.strftime("%Y%m%dT%H%M%S")}'
    client = Client(args.endpoint, timeout=30)
    client.session_timeout = 600_000    # the server's limit [ms]; more is only a warning
    await _secure(client, args)
    try:
        await client.connect()
    except (OSError, asyncio.TimeoutError) as err:
        raise _Failed(f'cannot connect to {args.endpoint}: {err or type(err).__name__} '
                      '(is feed-axis-energy serve running?)') from None
    except Exception as err:     # asyncua's refusals: security, identity, bad password
        raise _Failed(f'{args.endpoint} refused the connection: {err or type(err).__name__}'
                      + ('' if args.user or args.cert else ' (a server off loopback needs '
                         '--cert, --key and --user)')) from None
    code = 0
    try:
        try:
            idx = await client.get_namespace_index(NAMESPACE)
        except ValueError:
            raise _Failed(f'{args.endpoint} has no namespace {NAMESPACE}: not a '
                          'feed-axis-energy serve') from None
        root = await client.nodes.objects.get_child([f'{idx}:FeedAxisEnergy'])
        jobs = await root.get_child(f'{idx}:Jobs')
        results = await root.get_child(f'{idx}:Results')
        last_id = await results.get_child([f'{idx}:LastJob', f'{idx}:JobId'])
        for number, program in enumerate(args.programs, start=1):
            job_id = f'{prefix}-{number}'
            accepted, message = await jobs.call_method(f'{idx}:StartJob', job_id, program,
                                                       float(args.load_kg))
            if not accepted:
                raise _Failed(f'job {job_id} ({program}) refused: {message}')
            end = time.monotonic() + args.timeout
            while await last_id.read_value() != job_id:
                if time.monotonic() > end:
                    await jobs.call_method(f'{idx}:AbortJob', job_id)
                    raise _Failed(f'job {job_id} did not end within {args.timeout:g} s '
                                  '(aborted)')
                await asyncio.sleep(0.05)
            found, text, message = await results.call_method(f'{idx}:GetResult', job_id)
            if not found:
                raise _Failed(f'job {job_id}: no result: {message}')
            result = json.loads(text)
            print(json.dumps(result, sort_keys=True) if args.json else format_result(result),
                  flush=True)
            if result['status'] != 'ended':
                code = 1
    finally:
        await client.disconnect()
    return code


def run(args: argparse.Namespace) -> int:
    """Run the subcommand."""
    if not math.isfinite(args.load_kg) or args.load_kg < 0:
        print(f'error: --load-kg must be a finite mass >= 0 kg, got {args.load_kg}',
              file=sys.stderr)
        return 2
    if not math.isfinite(args.timeout) or args.timeout <= 0:
        print(f'error: --timeout must be a positive number of seconds, got {args.timeout}',
              file=sys.stderr)
        return 2
    if (args.cert is None) != (args.key is None):
        print('error: --cert and --key go together', file=sys.stderr)
        return 2
    for option, path in (('--cert', args.cert), ('--key', args.key)):
        if path is not None and not path.is_file():
            print(f'error: {option} {path}: no such file', file=sys.stderr)
            return 2
    if args.user is not None and not args.user.strip():
        print('error: --user needs a name', file=sys.stderr)
        return 2
    try:
        return asyncio.run(_run_jobs(args))
    except _Failed as err:
        print(f'error: {err}', file=sys.stderr)
        return 1
