"""Program text from bytes and files: encodings, line ends and the subroutine search path.

* Text is UTF-8, with or without a byte-order mark; any other byte sequence is a
  :class:`~..errors.GcodeError` naming the line and column of the first bad byte.
* Line ends may be LF, CRLF or a bare CR (classic Mac OS and some controls' editors), even
  mixed in one file; a CR-only file is as many lines as it has CRs.
* Subroutine files (``o<name> call`` of a subroutine not defined in the program) are found
  as LinuxCNC's ``SUBROUTINE_PATH`` finds them: the file ``<name>.ngc`` with the name in
  lower case, looked for in the program's own directory first and then in the directories
  the caller gives, in order.
"""
from __future__ import annotations

from os import PathLike
from pathlib import Path
import re

from ...errors import GcodeError

__all__ = ['decode_program', 'split_lines', 'read_program', 'read_program_bytes',
           'find_subroutine_file', 'MAX_PROGRAM_BYTES', 'SUBROUTINE_SUFFIX']

MAX_PROGRAM_BYTES = 2 * 1024 ** 3
"""Largest program or subroutine file read [bytes] (2 GiB); larger files are refused."""

SUBROUTINE_SUFFIX = '.ngc'
"""Suffix of a subroutine file, as in LinuxCNC (``o<name> call`` opens ``name.ngc``)."""

# LinuxCNC: subroutine file names are lower-case letters, digits, dash and underscore.
_SUB_NAME_RE = re.compile(r'[a-z0-9_\-]+')


def decode_program(data: bytes, *, file: str) -> str:
    """Decode program bytes as UTF-8 (a leading byte-order mark is dropped).

    Parameters
    ----------
    data
        The file's bytes.
    file
        Name used in errors.

    Returns
    -------
    str
        The text, line ends untouched (see :func:`split_lines`).

    Raises
    ------
    GcodeError
        For bytes that are not UTF-8, at the line and column of the first bad byte.
    """
    try:
        return data.decode('utf-8-sig')
    except UnicodeDecodeError as err:
        start = err.start
        line = 1 + data.count(b'\n', 0, start)
        # A CR-only file counts its lines by CR (a CR right before LF is one line end).
        line += data.count(b'\r', 0, start) - data.count(b'\r\n', 0, start)
        begin = max(data.rfind(b'\n', 0, start), data.rfind(b'\r', 0, start)) + 1
        msg = f'not UTF-8 text: byte 0x{data[start]:02x} at offset {start}'
        raise GcodeError(msg, file=file, line=line, column=start - begin + 1) from err


def split_lines(text: str) -> list[str]:
    """Split text into lines at LF, CRLF or CR (a final line end adds no empty line).

    Parameters
    ----------
    text
        Decoded program text.

    Returns
    -------
    list[str]
        The lines without their line ends. Only these three line ends count (unlike
        :meth:`str.splitlines`, a form feed or vertical tab stays inside its line).
    """
    if '\r' in text:
        text = text.replace('\r\n', '\n').replace('\r', '\n')
    lines = text.split('\n')
    if lines[-1] == '':
        lines.pop()
    return lines


def read_program(path: str | PathLike[str], *, file: str | None = None) -> str:
    """Read and decode a program or subroutine file.

    Parameters
    ----------
    path
        The file.
    file
        Name used in errors (default: ``str(path)``).

    Returns
    -------
    str
        The decoded text.

    Raises
    ------
    GcodeError
        When the file cannot be read (line 0, column 0, chained from the ``OSError``), is
        larger than :data:`MAX_PROGRAM_BYTES`, or is not UTF-8.
    """
    name = str(path) if file is None else file
    return decode_program(read_program_bytes(path, file=name), file=name)


def read_program_bytes(path: str | PathLike[str], *, file: str) -> bytes:
    """The bytes of a program file, at most :data:`MAX_PROGRAM_BYTES` (every dialect's reader
    decodes them its own way); :class:`GcodeError` at line 0, column 0 naming ``file`` when
    the file cannot be read or is larger."""
    try:
        with open(path, 'rb') as fh:
            data = fh.read(MAX_PROGRAM_BYTES + 1)
    except OSError as err:
        msg = f'cannot read the program: {err.strerror or err}'
        raise GcodeError(msg, file=file, line=0, column=0) from err
    if len(data) > MAX_PROGRAM_BYTES:
        msg = f'program larger than {MAX_PROGRAM_BYTES // 1024 ** 2} MiB'
        raise GcodeError(msg, file=file, line=0, column=0)
    return data


def find_subroutine_file(name: str, *, program_dir: str | PathLike[str] | None,
                         search_path: tuple[str | PathLike[str], ...] = ()) -> Path | None:
    """Find the file of subroutine ``name`` (LinuxCNC's ``SUBROUTINE_PATH`` rule).

    Parameters
    ----------
    name
        The subroutine's name as written in ``o<name> call`` (or its number as text).
    program_dir
        Directory of the program being run, searched first (``None``: none, e.g. a
        program given as a string).
    search_path
        Further directories, searched in order.

    Returns
    -------
    Path or None
        The first existing regular file ``<name lower-cased>.ngc``, or ``None``. Names with
        other characters than letters, digits, ``-`` and ``_`` are never looked up (so a
        name cannot reach outside the directories, e.g. ``o<../x> call``).
    """
    stem = name.lower()
    if not _SUB_NAME_RE.fullmatch(stem):
        return None
    dirs = ([] if program_dir is None else [program_dir]) + list(search_path)
    for directory in dirs:
        candidate = Path(directory) / (stem + SUBROUTINE_SUFFIX)
        if candidate.is_file():
            return candidate
    return None
