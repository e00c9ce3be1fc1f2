"""The job request: what a cell controller may ask for, checked before anything runs.

A request is a plain mapping (the JSON of ``job/command``, an OPC UA method's arguments, an
MQTT payload): :func:`parse_job_request` turns it into a frozen :class:`JobSpec` or raises
:class:`~feed_axis_energy.errors.JobError` naming the field and the reason. Nothing of the
request reaches the planner unchecked:

* ``job_id``: 1 to :data:`MAX_JOB_ID_CHARS` characters of ``A-Z a-z 0-9 . _ -``, starting
  with a letter or digit (it names files and topics' frames, so no path separators, no
  spaces, no control characters).
* ``program``: a path, absolute or relative to the configured program root, that resolves
  inside the root: no ``..`` component, no symbolic link that leads out, a regular file
  (not a directory, device or FIFO) of at most ``max_program_bytes``; its SHA-256 is
  taken from the file opened without following a final link.
* ``load_kg``: a finite number, ``0 <= load_kg <= max_load_kg``.
* ``machine`` (optional): a machine YAML, absolute or relative to the machine root, under
  the same rules as the program; ``overrides`` (optional): at most :data:`MAX_OVERRIDES`
  dotted machine-config keys with finite numbers (``sweep``'s ``--vary`` keys), applied to
  that machine and validated with it when the job starts (:func:`job_machine`).
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
import hashlib
import math
import os
from pathlib import Path
import re
import stat
from typing import Any, Mapping

from ..errors import describe, FeedAxisError, JobError, shorten_path

__all__ = ['JobLimits', 'JobSpec', 'MAX_JOB_ID_CHARS', 'MAX_OVERRIDES', 'check_job_id',
           'check_load', 'file_sha256', 'job_machine', 'parse_job_request', 'resolve_inside']

MAX_JOB_ID_CHARS = 64
MAX_OVERRIDES = 32
MAX_PATH_CHARS = 4096
_JOB_ID = re.compile(r'[A-Za-z0-9][A-Za-z0-9._-]*')
_KEY = re.compile(r'[A-Za-z0-9_*]+(\.[A-Za-z0-9_*]+)*')
_REQUEST_KEYS = frozenset(('job_id', 'program', 'load_kg', 'machine', 'overrides'))


@dataclass(frozen=True)
class JobLimits:
    """Where jobs may read from and how large a request may be.

    Attributes
    ----------
    program_root
        Directory every job's program must lie in.
    default_machine
        Machine YAML of a job that names none.
    machine_root
        Directory a job's ``machine`` must lie in (``None``: a job may not name a machine).
    max_load_kg
        Largest workpiece mass accepted [kg].
    max_program_bytes
        Largest program file accepted [bytes].
    record_root
        Directory the recorder writes one recording per job into (``<root>/<job_id>/``):
        a job id whose recording exists there is refused (``None``: nothing is recorded).
    """

    program_root: Path
    default_machine: Path
    machine_root: Path | None = None
    max_load_kg: float = 10_000.0
    max_program_bytes: int = 256 * 1024 * 1024
    record_root: Path | None = None

    def __post_init__(self) -> None:
        for name in ('program_root', 'machine_root'):
            root = getattr(self, name)
            if root is None:
                continue
            if not Path(root).is_dir():
                msg = f'{name} {shorten_path(str(root))} is not a directory'
                raise JobError(msg, field='request')
            object.__setattr__(self, name, Path(os.path.realpath(root)))
        if not (math.isfinite(self.max_load_kg) and self.max_load_kg >= 0):
            msg = f'max_load_kg must be a finite mass >= 0 kg, got {self.max_load_kg}'
            raise JobError(msg, field='request')


@dataclass(frozen=True)
class JobSpec:
    """A checked job request.

    Attributes
    ----------
    job_id
        The job's identifier (see the module docstring for its alphabet).
    program
        The program file, resolved inside the program root (no link left in the path).
    program_sha256
        SHA-256 of the program file as checked, hex.
    load_kg
        Workpiece mass [kg].
    machine
        Machine YAML, resolved (the default machine when the request named none).
    overrides
        ``(dotted key, value)`` pairs applied to ``machine``, in request order.
    """

    job_id: str
    program: Path
    program_sha256: str
    load_kg: float
    machine: Path
    overrides: tuple[tuple[str, float], ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (the ``spec`` of ``job/state``; docs/nodes.md)."""
        return {'job_id': self.job_id, 'program': str(self.program),
                'program_sha256': self.program_sha256, 'load_kg': self.load_kg,
                'machine': str(self.machine),
                'overrides': {k: v for k, v in self.overrides}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> 'JobSpec':
        """Inverse of :meth:`to_dict`, for the graph's own messages (no path check: the
        sender checked them); ``JobError`` on a missing or mistyped key."""
        try:
            overrides = d.get('overrides') or {}
            return cls(job_id=check_job_id(d['job_id']), program=Path(str(d['program'])),
                       program_sha256=str(d['program_sha256']),
                       load_kg=float(d['load_kg']), machine=Path(str(d['machine'])),
                       overrides=tuple((str(k), float(v)) for k, v in overrides.items()))
        except (KeyError, TypeError, ValueError, AttributeError) as err:
            if isinstance(err, JobError):
                raise
            msg = f'not a job spec: {type(err).__name__} {shorten_path(str(err))}'
            raise JobError(msg, field='request') from None


def check_job_id(value: Any) -> str:
    """``value`` if it is a valid job id, else ``JobError`` saying why."""
    if not isinstance(value, str):
        msg = f'must be text, got {describe(value)}'
        raise JobError(msg, field='job_id')
    if not value:
        raise JobError('must not be empty', field='job_id')
    if len(value) > MAX_JOB_ID_CHARS:
        msg = f'at most {MAX_JOB_ID_CHARS} characters, got {len(value)}'
        raise JobError(msg, field='job_id')
    if not _JOB_ID.fullmatch(value):
        msg = (f'{shorten_path(value)!r} holds characters other than A-Z a-z 0-9 . _ - '
               '(or does not start with a letter or digit)')
        raise JobError(msg, field='job_id')
    return value


def check_load(value: Any, *, max_load_kg: float, job_id: str = '') -> float:
    """``value`` as a mass [kg] if finite, ``>= 0`` and at most ``max_load_kg``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        msg = f'must be a number [kg], got {describe(value)}'
        raise JobError(msg, field='load_kg', job_id=job_id)
    load = float(value)
    if not math.isfinite(load):
        msg = f'must be finite, got {load}'
        raise JobError(msg, field='load_kg', job_id=job_id)
    if load < 0.0:
        msg = f'must be >= 0 kg, got {load:g} kg'
        raise JobError(msg, field='load_kg', job_id=job_id)
    if load > max_load_kg:
        msg = f'{load:g} kg is above the limit of {max_load_kg:g} kg'
        raise JobError(msg, field='load_kg', job_id=job_id)
    return load


def resolve_inside(root: Path, name: Any, *, what: str, job_id: str = '') -> Path:
    """The path ``name`` (absolute, or relative to ``root``) resolved, if it stays inside
    ``root`` and is a regular file.

    Raises
    ------
    JobError
        (``field`` = ``what``) not text, empty or too long, a NUL, a ``..`` component, a path
        that resolves outside ``root`` (through a symbolic link too), a missing file, or
        something other than a regular file.
    """
    if not isinstance(name, str):
        msg = f'must be a path (text), got {describe(name)}'
        raise JobError(msg, field=what, job_id=job_id)
    if not name or len(name) > MAX_PATH_CHARS or '\x00' in name:
        msg = (f'must be a path of 1 to {MAX_PATH_CHARS} characters without NUL, got '
               f'{len(name)} characters')
        raise JobError(msg, field=what, job_id=job_id)
    shown = shorten_path(name)
    if '..' in Path(name).parts:
        msg = f'{shown}: ".." is not allowed in a path'
        raise JobError(msg, field=what, job_id=job_id)
    real_root = os.path.realpath(root)
    path = Path(name) if os.path.isabs(name) else Path(real_root) / name
    real = os.path.realpath(path)
    if os.path.commonpath([real_root, real]) != real_root:
        msg = f'{shown} is outside the {what} root {shorten_path(real_root)}'
        if os.path.islink(path) or real != os.path.abspath(path):
            msg += ' (through a symbolic link)'
        raise JobError(msg, field=what, job_id=job_id)
    try:
        mode = os.stat(real).st_mode
    except OSError as err:
        msg = f'{shown}: {err.strerror or "cannot be read"}'
        raise JobError(msg, field=what, job_id=job_id) from None
    if not stat.S_ISREG(mode):
        kind = ('a directory' if stat.S_ISDIR(mode) else 'a device' if stat.S_ISCHR(mode)
                or stat.S_ISBLK(mode) else 'a FIFO' if stat.S_ISFIFO(mode) else
                'a socket' if stat.S_ISSOCK(mode) else 'not a regular file')
        msg = f'{shown} is {kind}, not a regular file'
        raise JobError(msg, field=what, job_id=job_id)
    return Path(real)


def file_sha256(path: Path, *, max_bytes: int, what: str = 'program',
                job_id: str = '') -> str:
    """SHA-256 (hex) of a regular file, read in blocks, refused above ``max_bytes``.

    The file is opened without following a final symbolic link and without blocking (a FIFO
    put in its place after the check is refused, not waited on), and checked again on the
    open descriptor.
    """
    flags = os.O_RDONLY | getattr(os, 'O_NOFOLLOW', 0) | getattr(os, 'O_NONBLOCK', 0)
    shown = shorten_path(str(path))
    try:
        fd = os.open(path, flags)
    except OSError as err:
        msg = f'{shown}: {err.strerror or "cannot be opened"}'
        raise JobError(msg, field=what, job_id=job_id) from None
    digest = hashlib.sha256()
    with os.fdopen(fd, 'rb') as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            msg = f'{shown} is not a regular file'
            raise JobError(msg, field=what, job_id=job_id)
        if st.st_size > max_bytes:
            msg = f'{shown} has {st.st_size} bytes, above the limit of {max_bytes}'
            raise JobError(msg, field=what, job_id=job_id)
        total = 0
        while block := f.read(1 << 20):
            total += len(block)
            if total > max_bytes:       # the file grew after the check
                msg = f'{shown} grew above the limit of {max_bytes} bytes'
                raise JobError(msg, field=what, job_id=job_id)
            digest.update(block)
    return digest.hexdigest()


def _overrides(value: Any, *, job_id: str) -> tuple[tuple[str, float], ...]:
    if value is None:
        return ()
    if not isinstance(value, Mapping):
        msg = f'must be a mapping of dotted machine keys to numbers, got {describe(value)}'
        raise JobError(msg, field='overrides', job_id=job_id)
    if len(value) > MAX_OVERRIDES:
        msg = f'at most {MAX_OVERRIDES} keys, got {len(value)}'
        raise JobError(msg, field='overrides', job_id=job_id)
    out = []
    for key, v in value.items():
        if not isinstance(key, str) or len(key) > 200 or not _KEY.fullmatch(key):
            msg = f'key {describe(key)} is not a dotted machine-config key (e.g. axes.X.mass_kg)'
            raise JobError(msg, field='overrides', job_id=job_id)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            msg = f'{key}: must be a finite number, got {describe(v)}'
            raise JobError(msg, field='overrides', job_id=job_id)
        out.append((key, float(v)))
    return tuple(out)


def parse_job_request(request: Any, limits: JobLimits) -> JobSpec:
    """A checked :class:`JobSpec` from a request mapping (keys ``job_id``, ``program``,
    ``load_kg`` (default 0), ``machine`` and ``overrides`` (optional)).

    Raises
    ------
    JobError
        Naming the field and the reason; unknown keys are refused too (a typo such as
        ``load`` must not silently run with 0 kg).
    """
    if not isinstance(request, Mapping):
        msg = f'a job request is a mapping (JSON object), got {describe(request)}'
        raise JobError(msg, field='request')
    unknown = sorted(str(k) for k in request if k not in _REQUEST_KEYS)
    if unknown:
        msg = (f'unknown key(s) {", ".join(repr(shorten_path(k)) for k in unknown[:5])}; '
               f'known: {", ".join(sorted(_REQUEST_KEYS))}')
        raise JobError(msg, field='request')
    job_id = check_job_id(request.get('job_id'))
    if limits.record_root is not None and os.path.lexists(Path(limits.record_root) / job_id):
        msg = (f'a recording {shorten_path(str(Path(limits.record_root) / job_id))} exists '
               'already (never overwritten); choose a new job id')
        raise JobError(msg, field='job_id', job_id=job_id)
    if 'program' not in request:
        raise JobError('is required', field='program', job_id=job_id)
    program = resolve_inside(limits.program_root, request['program'], what='program',
                             job_id=job_id)
    load = check_load(request.get('load_kg', 0.0), max_load_kg=limits.max_load_kg,
                      job_id=job_id)
    machine = limits.default_machine
    if request.get('machine') is not None:
        if limits.machine_root is None:
            msg = 'this graph runs one machine; a job may not name another (no machine root)'
            raise JobError(msg, field='machine', job_id=job_id)
        machine = resolve_inside(limits.machine_root, request['machine'], what='machine',
                                 job_id=job_id)
    overrides = _overrides(request.get('overrides'), job_id=job_id)
    sha = file_sha256(program, max_bytes=limits.max_program_bytes, job_id=job_id)
    return JobSpec(job_id=job_id, program=program, program_sha256=sha, load_kg=load,
                   machine=Path(machine), overrides=overrides)


_MACHINES: OrderedDict[tuple[Any, ...], Any] = OrderedDict()
_MACHINES_KEPT = 8


def job_machine(spec: JobSpec) -> Any:
    """The job's machine: its YAML with the overrides applied, validated.

    Kept per process for the last 8 (file, size, modification time, overrides): the graph's
    nodes ask for it on every batch; an edited file is read again.

    Raises
    ------
    JobError
        (``field`` = ``machine`` or ``overrides``) the file or an override the machine
        validation refuses, with its message.
    """
    from ..machine import load_machine
    from ..sim import variant_machine
    field_ = 'overrides' if spec.overrides else 'machine'
    try:
        st = os.stat(spec.machine)
    except OSError as err:
        msg = f'{shorten_path(str(spec.machine))}: {err.strerror or "cannot be read"}'
        raise JobError(msg, field='machine', job_id=spec.job_id) from None
    key = (str(spec.machine), st.st_size, st.st_mtime_ns, spec.overrides)
    machine = _MACHINES.get(key)
    if machine is not None:
        _MACHINES.move_to_end(key)
        return machine
    try:
        if not spec.overrides:
            machine = load_machine(spec.machine)
        else:
            machine = variant_machine(str(spec.machine),
                                      tuple((k, v, False) for k, v in spec.overrides))
    except FeedAxisError as err:
        raise JobError(str(err), field=field_, job_id=spec.job_id) from None
    _MACHINES[key] = machine
    while len(_MACHINES) > _MACHINES_KEPT:
        _MACHINES.popitem(last=False)
    return machine
