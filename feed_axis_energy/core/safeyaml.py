"""The one way YAML from outside enters the core: bounded in size, depth and alias expansion.

Every YAML file the core reads (machine configs, campaign manifests, a bag's
``metadata.yaml``) goes through :func:`load_yaml_file` (or :func:`load_yaml_text`):

* the file must be a regular file and is read as bytes, at most ``max_bytes``
  (:data:`MAX_BYTES` by default), then decoded as UTF-8; a bad byte is named by line and
  column;
* it is parsed by PyYAML's pure-Python safe loader (only plain data: mappings, lists,
  text, numbers, booleans, null, timestamps), with two limits that PyYAML lacks:

  - nesting deeper than :data:`MAX_DEPTH` levels is refused while composing, so no
    ``RecursionError`` can occur here or in the code that walks the result;
  - anchors and aliases (``&a``/``*a``, also ``<<: *a`` merge keys) are allowed, but the
    document with every alias expanded may hold at most :data:`MAX_EXPANDED_NODES` values
    ("billion laughs": a few hundred bytes of nested aliases would otherwise expand to
    billions of values once walked or printed); a recursive alias is refused.

Every failure is raised as the caller's error type (:class:`~.errors.ConfigError` for
configs, :class:`~.errors.DataError` for bag metadata) naming the file and, where known, the
line and column; quoted input is cut to :data:`~.errors.SHOWN_CHARS` characters.
"""
from __future__ import annotations

import os
from pathlib import Path
import stat
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, SequenceNode

from .errors import ConfigError, DataError, shorten

__all__ = ['MAX_BYTES', 'MAX_DEPTH', 'MAX_EXPANDED_NODES', 'load_yaml_file', 'load_yaml_text',
           'read_text_file']

MAX_BYTES = 16 * 1024 * 1024
"""Largest YAML file read [bytes] (machine configs and manifests are a few kB)."""
MAX_DEPTH = 50
"""Deepest nesting of mappings and lists accepted (our files use at most 6 levels)."""
MAX_EXPANDED_NODES = 200_000
"""Most values a document may hold once every alias is expanded."""


class _LimitExceeded(Exception):
    """Raised inside the loader; turned into the caller's error type with the place."""

    def __init__(self, message: str, mark: Any = None):
        super().__init__(message)
        self.mark = mark


class _BoundedLoader(yaml.SafeLoader):
    """PyYAML's safe loader with a nesting limit and alias bookkeeping."""

    def __init__(self, stream: str):
        super().__init__(stream)
        self._depth = 0
        self.aliases = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node:
        if self.check_event(yaml.AliasEvent):
            self.aliases += 1
            return super().compose_node(parent, index)
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                msg = f'nested deeper than {MAX_DEPTH} levels'
                raise _LimitExceeded(msg, self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def _expanded_size(root: Node, budget: int) -> int:
    """Count the values of ``root`` with aliases expanded; stop once above ``budget``."""
    sizes: dict[int, int] = {}
    on_path: set[int] = set()
    # iterative post-order walk: (node, children done?)
    stack: list[tuple[Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            on_path.discard(key)
            total = 1 + sum(sizes[id(c)] for c in _children(node))
            sizes[key] = total
            if total > budget:
                return total
            continue
        if key in sizes:
            continue
        if key in on_path:
            raise _LimitExceeded('an alias refers to the node that contains it (recursive '
                                 'alias)', node.start_mark)
        on_path.add(key)
        stack.append((node, True))
        for child in _children(node):
            if id(child) in on_path:
                raise _LimitExceeded('an alias refers to the node that contains it '
                                     '(recursive alias)', child.start_mark)
            if id(child) not in sizes:
                stack.append((child, False))
    return sizes[id(root)]


def _children(node: Node) -> list[Node]:
    if isinstance(node, SequenceNode):
        return list(node.value)
    if isinstance(node, MappingNode):
        return [n for pair in node.value for n in pair]
    return []


def _where(mark: Any) -> str:
    if mark is None:
        return ''
    return f'line {mark.line + 1}, column {mark.column + 1}: '


def _yaml_message(err: yaml.YAMLError) -> str:
    mark = getattr(err, 'problem_mark', None)
    problem = getattr(err, 'problem', None)
    if problem is None:
        # the first line only: PyYAML appends a quoted excerpt of the input
        problem = str(err).splitlines()[0] if str(err) else type(err).__name__
    context = getattr(err, 'context', None)
    text = f'{context}: {problem}' if context else str(problem)
    return f'{_where(mark)}not valid YAML: {shorten(text, limit=120)}'


def load_yaml_text(text: str, *, file: str, error: type = ConfigError) -> Any:
    """Parse one YAML document with the limits of this module.

    Parameters
    ----------
    text
        The document.
    file
        Names the source in errors.
    error
        The error type raised: :class:`ConfigError` or :class:`DataError`.

    Returns
    -------
    Any
        Plain Python data (``None`` for an empty document).

    Raises
    ------
    ConfigError or DataError
        Syntax error, nesting deeper than :data:`MAX_DEPTH`, alias expansion above
        :data:`MAX_EXPANDED_NODES`, a recursive alias or a value PyYAML cannot build (such
        as a date that does not exist), naming line and column where known.
    """
    try:
        loader = _BoundedLoader(text)
    except yaml.reader.ReaderError as err:
        pos = int(err.position)
        line = text.count('\n', 0, pos) + 1
        column = pos - (text.rfind('\n', 0, pos) + 1) + 1
        msg = (f'line {line}, column {column}: character U+{int(err.character):04X} is not '
               'allowed in YAML (control character); expected printable text')
        raise _make(error, msg, file) from None
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if loader.aliases:
            size = _expanded_size(node, MAX_EXPANDED_NODES)
            if size > MAX_EXPANDED_NODES:
                msg = (f'{loader.aliases} aliases (*name) expand the document to more than '
                       f'{MAX_EXPANDED_NODES} values; expected plain data (write the values '
                       'out, or use fewer nested aliases)')
                raise _LimitExceeded(msg)
        return loader.construct_document(node)
    except _LimitExceeded as err:
        raise _make(error, f'{_where(err.mark)}{err}', file) from None
    except yaml.YAMLError as err:
        raise _make(error, _yaml_message(err), file) from None
    except (ValueError, OverflowError, TypeError) as err:
        # PyYAML's constructors let these through, e.g. a timestamp 2024-13-45 or an
        # integer of more than 4300 digits
        msg = f'not valid YAML: a value cannot be read ({shorten(str(err), limit=120)})'
        raise _make(error, msg, file) from None
    finally:
        loader.dispose()


def read_text_file(path: str | Path, *, error: type = ConfigError, what: str = 'file',
                   max_bytes: int = MAX_BYTES) -> str:
    """Read a small UTF-8 text file whole, refusing anything that is not a regular file.

    Parameters
    ----------
    path
        The file.
    error
        The error type raised: :class:`ConfigError` or :class:`DataError`.
    what
        Names the file's role in messages (``'machine file'``).
    max_bytes
        Largest size accepted [bytes].

    Returns
    -------
    str
        The text (a leading UTF-8 byte-order mark removed).

    Raises
    ------
    ConfigError or DataError
        Missing, unreadable, not a regular file (a directory, a FIFO, a symlink loop), larger
        than ``max_bytes``, or not UTF-8 (naming line and column of the first bad byte).
    """
    file = str(path)
    try:
        # checked before opening: open() of a FIFO would wait for a writer forever
        if not stat.S_ISREG(os.stat(path).st_mode):
            msg = f'cannot read {what}: not a regular file'
            raise _make(error, msg, file)
        with open(path, 'rb') as fh:
            data = fh.read(max_bytes + 1)
    except OSError as err:
        msg = f'cannot read {what}: {err.strerror or type(err).__name__}'
        raise _make(error, msg, file) from None
    if len(data) > max_bytes:
        msg = f'{what} is larger than {max_bytes} bytes; expected a small text file'
        raise _make(error, msg, file)
    if data.startswith(b'\xef\xbb\xbf'):
        data = data[3:]
    try:
        return data.decode('utf-8')
    except UnicodeDecodeError as err:
        line = data.count(b'\n', 0, err.start) + 1
        column = err.start - (data.rfind(b'\n', 0, err.start) + 1) + 1
        msg = (f'line {line}, column {column}: byte 0x{data[err.start]:02x} is not valid '
               f'UTF-8; the {what} must be UTF-8 text')
        raise _make(error, msg, file) from None


def load_yaml_file(path: str | Path, *, error: type = ConfigError, what: str = 'YAML file',
                   max_bytes: int = MAX_BYTES) -> Any:
    """Read and parse a YAML file: :func:`read_text_file` then :func:`load_yaml_text`.

    Parameters
    ----------
    path
        The file.
    error
        The error type raised: :class:`ConfigError` or :class:`DataError`.
    what
        Names the file's role in messages (``'manifest'``).
    max_bytes
        Largest size accepted [bytes].

    Returns
    -------
    Any
        Plain Python data (``None`` for an empty file).

    Raises
    ------
    ConfigError or DataError
        Everything :func:`read_text_file` and :func:`load_yaml_text` raise.
    """
    text = read_text_file(path, error=error, what=what, max_bytes=max_bytes)
    return load_yaml_text(text, file=str(path), error=error)


def _make(error: type, message: str, file: str) -> Exception:
    if error is DataError:
        return DataError(message, file=file)
    return error(message, file=file)
