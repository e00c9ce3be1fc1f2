"""An MCAP file written block by block: message records built with numpy, not one by one.

The framing records (header, schemas, channels, chunk indexes, statistics, metadata, summary
offsets, footer) are the ``mcap`` library's record classes (:mod:`mcap.records`) written with
its ``RecordBuilder``; only the bulk - message records and message indexes - is laid out
here, because the library's ``Writer.add_message`` costs a few microseconds of Python per
message. Layout of the records written here (MCAP specification, https://mcap.dev/spec,
little-endian):

* Message (opcode 0x05): ``channel_id u16, sequence u32, log_time u64, publish_time u64,
  data``; a block of messages of one size is one ``(m, width)`` byte array whose rows get
  their 31-byte record header in place (:meth:`McapStream.add_block`);
* Chunk (0x06): ``message_start_time u64, message_end_time u64, uncompressed_size u64,
  uncompressed_crc u32 (CRC-32 of the records; 0, "not computed", for zstd chunks, whose
  frames carry their own checksum), compression string, records u64 + bytes``;
* MessageIndex (0x07), one per channel after each chunk: ``channel_id u16``, then
  ``u32`` byte length and ``(log_time u64, offset u64)`` pairs, offsets into the
  uncompressed records.

Schemas and channels are written before the first chunk (outside chunks) and repeated in the
summary; every chunk holds the messages of one stretch of time on every channel, so chunks
barely overlap in time. Compression: ``zstd`` at level -1, a "fast" level (on simulated
series 1.3x faster than level 1 for a 2-4 % larger file, level 1 1.7x faster than level 3,
rosbags' choice, for 3 %) or ``lz4``, both decoded by rosbags, the mcap
library and the common viewers (Foxglove, PlotJuggler), or none. Who reads what: rosbags'
MCAP storage (``rosbags/rosbag2/storage_mcap.py``) decompresses ``lz4`` with ``lz4.frame``
and ``zstd``; the ``mcap`` Python library (``mcap/stream_reader.py``) both, lz4 when the
``lz4`` package is installed (rosbags requires it); the MCAP C++ library, which PlotJuggler's
MCAP loader uses, has ``LZ4Reader`` and ``ZStdReader`` (https://mcap.dev/docs/cpp); Foxglove
decompresses chunks with ``@mcap/support``'s handlers for the well-known compressions lz4 and
zstd. Measured on these recordings (``bench/bench_record.py``, README "Benchmarks"): lz4 is
not faster than zstd -1 here and 35-50 % larger; zstd -3 is 5-15 % faster for a 4-6 %
larger file; 4 MiB chunks 0-15 % faster than 1 MiB at the same size. Compressing a chunk's
pieces as one frame without joining them, and rows without spare bytes (no copy into the
chunk, unaligned float views), were tried and measured no faster: the copies are cheap
next to encoding and compression.
"""
from __future__ import annotations

import queue
import struct
import threading
from typing import BinaryIO
import zlib

from mcap.data_stream import RecordBuilder
from mcap.records import (Channel, ChunkIndex, DataEnd, Footer, Header, Metadata,
                          MetadataIndex, Schema, Statistics, SummaryOffset)
import numpy as np

__all__ = ['McapStream', 'MCAP_COMPRESSIONS', 'CHUNK_BYTES', 'QUEUED_CHUNKS', 'RECORD_HEAD']

MCAP_COMPRESSIONS = ('none', 'zstd', 'lz4')
CHUNK_BYTES = 1 << 20          # uncompressed records per chunk (as rosbag2 and mcap write)
QUEUED_CHUNKS = 2              # chunks waiting for the writer thread (memory bound)
RECORD_HEAD = 31               # opcode, length, channel, sequence, log and publish time
ZSTD_LEVEL = -1
_MAGIC = b'\x89MCAP0\r\n'
_OP_MESSAGE, _OP_CHUNK, _OP_MESSAGE_INDEX = 0x05, 0x06, 0x07
_OP_SCHEMA, _OP_CHANNEL, _OP_STATISTICS, _OP_CHUNK_INDEX = 0x03, 0x04, 0x0B, 0x08
_OP_METADATA_INDEX = 0x0D
_MSG_HEAD = np.dtype([('op', 'u1'), ('len', '<u8'), ('channel', '<u2'), ('seq', '<u4'),
                      ('log', '<u8'), ('pub', '<u8')])


def _compressor(compression: str):
    """``(name in the chunk record, function bytes -> bytes)`` for a compression."""
    if compression == 'zstd':
        import zstandard
        # the frame's own checksum (XXH64, checked by every zstd decoder) stands in for the
        # chunk's CRC-32, which would cost a tenth of the writer's time
        return 'zstd', zstandard.ZstdCompressor(level=ZSTD_LEVEL, write_checksum=True).compress
    if compression == 'lz4':
        import lz4.frame
        return 'lz4', lz4.frame.compress
    if compression == 'none':
        return '', None
    msg = f'compression must be one of {", ".join(MCAP_COMPRESSIONS)}, got {compression!r}'
    raise ValueError(msg)


class McapStream:
    """Write one MCAP file to an open binary stream, chunk by chunk (bounded memory).

    Parameters
    ----------
    fh
        Binary stream opened for writing at its start; not closed here.
    compression
        ``'zstd'``, ``'lz4'`` or ``'none'``.
    chunk_bytes
        A chunk is closed once its uncompressed records reach this size.
    profile, library
        The header record's fields (``'ros2'`` for rosbag2 bags).
    background
        Compress and write in a second thread (the compressors and file writes release the
        GIL, so on a machine with a free core the caller's encoding and the compression
        overlap; at most :data:`QUEUED_CHUNKS` chunks wait). ``False``: all in the caller's
        thread. Either way the file is the same. An error of the thread (a full disk) is
        raised by the next call.
    """

    def __init__(self, fh: BinaryIO, *, compression: str = 'zstd',
                 chunk_bytes: int = CHUNK_BYTES, profile: str = 'ros2',
                 library: str = 'feed_axis_energy', background: bool = False) -> None:
        self._error: BaseException | None = None
        self._queue: queue.Queue | None = None
        self._thread: threading.Thread | None = None
        if background:
            self._queue = queue.Queue(maxsize=QUEUED_CHUNKS)
            self._thread = threading.Thread(target=self._work, name='mcap-writer',
                                            daemon=True)
            self._thread.start()
        self._fh = fh
        self._compression, self._compress = _compressor(compression)
        self.chunk_bytes = int(chunk_bytes)
        self._pos = 0
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self.counts: dict[int, int] = {}
        self.t_min: int | None = None
        self.t_max: int | None = None
        self._reset_chunk()
        self._do(self._write, _MAGIC)
        self._framing(Header(profile=profile, library=library))

    # ------------------------------------------------------------------ low level
    # Everything that writes to the file, and so knows file offsets, runs through _do: in
    # order, in the caller's thread or in the writer thread.
    def _work(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self._error is None:
                fn, args = item
                try:
                    fn(*args)
                except BaseException as err:  # noqa: B902 - handed to the caller's thread
                    self._error = err

    def _do(self, fn, *args) -> None:
        if self._error is not None:
            raise self._error
        if self._queue is None:
            fn(*args)
        else:
            self._queue.put((fn, args))

    def _stop(self) -> None:
        """End the writer thread after the work queued so far."""
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            self._thread = None
        if self._error is not None:
            raise self._error

    def abort(self) -> None:
        """Stop writing (after an error of the caller): the queued work is dropped."""
        if self._error is None:
            self._error = RuntimeError('aborted')
        try:
            self._stop()
        except BaseException:  # noqa: B902 - the caller's own error is the one that counts
            pass

    def _write(self, data) -> None:
        self._fh.write(data)
        self._pos += len(data) if isinstance(data, bytes) else memoryview(data).nbytes

    def _framing(self, *records) -> None:
        builder = RecordBuilder()
        for record in records:
            record.write(builder)
        self._do(self._write, builder.end())

    def _reset_chunk(self) -> None:
        self._blocks: list[bytes] = []
        self._size = 0
        # per channel (stamps, offsets): arrays of a block, or lists of single messages
        self._index: dict[int, list[tuple]] = {}
        self._start: int | None = None
        self._end = 0

    # ------------------------------------------------------------------ declarations
    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Declare a schema (written at once, outside chunks); return its id."""
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(schema)
        self.close_chunk()
        self._framing(schema)
        return schema.id

    def add_channel(self, topic: str, *, schema_id: int, message_encoding: str = 'cdr',
                    metadata: dict[str, str] | None = None) -> int:
        """Declare a channel (written at once, outside chunks); return its id."""
        channel = Channel(id=len(self._channels) + 1, schema_id=schema_id, topic=topic,
                          message_encoding=message_encoding, metadata=dict(metadata or {}))
        self._channels.append(channel)
        self.counts[channel.id] = 0
        self.close_chunk()
        self._framing(channel)
        return channel.id

    # ------------------------------------------------------------------ messages
    def add_block(self, channel: int, stamps: np.ndarray, rows: np.ndarray, *,
                  start: int, length: int) -> None:
        """Append messages of one size: message ``i`` is ``rows[i, start:start + length]``.

        ``rows`` must have :data:`RECORD_HEAD` spare bytes before ``start`` (they receive the
        record headers; the array is modified). Log and publish time are ``stamps`` [ns].
        The block goes into the open chunk whole; the chunk is closed when it is full.
        """
        m = int(rows.shape[0])
        if m == 0:
            return
        if start < RECORD_HEAD:
            msg = f'add_block: {start} spare bytes before the messages, need {RECORD_HEAD}'
            raise ValueError(msg)
        stamps = np.asarray(stamps, dtype=np.int64)
        if stamps.shape != (m,) or int(stamps.min()) < 0:
            msg = 'add_block: one non-negative stamp per row expected'
            raise ValueError(msg)
        c0 = start - RECORD_HEAD
        head = np.zeros(m, _MSG_HEAD)
        head['op'] = _OP_MESSAGE
        head['len'] = RECORD_HEAD - 9 + length
        head['channel'] = channel
        seq0 = self.counts[channel]
        head['seq'] = (np.arange(seq0, seq0 + m, dtype=np.int64) % (1 << 32)).astype('<u4')
        head['log'] = stamps
        head['pub'] = stamps
        rows[:, c0:start] = head.view(np.uint8).reshape(m, RECORD_HEAD)
        self._append(channel, stamps, rows[:, c0:start + length].tobytes(), RECORD_HEAD + length)

    def add_message(self, channel: int, stamp: int, data: bytes) -> None:
        """Append one message (for messages that are not series: no numpy per message)."""
        stamp = int(stamp)
        if stamp < 0:
            msg = 'add_message: negative stamp'
            raise ValueError(msg)
        seq = self.counts[channel] % (1 << 32)
        record = struct.pack('<BQHIQQ', _OP_MESSAGE, RECORD_HEAD - 9 + len(data), channel, seq,
                             stamp, stamp) + bytes(data)
        parts = self._index.setdefault(channel, [])
        if not parts or not isinstance(parts[-1][0], list):
            parts.append(([], []))          # single messages gather in lists
        parts[-1][0].append(stamp)
        parts[-1][1].append(self._size)
        self._blocks.append(record)
        self._size += len(record)
        self._start = stamp if self._start is None else min(self._start, stamp)
        self._end = max(self._end, stamp)
        self.t_min = stamp if self.t_min is None else min(self.t_min, stamp)
        self.t_max = stamp if self.t_max is None else max(self.t_max, stamp)
        self.counts[channel] += 1
        if self._size >= self.chunk_bytes:
            self.close_chunk()

    def _append(self, channel: int, stamps: np.ndarray, records: bytes, size: int) -> None:
        m = stamps.shape[0]
        offsets = self._size + size * np.arange(m, dtype=np.int64)
        self._index.setdefault(channel, []).append((stamps, offsets))
        self._blocks.append(records)
        self._size += len(records)
        lo, hi = int(stamps.min()), int(stamps.max())
        self._start = lo if self._start is None else min(self._start, lo)
        self._end = max(self._end, hi)
        self.t_min = lo if self.t_min is None else min(self.t_min, lo)
        self.t_max = hi if self.t_max is None else max(self.t_max, hi)
        self.counts[channel] += m
        if self._size >= self.chunk_bytes:
            self.close_chunk()

    def close_chunk(self) -> None:
        """Write the open chunk and its message indexes (nothing if it is empty).

        Called when the chunk is full, and by a caller that ends a stretch of time on every
        channel, so that chunks do not overlap in time.
        """
        if not self._blocks:
            return
        data = self._blocks[0] if len(self._blocks) == 1 else b''.join(self._blocks)
        indexes = []
        for channel in sorted(self._index):
            parts = self._index[channel]
            pairs = np.empty((sum(len(p[0]) for p in parts), 2), '<u8')
            pairs[:, 0] = np.concatenate([np.asarray(p[0], np.int64) for p in parts])
            pairs[:, 1] = np.concatenate([np.asarray(p[1], np.int64) for p in parts])
            indexes.append((channel, pairs.tobytes()))
        self._do(self._write_chunk, data, indexes, self._start, self._end)
        self._reset_chunk()

    def _write_chunk(self, data: bytes, indexes: list[tuple[int, bytes]], start: int,
                     end: int) -> None:
        if self._compress is None or self._compression != 'zstd':
            crc = zlib.crc32(data)
        else:
            crc = 0                              # "not computed": see _compressor
        packed = data if self._compress is None else self._compress(data)
        name = self._compression.encode()
        content = 8 + 8 + 8 + 4 + 4 + len(name) + 8 + len(packed)
        chunk_at = self._pos
        self._write(struct.pack('<BQQQQI', _OP_CHUNK, content, start, end, len(data), crc)
                    + struct.pack('<I', len(name)) + name + struct.pack('<Q', len(packed)))
        self._write(packed)
        index_at = self._pos
        offsets: dict[int, int] = {}
        for channel, pairs in indexes:
            offsets[channel] = self._pos
            self._write(struct.pack('<BQHI', _OP_MESSAGE_INDEX, 2 + 4 + len(pairs), channel,
                                    len(pairs)) + pairs)
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=start, message_end_time=end,
            chunk_start_offset=chunk_at, chunk_length=index_at - chunk_at,
            message_index_offsets=offsets, message_index_length=self._pos - index_at,
            compression=self._compression, compressed_size=len(packed),
            uncompressed_size=len(data)))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """Write a metadata record (after the open chunk)."""
        self.close_chunk()
        builder = RecordBuilder()
        Metadata(name=name, metadata=dict(data)).write(builder)
        self._do(self._write_metadata, name, builder.end())

    def _write_metadata(self, name: str, raw: bytes) -> None:
        self._metadata_indexes.append(MetadataIndex(offset=self._pos, length=len(raw),
                                                    name=name))
        self._write(raw)

    # ------------------------------------------------------------------ end
    def finish(self) -> None:
        """Write the last chunk, the summary section and the footer (the file is complete)."""
        self.close_chunk()
        self._framing(DataEnd(data_section_crc=0))
        self._do(self._write_summary)
        self._stop()

    def _write_summary(self) -> None:
        summary_at = self._pos
        builder = RecordBuilder()
        groups = []
        for opcode, records in ((_OP_SCHEMA, self._schemas), (_OP_CHANNEL, self._channels)):
            begin = builder.count
            for record in records:
                record.write(builder)
            groups.append((opcode, begin, builder.count))
        begin = builder.count
        Statistics(message_count=sum(self.counts.values()), schema_count=len(self._schemas),
                   channel_count=len(self._channels), attachment_count=0,
                   metadata_count=len(self._metadata_indexes),
                   chunk_count=len(self._chunk_indexes),
                   message_start_time=self.t_min or 0, message_end_time=self.t_max or 0,
                   channel_message_counts=dict(self.counts)).write(builder)
        groups.append((_OP_STATISTICS, begin, builder.count))
        for opcode, records in ((_OP_CHUNK_INDEX, self._chunk_indexes),
                                (_OP_METADATA_INDEX, self._metadata_indexes)):
            begin = builder.count
            for record in records:
                record.write(builder)
            groups.append((opcode, begin, builder.count))
        offsets_at = summary_at + builder.count
        for opcode, begin, end in groups:
            if end > begin:
                SummaryOffset(group_opcode=opcode, group_start=summary_at + begin,
                              group_length=end - begin).write(builder)
        summary = builder.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(struct.pack('<BQQQ', 0x02, 20, summary_at, offsets_at), crc)
        footer = RecordBuilder()
        Footer(summary_start=summary_at, summary_offset_start=offsets_at,
               summary_crc=crc).write(footer)
        self._write(summary + footer.end() + _MAGIC)
