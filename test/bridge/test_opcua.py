"""The OPC UA server with a real asyncua client over loopback (ports from FAE_OPCUA_PORTS).

The browse paths, argument names, engineering units and timestamps a client relies on are
asserted here as a contract (docs/cell.md); so are the hostile-client cases.
"""
from __future__ import annotations

import asyncio
import datetime
import json
import math
from pathlib import Path
import threading
import time
from typing import Any, Awaitable, Callable

from asyncua import Client, ua
from asyncua.crypto.cert_gen import setup_self_signed_certificate
from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256
from conftest import opcua_port
from cryptography.x509.oid import ExtendedKeyUsageOID
from fake_service import FakeJobService
import pytest

from feed_axis_energy.bridge import (BROWSE_PATHS, ENERGY_NAMES, J_PER_WH, LiveSample,
                                     NAMESPACE_URI, OpcUaBridge, OpcUaSecurity, OpcUaSettings,
                                     OpcUaThread, UNECE_NAMESPACE)
from feed_axis_energy.errors import ConfigError


def run(coro: Awaitable[Any], timeout: float = 60.0) -> Any:
    """Run one test's coroutine with a time limit."""
    async def bounded() -> Any:
        return await asyncio.wait_for(coro, timeout)
    return asyncio.run(bounded())


async def _child(client: Client, path: str) -> Any:
    idx = await client.get_namespace_index(NAMESPACE_URI)
    parts = ['FeedAxisEnergy', *path.split('/')] if path else ['FeedAxisEnergy']
    return await client.nodes.objects.get_child([f'{idx}:{p}' for p in parts])


async def _call(client: Client, method: str, *args: Any) -> list[Any]:
    idx = await client.get_namespace_index(NAMESPACE_URI)
    folder, name = method.split('/')
    parent = await _child(client, folder)
    out = await parent.call_method(f'{idx}:{name}', *args)
    return out if isinstance(out, list) else [out]


async def _until(check: Callable[[], Awaitable[bool]], timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if await check():
            return True
        await asyncio.sleep(0.05)
    return await check()


async def _read(client: Client, path: str) -> Any:
    return await (await _child(client, path)).read_value()


class Switchable:
    """The job service of the module's one server: delegates to the test's own double.

    asyncua takes seconds to build a server's standard address space, so the tests share
    one server (in a thread with its own event loop, as a node would run it) and each test
    switches it to a fresh :class:`FakeJobService`; the bridge's listeners move along.
    """

    def __init__(self, target: FakeJobService):
        self.target = target
        self._listeners: list[Any] = []
        self._unsubscribe: list[Callable[[], None]] = []

    def use(self, target: FakeJobService) -> None:
        for unsubscribe in self._unsubscribe:
            unsubscribe()
        self.target = target
        self._unsubscribe = [target.subscribe(listener) for listener in self._listeners]

    def subscribe(self, listener: Any) -> Callable[[], None]:
        self._listeners.append(listener)
        self._unsubscribe.append(self.target.subscribe(listener))

        def unsubscribe() -> None:
            self._listeners.remove(listener)
            self.use(self.target)
        return unsubscribe

    def __getattr__(self, name: str) -> Any:
        return getattr(self.target, name)


@pytest.fixture(scope='module')
def shared_server(tmp_path_factory) -> Any:
    """One OPC UA server on loopback for the module: ``(bridge, switchable service)``."""
    root = tmp_path_factory.mktemp('idle')
    service = Switchable(FakeJobService(root))
    settings = OpcUaSettings(port=opcua_port(), poll_s=0.05, call_timeout_s=1.0, queue_size=64)
    with OpcUaThread(service, settings) as server:     # type: ignore[arg-type]
        yield server.bridge, service
    assert not any(t.name == 'opcua-bridge' for t in threading.enumerate()), \
        'the server thread outlived stop()'


@pytest.fixture
def served(shared_server: Any) -> Callable[[FakeJobService], OpcUaBridge]:
    """Switch the module's server to a test's service; returns the bridge."""
    bridge, switchable = shared_server

    def use(service: FakeJobService) -> OpcUaBridge:
        switchable.use(service)
        return bridge
    yield use
    switchable.use(FakeJobService(switchable.target.program_root))


async def _idle(client: Client) -> bool:
    return await _until(lambda: _is(client, 'Jobs/State', 'idle'))


def test_every_documented_name_is_there_with_its_type_and_unit(served, program_root) -> None:
    bridge = served(FakeJobService(program_root))
    paths = [*BROWSE_PATHS, *(f'Energy/{a}/{n}' for a in 'XYZ' for n in ENERGY_NAMES)]
    units = {'AcActivePowerTotal': ('W', 'WTT'), 'AcActiveEnergyTotalImport': ('Wh', 'WHR'),
             'AcActiveEnergyTotalExport': ('Wh', 'WHR'), 'EnergyJ': ('J', 'JOU'),
             'DurationS': ('s', 'SEC'), 'PeakPowerW': ('W', 'WTT'), 'Progress': ('%', 'P1')}

    async def main() -> None:
        async with Client(bridge.endpoint) as client:
            for path in paths:
                node = await _child(client, path)
                name = path.rsplit('/', 1)[-1]
                assert (await node.read_browse_name()).Name == name
                if name in ('StartJob', 'AbortJob', 'GetResult'):
                    assert await node.read_node_class() == ua.NodeClass.Method
                    continue
                assert await node.read_node_class() == ua.NodeClass.Variable
                if name in units:
                    symbol, code = units[name]
                    eu = await (await node.get_child('0:EngineeringUnits')).read_value()
                    assert eu.NamespaceUri == UNECE_NAMESPACE
                    assert eu.DisplayName.Text == symbol
                    want = int.from_bytes(code.encode(), 'big')   # OPC 10000-8 UnitId
                    assert eu.UnitId == want
                if path.startswith('Energy/'):
                    text = (await node.read_description()).Text
                    assert 'Predicted' in text and 'not measured' in text
            for method, inputs, outputs in (
                    ('Jobs/StartJob', ['JobId', 'Program', 'LoadKg'], ['Accepted', 'Message']),
                    ('Jobs/AbortJob', ['JobId'], ['Accepted', 'Message']),
                    ('Results/GetResult', ['JobId'], ['Found', 'Result', 'Message'])):
                node = await _child(client, method)
                args = await (await node.get_child('0:InputArguments')).read_value()
                assert [a.Name for a in args] == inputs
                args = await (await node.get_child('0:OutputArguments')).read_value()
                assert [a.Name for a in args] == outputs
            start = await (await _child(client, 'Jobs/StartJob')).get_child('0:InputArguments')
            types = [a.DataType for a in await start.read_value()]
            assert types == [ua.NodeId(ua.ObjectIds.String), ua.NodeId(ua.ObjectIds.String),
                             ua.NodeId(ua.ObjectIds.Double)]
            assert await _idle(client)

    run(main())


def test_two_jobs_run_through_start_job_and_their_results_are_shown(served, program_root) -> None:
    service = FakeJobService(program_root, samples=15, period_s=0.01)
    bridge = served(service)
    dropped = bridge.dropped_events
    stamps: list[int] = []
    service.subscribe(lambda e: stamps.append(e.stamp_ns) if isinstance(e, LiveSample)
                      else None)

    async def main() -> None:
        async with Client(bridge.endpoint) as client:
            for job, program, load in (('job-1', 'a.ngc', 2.0), ('job-2', 'b.ngc', 0.0)):
                accepted, message = await _call(client, 'Jobs/StartJob', job, program,
                                                ua.Variant(load, ua.VariantType.Double))
                assert accepted is True, message
                assert await _until(lambda: _is(client, 'Results/LastJob/JobId', job))
                want = service.result(job)
                assert await _read(client, 'Results/LastJob/Status') == 'ended'
                assert await _read(client, 'Results/LastJob/EnergyJ') == want['energy_j']
                assert await _read(client, 'Results/LastJob/DurationS') == want['duration_s']
                assert await _read(client, 'Results/LastJob/PeakPowerW') == \
                    want['peak_power_w']
                assert await _until(lambda: _is(client, 'Jobs/State', 'ended'))
                assert await _read(client, 'Jobs/ActiveLine') == 15
                assert await _read(client, 'Jobs/Progress') == 100.0
                found, text, message = await _call(client, 'Results/GetResult', job)
                assert found is True and message == ''
                assert json.loads(text) == want
            # the last live values: OPC 34100 names in W and Wh, stamped with the sample
            node = await _child(client, 'Energy/Total/AcActiveEnergyTotalImport')
            value = await node.read_data_value()
            samples = service.samples
            # energy drawn: each axis's positive power integrated, added over the axes
            axes_import = sum(max(service.power_w(i, k), 0.0) * service.period_s
                              for i in range(3) for k in range(samples))
            assert math.isclose(value.Value.Value, axes_import / J_PER_WH, rel_tol=1e-12)
            # power is written with every sample (an energy only when it changes)
            power = await (await _child(client, 'Energy/Total/AcActivePowerTotal')
                           ).read_data_value()
            stamp = power.SourceTimestamp.replace(tzinfo=datetime.timezone.utc).timestamp()
            assert abs(stamp - stamps[-1] / 1e9) < 2e-6    # the last sample's wall clock
            found, text, message = await _call(client, 'Results/GetResult', 'job-9')
            assert (found, text) == (False, '') and "no result of job 'job-9'" in message
        assert bridge.dropped_events == dropped

    run(main())


async def _is(client: Client, path: str, want: Any) -> bool:
    return await _read(client, path) == want


def test_live_power_arrives_as_data_changes_in_wall_clock_time(served, program_root) -> None:
    service = FakeJobService(program_root, samples=30, period_s=0.02)
    bridge = served(service)

    class Handler:
        def __init__(self) -> None:
            self.changes: list[tuple[float, Any]] = []

        def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
            self.changes.append((value, data.monitored_item.Value.SourceTimestamp))

    async def main() -> None:
        async with Client(bridge.endpoint) as client:
            handler = Handler()
            sub = await client.create_subscription(10, handler)
            await sub.subscribe_data_change(await _child(client,
                                                         'Energy/X/AcActivePowerTotal'))
            await asyncio.sleep(0.2)
            before = datetime.datetime.now(datetime.timezone.utc)
            assert (await _call(client, 'Jobs/StartJob', 'live', 'a.ngc', 1.0))[0] is True
            assert await _until(lambda: _is(client, 'Jobs/State', 'ended'))
            await asyncio.sleep(0.2)
            after = datetime.datetime.now(datetime.timezone.utc)
            live = [(v, t) for v, t in handler.changes if t >= before]
            assert len(live) >= 10, handler.changes
            assert all(before <= t <= after for _, t in live)
            values = [v for v, _ in live]
            assert values[-1] == service.power_w(0, service.samples - 1)

    run(main())


BAD_CALLS = [
    (('', 'a.ngc', 1.0), 'JobId: must not be empty'),
    (('x' * 65, 'a.ngc', 1.0), 'JobId: has 65 characters, at most 64'),
    (('a\nb', 'a.ngc', 1.0), 'JobId: contains the non-printable character U+000A'),
    (('a\x00b', 'a.ngc', 1.0), 'U+0000'),
    ((' lead', 'a.ngc', 1.0), 'JobId: starts or ends with white space'),
    (('j', 'a.ngc', math.nan), 'LoadKg: expected a finite load in kg, got nan'),
    (('j', 'a.ngc', math.inf), 'LoadKg: expected a finite load in kg, got inf'),
    (('j', 'a.ngc', -1.0), 'LoadKg: a load cannot be negative: -1 kg'),
    (('j', 'a.ngc', 1e9), 'LoadKg: 1e+09 kg is above the largest load accepted'),
    (('j', 'a.ngc', '12'), "LoadKg: expected a load in kg (a number), got text '12'"),
    ((7, 'a.ngc', 1.0), 'JobId: expected text, got number 7'),
    (('j', '', 1.0), 'Program: must not be empty'),
    (('j', 'a\x1b.ngc', 1.0), 'Program: contains the non-printable character U+001B'),
    (('j', 'a.ngc'), 'expected 3 arguments (JobId, Program, LoadKg), got 2'),
    (('j', 'a.ngc', 1.0, 'extra'), 'expected 3 arguments'),
]


def test_hostile_calls_are_refused_by_the_bridge_and_never_reach_the_service(
        served, program_root) -> None:
    service = FakeJobService(program_root)
    bridge = served(service)
    refused = bridge.refused_calls

    async def main() -> None:
        async with Client(bridge.endpoint) as client:
            for args, want in BAD_CALLS:
                accepted, message = await _call(client, 'Jobs/StartJob', *args)
                assert accepted is False
                assert want in message, (args, message)
                assert message.startswith('StartJob')
            accepted, message = await _call(client, 'Jobs/AbortJob', 'x' * 100)
            assert accepted is False and 'AbortJob JobId: has 100 characters' in message
            found, text, message = await _call(client, 'Results/GetResult', 5)
            assert (found, text) == (False, '') and 'expected text' in message
            assert service.calls == []
            assert bridge.refused_calls == refused + len(BAD_CALLS) + 2
            # values are the server's to write: a client's write is refused
            for path, value in (('Jobs/State', 'ended'), ('Results/LastJob/EnergyJ', 1.0)):
                with pytest.raises(ua.UaStatusCodeError):
                    await (await _child(client, path)).write_value(value)
            # and the server is still there and answers
            assert await _idle(client)

    run(main())


def test_the_service_refuses_a_program_outside_its_root_and_a_second_job(
        served, program_root) -> None:
    service = FakeJobService(program_root, samples=5)
    service.hold.clear()
    bridge = served(service)

    async def main() -> None:
        async with Client(bridge.endpoint) as client:
            for program in ('../outside.ngc', str(program_root.parent / 'outside.ngc'),
                            'missing.ngc'):
                accepted, message = await _call(client, 'Jobs/StartJob', 'j0', program, 1.0)
                assert accepted is False and 'program' in message, message
            assert (await _call(client, 'Jobs/StartJob', 'j1', 'a.ngc', 1.0))[0] is True
            assert await _until(lambda: _is(client, 'Jobs/State', 'running'))
            accepted, message = await _call(client, 'Jobs/StartJob', 'j2', 'b.ngc', 1.0)
            assert accepted is False
            assert message == ("job 'j1' is running; abort it or wait for its end before "
                               "starting 'j2'")
            accepted, message = await _call(client, 'Jobs/AbortJob', 'other')
            assert accepted is False and "'other' is not running" in message
            accepted, message = await _call(client, 'Jobs/AbortJob', 'j1')
            assert accepted is True, message
            assert await _until(lambda: _is(client, 'Results/LastJob/JobId', 'j1'))
            assert await _read(client, 'Results/LastJob/Status') == 'aborted'
            assert await _until(lambda: _is(client, 'Jobs/State', 'aborted'))

    run(main())


def test_a_client_that_disconnects_mid_job_does_not_stop_it(served, program_root) -> None:
    service = FakeJobService(program_root, samples=10)
    service.hold.clear()
    bridge = served(service)

    async def main() -> None:
        client = Client(bridge.endpoint)
        await client.connect()
        assert (await _call(client, 'Jobs/StartJob', 'kept', 'a.ngc', 3.0))[0] is True
        await client.disconnect()
        await asyncio.sleep(0.2)
        assert service.state() == 'running'
        service.hold.set()
        async with Client(bridge.endpoint) as other:
            assert await _until(lambda: _is(other, 'Results/LastJob/JobId', 'kept'))
            assert await _read(other, 'Results/LastJob/Status') == 'ended'
        assert service.result('kept')['samples'] == 10

    run(main())


def test_a_service_that_fails_or_hangs_is_an_answer_not_a_crash(served, program_root) -> None:
    service = FakeJobService(program_root)
    bridge = served(service)

    def broken(job_id: str, program: str, load_kg: float) -> tuple[bool, str]:
        raise RuntimeError('service exploded')

    def slow(job_id: str) -> tuple[bool, str]:
        time.sleep(3.0)
        return True, 'late'

    async def main() -> None:
        async with Client(bridge.endpoint) as client:
            service.start_job = broken     # type: ignore[method-assign]
            service.abort_job = slow       # type: ignore[method-assign]
            accepted, message = await _call(client, 'Jobs/StartJob', 'j', 'a.ngc', 1.0)
            assert accepted is False and 'the job service failed: service exploded' in message
            accepted, message = await _call(client, 'Jobs/AbortJob', 'j')
            assert accepted is False and 'did not answer within 1 s' in message
            assert await _idle(client)

    run(main())


@pytest.mark.parametrize('host', ['127.0.0.1', '127.1.2.3', '::1', 'localhost'])
def test_loopback_allows_anonymous(host: str) -> None:
    from feed_axis_energy.bridge import security_plan
    plan = security_plan(host, OpcUaSecurity())
    assert plan.loopback and plan.anonymous
    assert plan.policies == (ua.SecurityPolicyType.NoSecurity,)


@pytest.mark.parametrize('host', ['0.0.0.0', '192.168.1.20', '::', 'cnc-cell.local'])
def test_elsewhere_requires_certificates_and_users(host: str, tmp_path: Path) -> None:
    from feed_axis_energy.bridge import security_plan
    with pytest.raises(ConfigError, match='requires Basic256Sha256 with certificates and user '
                                          'names; missing: a server certificate, its private '
                                          'key, at least one user with a password'):
        security_plan(host, OpcUaSecurity())
    plan = security_plan(host, OpcUaSecurity(certificate=tmp_path / 'c.der',
                                             private_key=tmp_path / 'k.pem',
                                             users={'mes': 'secret'}))
    assert not plan.anonymous
    assert plan.policies == (ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,)
    assert plan.tokens == (ua.UserNameIdentityToken,)


async def _certificate(folder: Path, name: str, uri: str, use: Any) -> tuple[Path, Path]:
    key, cert = folder / f'{name}-key.pem', folder / f'{name}-cert.der'
    await setup_self_signed_certificate(key, cert, uri, 'localhost', [use],
                                        {'organizationName': 'feed_axis_energy tests'})
    return cert, key


def test_off_loopback_only_basic256sha256_with_a_user_gets_in(program_root, tmp_path) -> None:
    """Bound to all interfaces (not loopback): anonymous and plain connections are refused;
    a client with a generated certificate, SignAndEncrypt and a password gets in."""
    service = FakeJobService(program_root)

    async def main() -> None:
        server_cert, server_key = await _certificate(
            tmp_path, 'server', 'urn:feed-axis-energy:server', ExtendedKeyUsageOID.SERVER_AUTH)
        client_cert, client_key = await _certificate(
            tmp_path, 'client', 'urn:feed-axis-energy:test-client',
            ExtendedKeyUsageOID.CLIENT_AUTH)
        security = OpcUaSecurity(certificate=server_cert, private_key=server_key,
                                 users={'mes': 'correct horse'},
                                 trusted_clients=(client_cert,))
        port = opcua_port()
        bridge = OpcUaBridge(service, OpcUaSettings(host='0.0.0.0', port=port,
                                                    security=security))
        async with bridge:
            url = f'opc.tcp://127.0.0.1:{port}/feed_axis_energy/'
            plain = Client(url)
            with pytest.raises(Exception):
                await plain.connect()
            for password, ok in (('wrong', False), ('correct horse', True)):
                client = Client(url)
                client.application_uri = 'urn:feed-axis-energy:test-client'
                client.set_user('mes')
                client.set_password(password)
                await client.set_security(SecurityPolicyBasic256Sha256, str(client_cert),
                                          str(client_key), mode=ua.MessageSecurityMode
                                          .SignAndEncrypt)
                if not ok:
                    with pytest.raises(ua.UaStatusCodeError):
                        await client.connect()
                    continue
                async with client:
                    assert await _read(client, 'Jobs/State') == 'idle'
                    accepted, _ = await _call(client, 'Jobs/StartJob', 's', 'a.ngc', 1.0)
                    assert accepted is True
            endpoints = await Client(url).connect_and_get_server_endpoints()
            assert {e.SecurityMode for e in endpoints} == {ua.MessageSecurityMode
                                                           .SignAndEncrypt}
            tokens = {t.TokenType for e in endpoints for t in e.UserIdentityTokens}
            assert tokens == {ua.UserTokenType.UserName}

    run(main(), timeout=120)
    service.wait()


def test_an_untrusted_client_certificate_is_refused(program_root, tmp_path) -> None:
    service = FakeJobService(program_root)

    async def main() -> None:
        server_cert, server_key = await _certificate(
            tmp_path, 'server', 'urn:feed-axis-energy:server', ExtendedKeyUsageOID.SERVER_AUTH)
        trusted, _ = await _certificate(tmp_path, 'trusted', 'urn:t:trusted',
                                        ExtendedKeyUsageOID.CLIENT_AUTH)
        other_cert, other_key = await _certificate(tmp_path, 'other', 'urn:t:other',
                                                   ExtendedKeyUsageOID.CLIENT_AUTH)
        security = OpcUaSecurity(certificate=server_cert, private_key=server_key,
                                 users={'mes': 'pw'}, trusted_clients=(trusted,))
        bridge = OpcUaBridge(service, OpcUaSettings(port=opcua_port(), security=security))
        async with bridge:
            client = Client(bridge.endpoint)
            client.application_uri = 'urn:t:other'
            client.set_user('mes')
            client.set_password('pw')
            await client.set_security(SecurityPolicyBasic256Sha256, str(other_cert),
                                      str(other_key))
            with pytest.raises(ua.UaStatusCodeError):
                await client.connect()
            # the loopback's anonymous endpoint still works beside the secure one
            async with Client(bridge.endpoint) as anonymous:
                assert await _read(anonymous, 'Jobs/State') == 'idle'

    run(main(), timeout=120)


def test_a_flood_of_live_samples_is_dropped_and_counted_not_queued(served, program_root):
    """5000 samples while the server's loop is stalled (a service whose state() takes 0.2 s):
    the queue (64 events here) stays bounded, the excess is counted, and the job's end and
    result still show."""
    service = FakeJobService(program_root, samples=5000, period_s=0.0)
    state = service.state

    def slow_state() -> str:
        time.sleep(0.2)
        return state()

    bridge = served(service)
    dropped = bridge.dropped_events
    service.state = slow_state      # type: ignore[method-assign]

    async def main() -> None:
        async with Client(bridge.endpoint) as client:
            assert (await _call(client, 'Jobs/StartJob', 'flood', 'a.ngc', 0.0))[0] is True
            assert await _until(lambda: _is(client, 'Results/LastJob/JobId', 'flood'), 60)
            assert await _until(lambda: _is(client, 'Jobs/State', 'ended'))
            assert await _read(client, 'Results/LastJob/EnergyJ') == \
                service.result('flood')['energy_j']

    run(main(), timeout=120)
    print(f'dropped {bridge.dropped_events - dropped} of 5000 samples')
    assert bridge.dropped_events > dropped


@pytest.mark.parametrize('key,value', [('port', 0), ('port', 70000), ('port', True),
                                       ('queue_size', 0), ('poll_s', math.nan),
                                       ('max_load_kg', -1.0), ('call_timeout_s', 'x')])
def test_bad_settings_are_config_errors(key: str, value: Any) -> None:
    with pytest.raises(ConfigError, match=f'<opcua>: {key}: expected'):
        OpcUaSettings(**{key: value})
