"""The OPC UA server of the machine cell, on top of a :class:`~.service.JobService`.

The address space is built in one place (:meth:`OpcUaBridge.start`) under
``Objects/FeedAxisEnergy`` in namespace :data:`NAMESPACE_URI`; :data:`BROWSE_PATHS` lists the
names a client can rely on (docs/cell.md, tested as a contract)::

    FeedAxisEnergy/
      Jobs/      StartJob(JobId, Program, LoadKg) -> (Accepted, Message)
                 AbortJob(JobId) -> (Accepted, Message)
                 State, JobId, ActiveLine, Progress [%]
      Results/   GetResult(JobId) -> (Found, Result, Message)    Result: the result as JSON
                 LastJob/ JobId, Status, EnergyJ [J], DurationS [s], PeakPowerW [W]
      Energy/    Total/ and one folder per axis, each with the OPC 34100 names (predicted):
                 AcActivePowerTotal [W], AcActiveEnergyTotalImport [Wh],
                 AcActiveEnergyTotalExport [Wh]

Every number carries an ``EngineeringUnits`` property (UNECE code, :data:`UNITS`); live values
carry the sample's wall-clock time as source timestamp. Method calls are checked here
(:mod:`.requests`) before the service sees them, run in a worker thread with a time limit,
and never raise: a refused or failed call answers ``Accepted = false`` and the reason.
"""
from __future__ import annotations

import asyncio
from dataclasses import dataclass, field
import datetime
import json
import logging
import math
import threading
from typing import Any, Callable, Mapping, Sequence

from asyncua import Node, Server, ua

from ..errors import ConfigError, describe, FeedAxisError, RequestError
from .logbound import BoundedLog
from .requests import check_job_id, check_load_kg, check_program, MAX_LOAD_KG
from .security import OpcUaSecurity, PasswordUsers, security_plan
from .service import (AxisPower, FINAL_STATES, JobService, LiveSample, result_summary,
                      ServiceEvent, StateChange)

__all__ = ['BROWSE_PATHS', 'J_PER_WH', 'NAMESPACE_URI', 'OpcUaBridge', 'OpcUaSettings',
           'OpcUaThread',
           'ENERGY_NAMES', 'unece_unit_id', 'UNECE_NAMESPACE', 'UNITS']

_log = logging.getLogger(__name__)

NAMESPACE_URI = 'urn:feed-axis-energy:cell'
"""Namespace of every node the bridge adds."""

UNECE_NAMESPACE = 'http://www.opcfoundation.org/UA/units/un/cefact'
"""``EUInformation.NamespaceUri`` of UNECE Recommendation 20 units (OPC 10000-8)."""

UNITS: Mapping[str, tuple[str, str]] = {
    'W': ('WTT', 'watt'), 'Wh': ('WHR', 'watt hour'), 'J': ('JOU', 'joule'),
    's': ('SEC', 'second'), 'kg': ('KGM', 'kilogram'), '%': ('P1', 'percent'),
}
"""Unit symbol -> (UNECE common code, name)."""

J_PER_WH = 3600.0
"""Joules in one watt hour."""

ENERGY_NAMES = ('AcActivePowerTotal', 'AcActiveEnergyTotalImport', 'AcActiveEnergyTotalExport')
"""The OPC 34100 names under ``Energy/Total`` and ``Energy/<axis>`` (W, Wh, Wh)."""

BROWSE_PATHS = (
    'Jobs/StartJob', 'Jobs/AbortJob', 'Jobs/State', 'Jobs/JobId', 'Jobs/ActiveLine',
    'Jobs/Progress', 'Results/GetResult', 'Results/LastJob/JobId', 'Results/LastJob/Status',
    'Results/LastJob/EnergyJ', 'Results/LastJob/DurationS', 'Results/LastJob/PeakPowerW',
    *(f'Energy/Total/{name}' for name in ENERGY_NAMES),
)
"""Browse names under ``Objects/FeedAxisEnergy`` a client can rely on (plus, per axis,
``Energy/<axis>/<name>`` for each of :data:`ENERGY_NAMES`)."""

_PREDICTED = ('Predicted by the feed-axis energy model from the NC program (mechanical power '
              'at the screw and motor shaft), not measured at the supply')


def unece_unit_id(code: str) -> int:
    """``EUInformation.UnitId`` of a UNECE common code (OPC 10000-8: the code's bytes)."""
    value = 0
    for char in code:
        value = (value << 8) | ord(char)
    return value


def _eu(symbol: str) -> ua.EUInformation:
    code, name = UNITS[symbol]
    return ua.EUInformation(NamespaceUri=UNECE_NAMESPACE, UnitId=unece_unit_id(code),
                            DisplayName=ua.LocalizedText(symbol),
                            Description=ua.LocalizedText(name))


def _check_port(port: object, file: str) -> None:
    if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
        raise ConfigError(f'expected a TCP port 1...65535, got {describe(port)}', file=file,
                          key='port')


def _stamp(stamp_ns: int | None = None) -> ua.DateTime:
    if stamp_ns is None:
        return ua.DateTime.now(datetime.timezone.utc)
    return ua.DateTime.fromtimestamp(stamp_ns / 1e9, datetime.timezone.utc)


@dataclass(frozen=True)
class OpcUaSettings:
    """Where and how the OPC UA server listens.

    Attributes
    ----------
    host, port
        Address bound; loopback allows anonymous clients (:mod:`.security`).
    security
        Certificates and users (required off loopback).
    max_load_kg
        Largest ``LoadKg`` accepted [kg].
    poll_s
        Period of reading the service's state, line, progress and last result [s].
    call_timeout_s
        Longest wait for the service to answer a method call [s].
    queue_size
        Service events held for the server's loop; beyond, new ones are dropped and counted.
    """

    host: str = '127.0.0.1'
    port: int = 4840
    security: OpcUaSecurity = field(default_factory=OpcUaSecurity)
    max_load_kg: float = MAX_LOAD_KG
    poll_s: float = 0.1
    call_timeout_s: float = 10.0
    queue_size: int = 4096

    def __post_init__(self) -> None:
        _check_port(self.port, '<opcua>')
        for key in ('max_load_kg', 'poll_s', 'call_timeout_s'):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value <= 0:
                raise ConfigError(f'expected a positive finite number, got {describe(value)}',
                                  file='<opcua>', key=key)
        if isinstance(self.queue_size, bool) or not isinstance(self.queue_size, int) \
                or self.queue_size < 1:
            raise ConfigError(f'expected a positive integer, got {describe(self.queue_size)}',
                              file='<opcua>', key='queue_size')

    @property
    def endpoint(self) -> str:
        """The server's endpoint URL."""
        host = f'[{self.host}]' if ':' in self.host else self.host
        return f'opc.tcp://{host}:{self.port}/feed_axis_energy/'


def _variant(value: Any, vtype: ua.VariantType) -> ua.Variant:
    return ua.Variant(value, vtype)


def _argument(name: str, datatype: int, text: str) -> ua.Argument:
    return ua.Argument(Name=name, DataType=ua.NodeId(ua.Int32(datatype)), ValueRank=-1,
                       ArrayDimensions=[], Description=ua.LocalizedText(text))


class OpcUaBridge:
    """An OPC UA server showing a job service: start it, let it run, stop it.

    Parameters
    ----------
    service
        The job machinery (:class:`~.service.JobService`).
    settings
        Address, security, limits.

    Use as ``async with OpcUaBridge(service, settings) as bridge: ...`` or call
    :meth:`start` and :meth:`stop` in the same event loop.
    """

    def __init__(self, service: JobService, settings: OpcUaSettings | None = None):
        self.service = service
        self.settings = settings or OpcUaSettings()
        self.plan = security_plan(self.settings.host, self.settings.security)
        self.dropped_events = 0
        """Service events dropped because the queue was full (the server fell behind)."""
        self.refused_calls = 0
        """Method calls answered ``Accepted = false`` or ``Found = false``."""
        self._server: Server | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._queue: asyncio.Queue[ServiceEvent] | None = None
        self._tasks: list[asyncio.Task[None]] = []
        self._unsubscribe: Callable[[], None] | None = None
        self._nodes: dict[str, ua.NodeId] = {}
        self._shown: dict[str, Any] = {}
        self._axes: tuple[str, ...] = ()
        self.idx = 0
        self._log = BoundedLog(_log)

    @property
    def endpoint(self) -> str:
        """The endpoint URL clients connect to."""
        return self.settings.endpoint

    async def __aenter__(self) -> OpcUaBridge:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    # -- start and stop -------------------------------------------------------------------

    async def start(self) -> None:
        """Build the address space, listen, and follow the service's events."""
        settings = self.settings
        sec = settings.security
        server = Server(user_manager=PasswordUsers(sec.users, anonymous=self.plan.anonymous))
        await server.init()
        server.set_endpoint(settings.endpoint)
        server.set_server_name('feed_axis_energy cell bridge')
        await server.set_application_uri('urn:feed-axis-energy:server')
        server.set_security_policy(list(self.plan.policies))
        server.set_identity_tokens(list(self.plan.tokens))
        if sec.certificate is not None and sec.private_key is not None:
            await server.load_certificate(str(sec.certificate))
            await server.load_private_key(str(sec.private_key))
        if sec.trusted_clients:
            server.set_certificate_validator(await _trust_list(sec.trusted_clients))
        self.idx = await server.register_namespace(NAMESPACE_URI)
        self._server = server
        self._axes = tuple(str(a) for a in self.service.axes())
        await self._build(server)
        self._loop = asyncio.get_running_loop()
        self._queue = asyncio.Queue(maxsize=settings.queue_size)
        try:
            await server.start()
        except OSError as exc:
            self._server = None
            msg = f'cannot listen on {settings.endpoint}: {exc.strerror or exc}'
            raise FeedAxisError(msg) from exc
        await self._refresh()
        self._tasks = [asyncio.create_task(self._pump(), name='opcua-pump'),
                       asyncio.create_task(self._poll(), name='opcua-poll')]
        self._unsubscribe = self.service.subscribe(self._on_event)

    async def stop(self) -> None:
        """Stop following the service and close every session; the service keeps running."""
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            try:
                await task
            except asyncio.CancelledError:
                pass
        self._tasks = []
        self._loop = None
        self._queue = None
        if self._server is not None:
            server, self._server = self._server, None
            await server.stop()

    # -- the address space ----------------------------------------------------------------

    def _nid(self, path: str) -> ua.NodeId:
        text = f'FeedAxisEnergy/{path}' if path else 'FeedAxisEnergy'
        return ua.NodeId(ua.String(text), ua.Int16(self.idx))

    def _qname(self, name: str) -> ua.QualifiedName:
        return ua.QualifiedName(name, self.idx)

    async def _object(self, parent: Node, path: str, text: str) -> Node:
        name = path.rsplit('/', 1)[-1] if path else 'FeedAxisEnergy'
        node = await parent.add_object(self._nid(path), self._qname(name))
        await node.write_attribute(ua.AttributeIds.Description,
                                   ua.DataValue(ua.Variant(ua.LocalizedText(text))))
        return node

    async def _variable(self, parent: Node, path: str, value: Any, vtype: ua.VariantType,
                        text: str, unit: str | None = None) -> None:
        node = await parent.add_variable(self._nid(path), self._qname(path.rsplit('/', 1)[-1]),
                                         _variant(value, vtype))
        await node.write_attribute(ua.AttributeIds.Description,
                                   ua.DataValue(ua.Variant(ua.LocalizedText(text))))
        if unit is not None:
            await node.add_property(self._nid(f'{path}/EngineeringUnits'),
                                    ua.QualifiedName('EngineeringUnits', 0),
                                    ua.Variant(_eu(unit), ua.VariantType.ExtensionObject))
        self._nodes[path] = node.nodeid
        self._shown[path] = value

    async def _build(self, server: Server) -> None:
        root_node = await self._object(server.nodes.objects, '', 'Feed-axis energy prediction '
                                       'of a machine tool (feed_axis_energy)')
        jobs = await self._object(root_node, 'Jobs', 'Job order control (in the spirit of '
                                  'OPC 40001-3): start, abort, state')
        results = await self._object(root_node, 'Results', 'Results of finished jobs')
        last = await self._object(results, 'Results/LastJob', 'The last job that ended')
        energy = await self._object(root_node, 'Energy', 'Predicted power and energy '
                                    '(OPC 34100 names). ' + _PREDICTED + '.')
        S, D, U = ua.VariantType.String, ua.VariantType.Double, ua.VariantType.UInt32
        await self._variable(jobs, 'Jobs/State', 'idle', S,
                             'idle, planning, running, ended, aborted or failed')
        await self._variable(jobs, 'Jobs/JobId', '', S, 'The job planning or running, or the '
                             'last job')
        await self._variable(jobs, 'Jobs/ActiveLine', 0, U, 'Program line being executed '
                             '(1-based; 0: none)')
        await self._variable(jobs, 'Jobs/Progress', 0.0, D, 'Share of the running job done',
                             '%')
        await self._variable(last, 'Results/LastJob/JobId', '', S, 'Job id')
        await self._variable(last, 'Results/LastJob/Status', '', S, 'ended, aborted or failed')
        await self._variable(last, 'Results/LastJob/EnergyJ', 0.0, D, 'Total mechanical '
                             'energy of the job (simulate: energy_j.total)', 'J')
        await self._variable(last, 'Results/LastJob/DurationS', 0.0, D, 'Duration', 's')
        await self._variable(last, 'Results/LastJob/PeakPowerW', 0.0, D,
                             'Peak total mechanical power', 'W')
        for name in ('Total', *self._axes):
            what = 'all feed axes' if name == 'Total' else f'axis {name}'
            folder = await self._object(energy, f'Energy/{name}', f'Predicted, {what}')
            await self._variable(folder, f'Energy/{name}/AcActivePowerTotal', 0.0, D,
                                 f'Predicted mechanical power of {what}. {_PREDICTED}', 'W')
            await self._variable(folder, f'Energy/{name}/AcActiveEnergyTotalImport', 0.0, D,
                                 f'Predicted energy drawn by {what} during the job. '
                                 f'{_PREDICTED}', 'Wh')
            await self._variable(folder, f'Energy/{name}/AcActiveEnergyTotalExport', 0.0, D,
                                 f'Predicted energy returned while braking by {what} during '
                                 f'the job. {_PREDICTED}', 'Wh')
        String, Double, Boolean = ua.ObjectIds.String, ua.ObjectIds.Double, ua.ObjectIds.Boolean
        await jobs.add_method(
            self._nid('Jobs/StartJob'), self._qname('StartJob'), self._start_job,
            [_argument('JobId', String, 'Job id: 1 to 64 printable characters'),
             _argument('Program', String, 'NC program: a path, absolute or relative to the '
                       'program root, that must resolve inside it'),
             _argument('LoadKg', Double, 'Mass of workpiece and fixture on the table [kg]')],
            [_argument('Accepted', Boolean, 'Whether the job was started'),
             _argument('Message', String, 'Why not, or what happens')])
        await jobs.add_method(
            self._nid('Jobs/AbortJob'), self._qname('AbortJob'), self._abort_job,
            [_argument('JobId', String, 'The running job')],
            [_argument('Accepted', Boolean, 'Whether the abort was accepted'),
             _argument('Message', String, 'Why not, or what happens')])
        await results.add_method(
            self._nid('Results/GetResult'), self._qname('GetResult'), self._get_result,
            [_argument('JobId', String, 'A job among the last ones the service keeps')],
            [_argument('Found', Boolean, 'Whether the result is known'),
             _argument('Result', String, 'The result as JSON (docs/cell.md); empty if not '
                       'found'),
             _argument('Message', String, 'Why not found')])

    # -- method calls ---------------------------------------------------------------------

    async def _service_call(self, request: str, call: Callable[[], Any]) -> Any:
        return await asyncio.wait_for(asyncio.to_thread(call),
                                      timeout=self.settings.call_timeout_s)

    def _refuse(self, message: str) -> list[ua.Variant]:
        self.refused_calls += 1
        return [_variant(False, ua.VariantType.Boolean), _variant(message, ua.VariantType.String)]

    async def _answer(self, request: str, call: Callable[[], Any]) -> list[ua.Variant]:
        try:
            accepted, message = await self._service_call(request, call)
        except asyncio.TimeoutError:
            return self._refuse(f'{request}: the job service did not answer within '
                                f'{self.settings.call_timeout_s:g} s')
        except Exception as exc:   # the service's failure must not end the server
            self._log.log(logging.ERROR, request, f'{request} failed in the job service',
                          exc_info=True)
            return self._refuse(f'{request}: the job service failed: {exc}')
        if not accepted:
            self.refused_calls += 1
        await self._refresh()
        return [_variant(bool(accepted), ua.VariantType.Boolean),
                _variant(str(message), ua.VariantType.String)]

    @staticmethod
    def _values(request: str, args: Sequence[Any], names: Sequence[str]) -> list[Any]:
        if len(args) != len(names):
            msg = f'expected {len(names)} arguments ({", ".join(names)}), got {len(args)}'
            raise RequestError(msg, request=request)
        return [a.Value if isinstance(a, ua.Variant) else a for a in args]

    async def _start_job(self, parent: ua.NodeId, *args: Any) -> list[ua.Variant]:
        request = 'StartJob'
        try:
            job, program, load = self._values(request, args, ('JobId', 'Program', 'LoadKg'))
            job_id = check_job_id(job, request=request)
            program = check_program(program, request=request)
            load_kg = check_load_kg(load, request=request, max_kg=self.settings.max_load_kg)
        except RequestError as exc:
            return self._refuse(str(exc))
        return await self._answer(request, lambda: self.service.start_job(job_id, program,
                                                                          load_kg))

    async def _abort_job(self, parent: ua.NodeId, *args: Any) -> list[ua.Variant]:
        request = 'AbortJob'
        try:
            (job,) = self._values(request, args, ('JobId',))
            job_id = check_job_id(job, request=request)
        except RequestError as exc:
            return self._refuse(str(exc))
        return await self._answer(request, lambda: self.service.abort_job(job_id))

    async def _get_result(self, parent: ua.NodeId, *args: Any) -> list[ua.Variant]:
        request = 'GetResult'
        S = ua.VariantType.String

        def not_found(message: str) -> list[ua.Variant]:
            self.refused_calls += 1
            return [_variant(False, ua.VariantType.Boolean), _variant('', S),
                    _variant(message, S)]

        try:
            (job,) = self._values(request, args, ('JobId',))
            job_id = check_job_id(job, request=request)
        except RequestError as exc:
            return not_found(str(exc))
        try:
            result = await self._service_call(request, lambda: self.service.result(job_id))
            if result is None:
                return not_found(f'{request}: no result of job {job_id!r} is kept (unknown, '
                                 f'still running, or older than the jobs kept)')
            text = json.dumps(dict(result), allow_nan=False, sort_keys=True)
        except asyncio.TimeoutError:
            return not_found(f'{request}: the job service did not answer within '
                             f'{self.settings.call_timeout_s:g} s')
        except (TypeError, ValueError) as exc:
            return not_found(f'{request}: the result of job {job_id!r} cannot be shown as '
                             f'JSON: {exc}')
        except Exception as exc:   # the service's failure must not end the server
            self._log.log(logging.ERROR, request, f'{request} failed in the job service',
                          exc_info=True)
            return not_found(f'{request}: the job service failed: {exc}')
        return [_variant(True, ua.VariantType.Boolean), _variant(text, S), _variant('', S)]

    # -- live values ----------------------------------------------------------------------

    def _on_event(self, event: ServiceEvent) -> None:
        """The service's listener: hands the event to the server's loop (any thread)."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return
        try:
            loop.call_soon_threadsafe(self._put, event)
        except RuntimeError:   # the loop closed between the check and the call
            pass

    def _put(self, event: ServiceEvent) -> None:
        if self._queue is None:
            return
        try:
            self._queue.put_nowait(event)
        except asyncio.QueueFull:
            self.dropped_events += 1

    async def _pump(self) -> None:
        assert self._queue is not None
        while True:
            event = await self._queue.get()
            try:
                if isinstance(event, LiveSample):
                    await self._show_sample(event)
                elif isinstance(event, StateChange):
                    await self._refresh(event.stamp_ns)
            except Exception:   # one bad event must not stop the live values
                self._log.log(logging.ERROR, 'event', 'cannot show a job service event on '
                              'OPC UA', exc_info=True)

    async def _poll(self) -> None:
        while True:
            await asyncio.sleep(self.settings.poll_s)
            try:
                await self._refresh()
            except Exception:   # a service that fails on every poll must not flood the log
                self._log.log(logging.ERROR, 'poll', 'cannot read the job service state',
                              exc_info=True)

    async def _write(self, path: str, value: Any, vtype: ua.VariantType,
                     stamp: ua.DateTime, *, always: bool = False) -> None:
        if not always and self._shown.get(path) == value:
            return
        server = self._server
        if server is None:
            return
        self._shown[path] = value
        now = _stamp()
        await server.write_attribute_value(
            self._nodes[path], ua.DataValue(Value=_variant(value, vtype), SourceTimestamp=stamp,
                                            ServerTimestamp=now))

    async def _show_power(self, name: str, power: AxisPower, stamp: ua.DateTime) -> None:
        D = ua.VariantType.Double
        values = (power.power_w, power.energy_import_j / J_PER_WH,
                  power.energy_export_j / J_PER_WH)
        for short, value in zip(ENERGY_NAMES, values):
            if math.isfinite(value):    # never NaN on the server; a gap keeps the last value
                await self._write(f'Energy/{name}/{short}', float(value), D, stamp,
                                  always=(short == 'AcActivePowerTotal'))

    async def _show_sample(self, sample: LiveSample) -> None:
        stamp = _stamp(sample.stamp_ns)
        await self._show_power('Total', sample.total, stamp)
        for axis, power in sample.axes.items():
            if axis in self._axes:
                await self._show_power(axis, power, stamp)

    async def _refresh(self, stamp_ns: int | None = None) -> None:
        """Read the service's state, job, line, progress and last result; show what changed."""
        service = self.service
        stamp = _stamp(stamp_ns)
        S, D = ua.VariantType.String, ua.VariantType.Double
        state = str(service.state())
        await self._write('Jobs/State', state, S, stamp)
        await self._write('Jobs/JobId', str(service.active_job()), S, stamp)
        line = service.active_line()
        await self._write('Jobs/ActiveLine', max(0, min(int(line), 2**32 - 1)),
                          ua.VariantType.UInt32, stamp)
        progress = float(service.progress())
        if math.isfinite(progress):
            await self._write('Jobs/Progress', 100.0 * min(max(progress, 0.0), 1.0), D, stamp)
        last = service.last_result()
        if last is None:
            return
        try:
            summary = result_summary(last)
        except RequestError as exc:
            self._log.log(logging.ERROR, 'result', f'the last result is not shown: {exc} '
                          f'({describe(last)})')
            return
        if summary.status not in FINAL_STATES:
            return
        for path, value, vtype in (('Results/LastJob/EnergyJ', summary.energy_j, D),
                                   ('Results/LastJob/DurationS', summary.duration_s, D),
                                   ('Results/LastJob/PeakPowerW', summary.peak_power_w, D),
                                   ('Results/LastJob/Status', summary.status, S),
                                   # written last: a client that sees the id sees its numbers
                                   ('Results/LastJob/JobId', summary.job_id, S)):
            await self._write(path, value, vtype, stamp)


async def _trust_list(paths: Sequence[Any]) -> Callable[..., Any]:
    from asyncua.crypto import uacrypto
    from asyncua.common.utils import ServiceError

    allowed = set()
    for path in paths:
        cert = await uacrypto.load_certificate(str(path))
        allowed.add(uacrypto.der_from_x509(cert))

    async def validate(cert: Any, app_description: Any) -> None:
        if uacrypto.der_from_x509(cert) not in allowed:
            raise ServiceError(ua.StatusCodes.BadCertificateUntrusted)

    return validate


class OpcUaThread:
    """An :class:`OpcUaBridge` in a thread of its own with its own event loop.

    For a caller without asyncio (an rclpy node, a test): :meth:`start` returns when the
    server listens, :meth:`stop` when it has closed every session and the thread has ended.

    Parameters
    ----------
    service, settings
        As for :class:`OpcUaBridge`.
    start_timeout_s
        Longest wait for the server to build its address space and listen [s].
    """

    def __init__(self, service: JobService, settings: OpcUaSettings | None = None, *,
                 start_timeout_s: float = 120.0):
        self.bridge = OpcUaBridge(service, settings)
        self._timeout = start_timeout_s
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None

    def __enter__(self) -> OpcUaThread:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def endpoint(self) -> str:
        """The endpoint URL clients connect to."""
        return self.bridge.endpoint

    def start(self) -> None:
        """Start the thread and the server in it; raises what :meth:`OpcUaBridge.start` does."""
        loop = asyncio.new_event_loop()
        thread = threading.Thread(target=loop.run_forever, name='opcua-bridge', daemon=True)
        thread.start()
        self._loop, self._thread = loop, thread
        future = asyncio.run_coroutine_threadsafe(self.bridge.start(), loop)
        try:
            future.result(self._timeout)
        except BaseException:
            self._end_loop()
            raise

    def stop(self) -> None:
        """Stop the server, then the loop and its thread (the service keeps running)."""
        if self._loop is None:
            return
        try:
            asyncio.run_coroutine_threadsafe(self.bridge.stop(), self._loop).result(60)
        finally:
            self._end_loop()

    def _end_loop(self) -> None:
        loop, thread = self._loop, self._thread
        self._loop = self._thread = None
        if loop is None or thread is None:
            return
        loop.call_soon_threadsafe(loop.stop)
        thread.join(30)
        if not thread.is_alive():
            loop.close()
