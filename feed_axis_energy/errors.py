"""Every error type the core raises; each message names the place and what was expected."""
from __future__ import annotations

import os
from typing import Any

__all__ = ['FeedAxisError', 'GcodeError', 'ConfigError', 'DataError', 'PlanningError',
           'OutputError', 'JobError', 'RequestError', 'describe', 'shorten', 'shorten_path',
           'SHOWN_CHARS']

SHOWN_CHARS = 60
"""Quoted input in an error message is cut to about this many characters."""


def shorten(text: str, *, limit: int = SHOWN_CHARS) -> str:
    """Return ``text`` cut to ``limit`` characters, marking the cut with ``...``.

    Parameters
    ----------
    text
        Any text taken from the input.
    limit
        Characters kept.

    Returns
    -------
    str
        At most ``limit + 3`` characters.
    """
    text = str(text)
    return text if len(text) <= limit else text[:limit] + '...'


def shorten_path(path: str) -> str:
    """Return a path for a message: control characters escaped, its end kept when long.

    Parameters
    ----------
    path
        A path from the command line or from a file.

    Returns
    -------
    str
        At most :data:`SHOWN_CHARS` characters; a cut is marked by a leading ``...``.
    """
    text = str(path).encode('unicode_escape', 'backslashreplace').decode('ascii')
    return text if len(text) <= SHOWN_CHARS else '...' + text[3 - SHOWN_CHARS:]


def describe(value: Any) -> str:
    """Describe a value from outside data for an error message, in bounded length.

    Containers are described by their type and size, never by their ``repr`` (a YAML file
    with aliases can expand to a structure far larger than the file); text and numbers are
    shown quoted and cut to :data:`SHOWN_CHARS` characters.

    Parameters
    ----------
    value
        Whatever the parser produced.

    Returns
    -------
    str
        For example ``nothing``, ``true``, ``number 1e+400``, ``text 'abc'``,
        ``a list of 3 items``, ``a mapping of 2 keys``.
    """
    if value is None:
        return 'nothing'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        if value.bit_length() > 190:  # str() of huge ints is slow and may be refused
            return f'an integer of {value.bit_length()} bits'
        return f'number {shorten(str(value))}'
    if isinstance(value, float):
        return f'number {value!r}'
    if isinstance(value, str):
        return f'text {shorten(value)!r}'
    if isinstance(value, (bytes, bytearray)):
        return f'{len(value)} bytes of binary data'
    if isinstance(value, dict):
        return f'a mapping of {len(value)} key{"s" if len(value) != 1 else ""}'
    if isinstance(value, (list, tuple)):
        return f'a list of {len(value)} item{"s" if len(value) != 1 else ""}'
    return f'a value of type {type(value).__name__}'


class FeedAxisError(ValueError):
    """Base of all domain errors of the package (a ``ValueError``)."""


class GcodeError(FeedAxisError):
    """An NC program that cannot be simulated.

    Parameters
    ----------
    message
        What is wrong and what was expected.
    file, line, column
        The place: file name, 1-based line and 1-based column of the offending text.
    text
        The offending text itself (a word such as ``G5`` or the whole line).
    """

    def __init__(self, message: str, *, file: str, line: int, column: int, text: str = ''):
        self.file = file
        self.line = line
        self.column = column
        self.text = text
        self.reason = message
        shown = f' near {text!r}' if text else ''
        super().__init__(f'{file}:{line}:{column}: {message}{shown}')


class ConfigError(FeedAxisError):
    """A machine, manifest or node parameter file with a missing or invalid value.

    ``key`` is the dotted path of the value (``axes.X.screw.lead_m``).
    """

    def __init__(self, message: str, *, file: str = '<config>', key: str = ''):
        self.file = file
        self.key = key
        self.reason = message
        where = f'{file}: {key}: ' if key else f'{file}: '
        super().__init__(f'{where}{message}')


class DataError(FeedAxisError):
    """Measured data that cannot be used.

    Names the file, and where known the column and 1-based data row (CSV) or the topic and
    0-based message index (bags).
    """

    def __init__(self, message: str, *, file: str, column: str = '', row: int | None = None,
                 topic: str = '', index: int | None = None):
        self.file = file
        self.column = column
        self.row = row
        self.topic = topic
        self.index = index
        self.reason = message
        parts = [file]
        if column:
            parts.append(f'column {shorten(column)!r}')
        if row is not None:
            parts.append(f'row {row}')
        if topic:
            parts.append(f'topic {shorten(topic)!r}')
        if index is not None:
            parts.append(f'message {index}')
        super().__init__(f'{", ".join(parts)}: {message}')


class PlanningError(FeedAxisError):
    """A program the planner cannot turn into motion (e.g. a move on an axis the machine lacks)."""

    def __init__(self, message: str, *, file: str = '<program>', line: int = 0):
        self.file = file
        self.line = line
        self.reason = message
        super().__init__(f'{file}:{line}: {message}' if line else f'{file}: {message}')


class OutputError(FeedAxisError):
    """An output that must not be written: names the option and the path.

    Parameters
    ----------
    message
        What is wrong and what to do.
    path
        The path concerned (shown cut to about 60 characters).
    option
        The argument or key the path comes from (``--out``, ``campaign.yaml runs[2].name``).
    """

    def __init__(self, message: str, *, path: str | os.PathLike[str] = '', option: str = ''):
        self.path = shorten_path(os.fspath(path)) if path else ''
        self.option = option
        self.reason = message
        where = ' '.join(p for p in (option, self.path) if p)
        super().__init__(f'{where}: {message}' if where else message)


class JobError(FeedAxisError):
    """A job request refused, or a job command that is not legal in the current state.

    Parameters
    ----------
    message
        What is wrong and what was expected.
    field
        The request field at fault (``job_id``, ``program``, ``load_kg``, ``machine``,
        ``overrides``, ``request``) or ``state`` for a command the job state does not allow.
    job_id
        The job the request named (shown cut to about 60 characters; may be empty).
    """

    def __init__(self, message: str, *, field: str, job_id: str = ''):
        self.field = field
        self.job_id = job_id
        self.reason = message
        who = f'job {shorten(job_id)!r}: ' if job_id else ''
        super().__init__(f'{who}{field}: {message}')


class RequestError(FeedAxisError):
    """A request from a cell client (an OPC UA method call, an MQTT message) that is refused.

    Parameters
    ----------
    message
        What is wrong and what was expected.
    request
        The request (``StartJob``, ``AbortJob``, an MQTT topic).
    field
        The argument or key at fault (``JobId``, ``LoadKg``, ``value``).
    code
        A short fixed word for counting refusals by kind (``bad_json``, ``too_large``).
    """

    def __init__(self, message: str, *, request: str, field: str = '', code: str = ''):
        self.request = request
        self.field = field
        self.code = code
        self.reason = message
        where = f'{shorten(request)} {field}' if field else shorten(request)
        super().__init__(f'{where}: {message}')
