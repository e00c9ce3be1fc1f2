"""The JSON text of the job topics: commands in, replies, state and results out.

``job/command`` carries one JSON object per message (docs/nodes.md, "Jobs"):
``{"command": "start", "request_id": "...", "job_id": ..., "program": ..., "load_kg": ...,
"machine": ..., "overrides": {...}}`` or ``{"command": "abort", "request_id": "...",
"job_id": ...}`` or ``{"command": "result", "request_id": "...", "job_id": ...}`` (the reply
carries the kept result). :func:`parse_command` bounds and checks the text before anything reads
it (size, UTF-8, JSON, nesting, the command word); what goes out is written by
:func:`dumps` (no NaN or infinity: they are not JSON and a result holds none).
"""
from __future__ import annotations

from dataclasses import dataclass
import json
from typing import Any

from ..errors import describe, JobError

__all__ = ['COMMANDS', 'Command', 'MAX_COMMAND_BYTES', 'dumps', 'parse_command', 'reply']

MAX_COMMAND_BYTES = 16 * 1024
COMMANDS = ('start', 'abort', 'result')
_MAX_DEPTH = 4


@dataclass(frozen=True)
class Command:
    """A checked command: its word, the client's ``request_id`` (echoed in the reply) and
    the other keys (the job request for ``start``)."""

    command: str
    request_id: str
    body: dict[str, Any]


def _depth(value: Any, level: int = 0) -> int:
    if isinstance(value, dict):
        return max([_depth(v, level + 1) for v in value.values()] or [level + 1])
    if isinstance(value, list):
        return max([_depth(v, level + 1) for v in value] or [level + 1])
    return level


def parse_command(text: str | bytes) -> Command:
    """A :class:`Command` from the text of one ``job/command`` message.

    Raises
    ------
    JobError
        (``field`` = ``request``) too long, not UTF-8, not a JSON object, nested deeper than
        a job request, an unknown command, or a ``request_id`` that is not short text.
    """
    raw = text.encode('utf-8', 'surrogatepass') if isinstance(text, str) else bytes(text)
    if len(raw) > MAX_COMMAND_BYTES:
        msg = f'a command is at most {MAX_COMMAND_BYTES} bytes, got {len(raw)}'
        raise JobError(msg, field='request')
    try:
        data = json.loads(raw.decode('utf-8'), parse_constant=_no_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as err:
        msg = f'not JSON text: {type(err).__name__}: {str(err)[:80]}'
        raise JobError(msg, field='request') from None
    if not isinstance(data, dict):
        msg = f'a command is a JSON object, got {describe(data)}'
        raise JobError(msg, field='request')
    if _depth(data) > _MAX_DEPTH:
        msg = f'a command is nested at most {_MAX_DEPTH} levels deep'
        raise JobError(msg, field='request')
    word = data.pop('command', None)
    if word not in COMMANDS:
        msg = f'"command" must be one of {", ".join(COMMANDS)}, got {describe(word)}'
        raise JobError(msg, field='request')
    request_id = data.pop('request_id', '')
    if not isinstance(request_id, str) or len(request_id) > 64 or not request_id.isprintable():
        msg = ('"request_id" must be printable text of at most 64 characters, got '
               f'{describe(request_id)}')
        raise JobError(msg, field='request')
    return Command(command=word, request_id=request_id, body=data)


def _no_constant(name: str) -> Any:
    msg = f'{name} is not a number JSON allows'
    raise ValueError(msg)


def reply(request_id: str, *, accepted: bool, message: str, job_id: str = '',
          state: str = '', field: str = '') -> dict[str, Any]:
    """The ``job/reply`` object answering one command."""
    return {'request_id': request_id, 'accepted': bool(accepted), 'message': message,
            'job_id': job_id, 'state': state, 'field': field}


def dumps(obj: Any) -> str:
    """Compact JSON text; ``ValueError`` on NaN or infinity (never sent)."""
    return json.dumps(obj, allow_nan=False, separators=(',', ':'), sort_keys=True)
