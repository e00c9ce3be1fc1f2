"""The one way YAML from outside enters the core: bounded in size, depth and alias expansion.

Every YAML file the core reads (machine configs, campaign manifests, a bag's
``metadata.yaml``) goes through :func:`load_yaml_file` (or :func:`load_yaml_text`):

* the file must be a regular file and is read as bytes, at most ``max_bytes``
  (:data:`MAX_BYTES` by default), then decoded as UTF-8; a bad byte is named by line and
  column;
* a text in the small subset of :mod:`.yamlsubset` (plain block mappings of numbers and
  names, as the machine configs are) is read there without importing PyYAML, to the same
  data PyYAML would build (start-up time, issue 10); every other text is parsed by
  PyYAML's pure-Python safe loader (:mod:`.yamlload`; only plain data: mappings, lists,
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

from .errors import ConfigError, DataError
from .yamlsubset import parse_subset

__all__ = ['MAX_BYTES', 'MAX_DEPTH', 'MAX_EXPANDED_NODES', 'load_yaml_file', 'load_yaml_text',
           'read_text_file']

MAX_BYTES = 16 * 1024 * 1024
"""Largest YAML file read [bytes] (machine configs and manifests are a few kB)."""
MAX_DEPTH = 50
"""Deepest nesting of mappings and lists accepted (our files use at most 6 levels)."""
MAX_EXPANDED_NODES = 200_000
"""Most values a document may hold once every alias is expanded."""


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
    data = parse_subset(text, max_depth=MAX_DEPTH - 1)
    if data is not None:
        return data
    from .yamlload import load_pyyaml
    return load_pyyaml(text, file=file, make_error=lambda message, f: _make(error, message, f),
                       max_depth=MAX_DEPTH, max_expanded=MAX_EXPANDED_NODES)


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
