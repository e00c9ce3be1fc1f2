"""Framing check of an MCAP file before ``rosbags`` reads it, so that memory stays bounded.

``rosbags`` trusts the length fields of an MCAP file: a damaged length (one flipped byte in a
record header, a chunk index or the footer's summary offset) makes it allocate that many
bytes at once, gigabytes for a file of a few kB. :func:`check_mcap` walks the top-level
records with seeks, reading only their 9-byte headers and the small headers of chunks and
chunk indexes, and refuses the file unless

* every record fits in the file (the file is not truncated or damaged in a length),
* the footer's summary offset and every chunk index point at record starts (at a chunk),
* every chunk's compressed part fits in the chunk, and its declared uncompressed size is at
  most :data:`MAX_CHUNK_BYTES`.

Record layout (MCAP specification, https://mcap.dev/spec): magic ``\\x89MCAP0\\r\\n``, then
records of ``opcode: uint8, length: uint64 LE, content``, the footer (opcode 0x02) and the
magic again. What this check cannot see: a compressed chunk whose real decompressed size
exceeds the size it declares is decompressed whole by ``rosbags`` before the size is
compared (our own bags are not compressed).
"""
from __future__ import annotations

import os
from pathlib import Path
import struct
from typing import BinaryIO, NoReturn

from ..errors import DataError

__all__ = ['MAX_CHUNK_BYTES', 'check_mcap']

MAX_CHUNK_BYTES = 256 * 1024 * 1024
"""Largest declared uncompressed chunk accepted [bytes] (rosbag2 writes chunks of ~1 MB)."""

_MAGIC = b'\x89MCAP0\r\n'
_FOOTER, _CHUNK, _CHUNK_INDEX = 0x02, 0x06, 0x08
_MAX_INDEX_RECORD = 1024 * 1024


def check_mcap(path: str | Path, *, bag: str | Path | None = None) -> None:
    """Refuse an MCAP file whose length fields do not fit (see the module docstring).

    Parameters
    ----------
    path
        The ``.mcap`` file.
    bag
        The bag directory, named in errors (default: the file).

    Raises
    ------
    DataError
        Naming the bag and the byte offset of the first record that does not fit.
    """
    where = str(bag if bag is not None else path)
    name = Path(path).name
    try:
        with open(path, 'rb') as fh:
            size = os.fstat(fh.fileno()).st_size
            if size < 2 * len(_MAGIC) + 9 or fh.read(len(_MAGIC)) != _MAGIC:
                return  # rosbags names these (empty, bad magic) without a large allocation
            starts, chunks, footer = _walk(fh, size, where, name)
            for offset in chunks:
                _check_chunk(fh, offset, where, name)
            if footer is not None:
                _check_footer(fh, footer, starts, where, name)
            for offset, content in _chunk_indexes(fh, starts, where, name):
                _check_chunk_index(content, offset, size, chunks, where, name)
    except OSError as err:
        msg = f'cannot read {name}: {err.strerror or type(err).__name__}'
        raise DataError(msg, file=where) from None


def _fail(message: str, where: str, name: str, offset: int) -> NoReturn:
    msg = f'{name}, byte {offset}: {message}; the file is truncated or damaged'
    raise DataError(msg, file=where)


def _walk(fh: BinaryIO, size: int, where: str,
          name: str) -> tuple[dict[int, int], set[int], int | None]:
    """Record starts ``{offset: opcode}``, chunk offsets and the footer offset."""
    starts: dict[int, int] = {}
    chunks: set[int] = set()
    pos = len(_MAGIC)
    end = size - len(_MAGIC)
    while pos < end:
        fh.seek(pos)
        head = fh.read(9)
        if len(head) < 9:
            _fail('a record header is cut off', where, name, pos)
        opcode, length = head[0], struct.unpack('<Q', head[1:])[0]
        if length > end - pos - 9:
            _fail(f'a record (opcode 0x{opcode:02x}) claims {length} bytes, '
                  f'{end - pos - 9} are left', where, name, pos)
        starts[pos] = opcode
        if opcode == _CHUNK:
            chunks.add(pos)
        if opcode == _FOOTER:
            return starts, chunks, pos
        pos += 9 + length
    return starts, chunks, None


def _read_u64(data: bytes, at: int) -> int:
    return struct.unpack_from('<Q', data, at)[0]


def _check_chunk(fh: BinaryIO, offset: int, where: str, name: str) -> None:
    fh.seek(offset + 1)
    length = struct.unpack('<Q', fh.read(8))[0]
    head = fh.read(min(length, 32 + 1024))
    if len(head) < 32:
        _fail('a chunk header is cut off', where, name, offset)
    uncompressed = _read_u64(head, 16)
    text_len = struct.unpack_from('<I', head, 28)[0]
    if 32 + text_len + 8 > len(head):
        _fail('a chunk names a compression longer than the chunk', where, name, offset)
    compressed = _read_u64(head, 32 + text_len)
    if compressed > length - (32 + text_len + 8):
        _fail(f'a chunk claims {compressed} compressed bytes, more than it holds', where, name,
              offset)
    if uncompressed > MAX_CHUNK_BYTES:
        _fail(f'a chunk declares {uncompressed} bytes uncompressed, more than the '
              f'{MAX_CHUNK_BYTES} accepted', where, name, offset)


def _check_footer(fh: BinaryIO, footer: int, starts: dict[int, int], where: str,
                  name: str) -> None:
    fh.seek(footer + 9)
    content = fh.read(20)
    if len(content) < 16:
        _fail('the footer is cut off', where, name, footer)
    for label, value in (('summary', _read_u64(content, 0)),
                         ('summary offset', _read_u64(content, 8))):
        if value and value not in starts:
            _fail(f'the footer\'s {label} start {value} is not the start of a record', where,
                  name, footer)


def _chunk_indexes(fh: BinaryIO, starts: dict[int, int], where: str,
                   name: str) -> list[tuple[int, bytes]]:
    out = []
    for offset, opcode in starts.items():
        if opcode != _CHUNK_INDEX:
            continue
        fh.seek(offset + 1)
        length = struct.unpack('<Q', fh.read(8))[0]
        if length > _MAX_INDEX_RECORD:
            _fail(f'a chunk index claims {length} bytes', where, name, offset)
        out.append((offset, fh.read(length)))
    return out


def _check_chunk_index(content: bytes, offset: int, size: int, chunks: set[int], where: str,
                       name: str) -> None:
    try:
        chunk_start, chunk_length = _read_u64(content, 16), _read_u64(content, 24)
        map_len = struct.unpack_from('<I', content, 32)[0]
        at = 36 + map_len + 8
        text_len = struct.unpack_from('<I', content, at)[0]
        at += 4 + text_len
        compressed, uncompressed = _read_u64(content, at), _read_u64(content, at + 8)
    except struct.error:
        _fail('a chunk index is cut off', where, name, offset)
    if chunk_start not in chunks or chunk_start + chunk_length > size:
        _fail(f'a chunk index points at byte {chunk_start}, where no chunk starts', where, name,
              offset)
    if compressed > chunk_length or uncompressed > MAX_CHUNK_BYTES:
        _fail(f'a chunk index claims {compressed} compressed and {uncompressed} uncompressed '
              'bytes, more than the chunk can hold', where, name, offset)
