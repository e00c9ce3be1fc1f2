"""The rosbag2 writer: a bag directory with one MCAP file, written block by block.

:class:`StreamBagWriter` is the one writer of whole recordings (simulations, imported
measured runs, rig bags, test bags): it writes what ``rosbags``' own ``Writer`` writes - the
same topics, CDR bytes, ``metadata.yaml`` keys and custom data, read back by the same readers
(``test/record/test_bagwrite.py`` compares them) - but takes series as :class:`.cdr.MessageRows`
blocks, so that a chunk of samples becomes one numpy array of message records
(:mod:`.mcapstream`) instead of a Python call per message. Single messages
(:meth:`StreamBagWriter.write_message`, :meth:`StreamBagWriter.write_raw`) and whole series
(:meth:`StreamBagWriter.write_series`) go through the same blocks.

The rosbag2 conventions of a bag live here once, for this writer and for the crash-safe one
of the node graph (:class:`.crashsafe.ChunkedBagWriter`, which writes its files with the same
:class:`.mcapstream.McapStream`): the bag directory (:func:`create_bag_dir`), a topic as an
MCAP schema and channel (:func:`declare_topic`) and the ``metadata.yaml`` mapping
(:func:`bag_information`).

Output safety: the directory must not exist (not even as a dangling link) and is created by
this class; the MCAP file is opened with ``O_EXCL | O_NOFOLLOW``; ``metadata.yaml`` is
written last, through a temporary name, when the MCAP file is complete. On an exception
inside the ``with`` block the directory is removed: a failed write leaves nothing.
"""
from __future__ import annotations

from functools import lru_cache
import json
import os
from pathlib import Path
import shutil
from typing import Mapping, Sequence

import numpy as np
import yaml

from .cdr import block_energy_cdr, joint_trajectory_rows, MessageRows
from .bagio import DIAGNOSTIC_ARRAY, JOINT_TRAJECTORY, Series, TOPIC_BLOCK_ENERGY, typestore
from .qos import qos_yaml, topic_qos
from .mcapstream import CHUNK_BYTES, McapStream, RECORD_HEAD

__all__ = ['StreamBagWriter', 'create_bag_dir', 'declare_topic', 'bag_information',
           'replace_metadata']

_NS = 1_000_000_000
_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)


def create_bag_dir(path: str | Path) -> Path:
    """Create the bag directory ``path``; refuse anything that exists there, links included.

    Missing parent directories are created. Raises ``FileExistsError`` (an ``OSError``) when
    ``path`` exists or is a symlink (even a dangling one), and ``OSError`` for the rest.
    """
    path = Path(path)
    if os.path.lexists(path):
        kind = 'a symlink' if path.is_symlink() else 'exists already'
        msg = f'{path}: {kind}; choose a new output directory (nothing is overwritten)'
        raise FileExistsError(msg)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.mkdir(path)   # atomic; fails on anything that appeared meanwhile, links included
    except FileExistsError as err:
        msg = f'{path}: exists already; choose a new output directory (nothing is overwritten)'
        raise FileExistsError(msg) from err
    return path


@lru_cache(maxsize=64)
def _msgdef(store, msgtype: str) -> bytes:
    return store.generate_msgdef(msgtype, ros_version=2)[0].encode()


def declare_topic(mcap: McapStream, schemas: dict[str, int], topic: str, msgtype: str, *,
                  store=None) -> int:
    """Declare ``topic`` on ``mcap`` as rosbag2 does; return its channel id.

    A ``ros2msg`` schema per message type (its id kept in ``schemas``, added on first use)
    and a ``cdr`` channel whose metadata holds the topic's offered QoS profiles
    (:func:`.qos.topic_qos`). ``store``: the rosbags typestore of the message definitions
    (default :func:`.bagio.typestore`).
    """
    if msgtype not in schemas:
        schemas[msgtype] = mcap.add_schema(msgtype, 'ros2msg',
                                           _msgdef(store or typestore(), msgtype))
    return mcap.add_channel(topic, schema_id=schemas[msgtype],
                            metadata={'offered_qos_profiles': qos_yaml(topic_qos(topic))})


def bag_information(types: Mapping[str, str], counts: Mapping[str, int], *, start: int,
                    end: int, custom: Mapping[str, str], store=None) -> dict:
    """``rosbag2_bagfile_information`` (version 9, MCAP storage) but the two file lists.

    ``types`` ``{topic: message type}`` in the order listed, ``counts`` messages per topic,
    ``start`` and ``end`` the first and last log time [ns], ``custom`` the ``custom_data``
    strings. The caller adds ``relative_file_paths`` and ``files``.
    """
    store = store or typestore()
    topics = [{'topic_metadata': {
        'name': topic, 'type': msgtype, 'serialization_format': 'cdr',
        'offered_qos_profiles': topic_qos(topic),
        'type_description_hash': store.hash_rihs01(msgtype)},
        'message_count': counts.get(topic, 0)} for topic, msgtype in types.items()]
    return {
        'version': 9, 'storage_identifier': 'mcap',
        'duration': {'nanoseconds': max(0, end - start)},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': sum(counts.get(topic, 0) for topic in types),
        'topics_with_message_count': topics,
        'compression_format': '', 'compression_mode': '',
        'custom_data': dict(custom) or None, 'ros_distro': 'rosbags'}


def replace_metadata(path: Path, text: str) -> None:
    """Write ``metadata.yaml`` of the bag directory ``path`` atomically.

    The text goes to ``.metadata.yaml.tmp`` (a stale one, left by a killed writer, is removed
    first; created exclusively, never through a link) and is renamed over ``metadata.yaml``,
    so a reader sees the old or the new file, never a part.
    """
    tmp = path / '.metadata.yaml.tmp'
    if os.path.lexists(tmp):
        tmp.unlink()
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
    with os.fdopen(fd, 'w', encoding='utf-8') as fh:
        fh.write(text)
    os.replace(tmp, path / 'metadata.yaml')


class StreamBagWriter:
    """Write a rosbag2 directory with one MCAP file, block by block (context manager).

    Parameters
    ----------
    path
        Bag directory to create; it must not exist.
    compression
        MCAP chunk compression: ``'none'`` (default), ``'zstd'`` (about 8x smaller for
        simulated series) or ``'lz4'``.
    chunk_bytes
        Uncompressed size at which a chunk is closed.
    background
        Compress and write in a second thread (:class:`.mcapstream.McapStream`).
    """

    def __init__(self, path: str | Path, *, compression: str = 'none',
                 chunk_bytes: int = CHUNK_BYTES, background: bool = False) -> None:
        self.path = Path(path)
        self.compression = compression
        self.chunk_bytes = int(chunk_bytes)
        self.background = bool(background)
        self._types: dict[str, str] = {}
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._custom: dict[str, str] = {}
        self._fh = None
        self._mcap: McapStream | None = None

    def __enter__(self) -> 'StreamBagWriter':
        create_bag_dir(self.path)
        try:
            name = self.path / f'{self.path.name}.mcap'
            fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
            self._fh = os.fdopen(fd, 'wb', buffering=1 << 20)
            self._mcap = McapStream(self._fh, compression=self.compression,
                                    chunk_bytes=self.chunk_bytes, background=self.background)
        except BaseException:
            self._discard()
            raise
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self._discard()
            return
        try:
            self._close()
        except BaseException:
            self._discard()
            raise

    def _discard(self) -> None:
        if self._mcap is not None:
            self._mcap.abort()                  # the writer thread stops before the removal
        if self._fh is not None:
            try:
                self._fh.close()
            except OSError:
                pass
            self._fh = None
        shutil.rmtree(self.path, ignore_errors=True)

    def channel(self, topic: str, msgtype: str) -> int:
        """The MCAP channel of ``topic`` (declared on first use)."""
        known = self._types.get(topic)
        if known is not None:
            if known != msgtype:
                msg = f'topic {topic} has type {known}, not {msgtype}'
                raise ValueError(msg)
            return self._channels[topic]
        self._types[topic] = msgtype
        self._channels[topic] = declare_topic(self._mcap, self._schemas, topic, msgtype)
        return self._channels[topic]

    def close_chunk(self) -> None:
        """End the open MCAP chunk (see :meth:`.mcapstream.McapStream.close_chunk`)."""
        self._mcap.close_chunk()

    @property
    def lead(self) -> int:
        """Spare bytes that :meth:`write_rows` needs before each message in its rows."""
        return RECORD_HEAD

    def write_rows(self, topic: str, block: MessageRows, *,
                   msgtype: str = JOINT_TRAJECTORY) -> int:
        """Write a block of same-sized messages (built with ``lead=self.lead``); return count."""
        channel = self.channel(topic, msgtype)
        self._mcap.add_block(channel, block.stamps, block.rows, start=block.start,
                             length=block.length)
        return int(block.rows.shape[0])

    def write_raw(self, topic: str, msgtype: str, stamp_ns: int, data: bytes) -> None:
        """Write one serialised (CDR) message at ``stamp_ns``."""
        self._mcap.add_message(self.channel(topic, msgtype), stamp_ns, data)

    def write_message(self, topic: str, msgtype: str, stamp_ns: int, message) -> None:
        """Serialise one rosbags message object and write it at ``stamp_ns``."""
        self.write_raw(topic, msgtype, stamp_ns, typestore().serialize_cdr(message, msgtype))

    def write_series(self, topic: str, series: Series, *, batch: int = 100) -> int:
        """Write a series as JointTrajectory messages of ``batch`` points; return the count.

        The messages equal :func:`.bagio.series_to_messages`' (the last may be shorter).
        """
        t_ns = series.stamps_ns()           # the series' start (t0_ns) kept
        if np.any(t_ns < 0):
            msg = 'bag time series must not have negative times'
            raise ValueError(msg)
        self.channel(topic, JOINT_TRAJECTORY)  # listed even without messages
        values = [series.positions, series.velocities, series.accelerations, series.effort]
        n = int(t_ns.shape[0])
        full = (n // batch) * batch
        count = 0
        for lo, hi, points in ((0, full, batch), (full, n, n - full)):
            if hi > lo:
                block = joint_trajectory_rows(
                    t_ns[lo:hi], tuple(series.names),
                    [None if v is None else v[lo:hi] for v in values], points=points,
                    lead=self.lead)
                count += self.write_rows(topic, block)
        return count

    def write_block_energy(self, blocks: Sequence[tuple[int, float, float]], *,
                           stamp_s: float = 0.0, stamp_ns: int | None = None,
                           program: str = '') -> None:
        """Write the per-block energy (:func:`.cdr.block_energy_cdr`) at ``stamp_ns``
        (or ``stamp_s``)."""
        self.channel(TOPIC_BLOCK_ENERGY, DIAGNOSTIC_ARRAY)   # listed even without messages
        for stamp, data in block_energy_cdr(blocks, stamp_s=stamp_s, stamp_ns=stamp_ns,
                                            program=program):
            self.write_raw(TOPIC_BLOCK_ENERGY, DIAGNOSTIC_ARRAY, stamp, bytes(data))

    def set_custom_data(self, key: str, value: object) -> None:
        """Store a JSON-serialisable value in the bag's metadata (``custom_data``)."""
        self._custom[key] = json.dumps(value)

    def metadata(self) -> dict:
        """The ``metadata.yaml`` mapping (rosbag2 version 9) of what was written."""
        mcap = self._mcap
        start = mcap.t_min or 0
        end = mcap.t_max or 0
        counts = {topic: mcap.counts[channel] for topic, channel in self._channels.items()}
        info = bag_information(self._types, counts, start=start, end=end, custom=self._custom)
        name = f'{self.path.name}.mcap'
        info['relative_file_paths'] = [name]
        info['files'] = [{'path': name, 'starting_time': {'nanoseconds_since_epoch': start},
                          'duration': {'nanoseconds': end - start},
                          'message_count': info['message_count']}]
        return {'rosbag2_bagfile_information': info}

    def _close(self) -> None:
        text = yaml.dump(self.metadata(), Dumper=_DUMPER, default_flow_style=False)
        self._mcap.add_metadata('rosbag2', {'serialized_metadata': text})
        self._mcap.finish()
        self._fh.close()
        self._fh = None
        replace_metadata(self.path, text)
