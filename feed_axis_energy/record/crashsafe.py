"""A rosbag2/MCAP directory that stays readable whenever its writer is killed.

Layout (what :class:`ChunkedBagWriter` guarantees at every moment, SIGKILL included):

* ``metadata.yaml`` exists from the moment the directory does (right after creation it
  lists one MCAP file with every declared topic and no messages) and is only ever replaced
  atomically (written to ``.metadata.yaml.tmp``, then renamed over the old one);
* every ``.mcap`` file it lists is complete and closed (header, chunks, summary, footer and
  end magic): ``rosbags`` needs the footer (an MCAP without one is refused as "File end magic
  is invalid"), and the ``mcap`` library reads each file on its own;
* a flush writes the buffered messages as the next file ``<bag>_<i>.mcap``: first under a
  hidden temporary name, renamed when complete, and only then is the metadata replaced. A
  kill in between leaves a hidden ``.tmp`` file or an unlisted ``.mcap`` that readers ignore;
  the bag reads as of the previous flush.

The files are written by the MCAP core of every bag, :class:`.mcapstream.McapStream`, with the
rosbag2 conventions of :mod:`.bagwrite` (:func:`.bagwrite.declare_topic`,
:func:`.bagwrite.bag_information`, :func:`.bagwrite.create_bag_dir`,
:func:`.bagwrite.replace_metadata`); what is this module's
own is the file discipline above. It cannot be a mode of
:class:`.bagwrite.StreamBagWriter`'s one growing file: ``rosbags`` opens an MCAP only through
its footer and summary, which a file gets when it is finished, so a bag that must read at
every moment needs every listed file finished, hence a new file per flush.

So a kill loses exactly the messages buffered since the last flush; the recorder
(:mod:`feed_axis_energy.nodes.mcap_recorder`) flushes by message count and by wall time, which
bounds that loss (docs/nodes.md). Not covered: power loss or an OS crash (nothing is fsynced;
the page cache survives the death of a process, not of the machine).

Output safety: the bag directory is created by this class and must not exist, not even as a
dangling symlink; its last component is created with ``mkdir`` (which does not follow a
symlink), file names inside it are the writer's own, and files are replaced by rename, which
replaces a link instead of writing through it.
"""
from __future__ import annotations

import os
from pathlib import Path
import shutil
from typing import Mapping

import yaml

from .bagwrite import bag_information, create_bag_dir, declare_topic, replace_metadata
from .mcapstream import McapStream

__all__ = ['ChunkedBagWriter']

_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)


def _indent(text: str) -> str:
    """A YAML block moved two spaces in (an item of the root mapping's mapping)."""
    return ''.join('  ' + line for line in text.splitlines(keepends=True))


class ChunkedBagWriter:
    """A rosbag2 directory (MCAP storage) that stays readable if the writer is killed.

    Messages are buffered; :meth:`flush` writes them as one complete MCAP file and atomically
    replaces ``metadata.yaml`` with one that lists every file (module docstring). The
    directory and its metadata exist from construction on.

    Parameters
    ----------
    path
        Bag directory to create; must not exist (:func:`create_bag_dir`).
    typestore
        rosbags typestore for the message definitions.
    topics
        ``{topic: message type}`` declared from the start (more with :meth:`add_topic`).
    """

    def __init__(self, path: str | Path, *, typestore,
                 topics: Mapping[str, str] | None = None) -> None:
        self.path = create_bag_dir(path)
        self._typestore = typestore
        self._types: dict[str, str] = dict(topics or {})
        self._buffer: list[tuple[str, int, bytes]] = []
        self._files: list[dict] = []
        self._custom: dict[str, str] = {}
        self._path_yaml: list[str] = []
        self._file_yaml: list[str] = []
        self.counts: dict[str, int] = {}
        self.closed = False
        try:
            self._write_file([])   # the first file: connections only
        except BaseException:
            shutil.rmtree(self.path, ignore_errors=True)   # nothing left on failure
            raise

    @property
    def buffered(self) -> int:
        """Messages waiting for the next flush."""
        return len(self._buffer)

    @property
    def topics(self) -> dict[str, str]:
        """``{topic: message type}`` declared so far (a copy)."""
        return dict(self._types)

    @property
    def files(self) -> int:
        """Number of MCAP files written (the first, empty one included)."""
        return len(self._files)

    def add_topic(self, topic: str, msgtype: str) -> None:
        """Declare a topic and its message type (listed in the metadata at once)."""
        if self._types.get(topic) == msgtype:
            return
        self._types[topic] = msgtype
        self._write_metadata()

    def write(self, topic: str, stamp_ns: int, data: bytes) -> None:
        """Buffer one serialized (CDR) message logged at ``stamp_ns``."""
        if topic not in self._types:
            msg = f'topic {topic!r} was not declared with add_topic'
            raise KeyError(msg)
        self._buffer.append((topic, int(stamp_ns), data))

    def set_custom_data(self, key: str, value: str) -> None:
        """Store a string in the bag's metadata (written with the next flush)."""
        self._custom[key] = value

    def flush(self) -> int:
        """Write the buffered messages as the next MCAP file; returns how many were written."""
        if not self._buffer:
            return 0
        buffer, self._buffer = self._buffer, []
        try:
            self._write_file(buffer)
        except BaseException:
            self._buffer = buffer + self._buffer   # kept for a retry (close)
            raise
        for topic, _, _ in buffer:
            self.counts[topic] = self.counts.get(topic, 0) + 1
        return len(buffer)

    def _write_file(self, buffer: list[tuple[str, int, bytes]]) -> None:
        name = f'{self.path.name}_{len(self._files)}.mcap'
        tmp = self.path / f'.{name}.tmp'
        if os.path.lexists(tmp):
            tmp.unlink()
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
            with os.fdopen(fd, 'wb') as fh:
                self._write_mcap(fh, buffer)
            os.replace(tmp, self.path / name)
        finally:
            if os.path.lexists(tmp):
                tmp.unlink()
        stamps = [s for _, s, _ in buffer]
        start = min(stamps) if stamps else 0
        self._files.append({'path': name, 'starting_time': {
            'nanoseconds_since_epoch': start},
            'duration': {'nanoseconds': (max(stamps) - start) if stamps else 0},
            'message_count': len(buffer)})
        self._write_metadata(extra=buffer)

    def _write_mcap(self, fh, buffer: list[tuple[str, int, bytes]]) -> None:
        """One complete MCAP file as rosbag2 writes it (profile ``ros2``, ``ros2msg`` schemas),
        uncompressed, every declared topic a channel: :class:`.mcapstream.McapStream`."""
        mcap = McapStream(fh, compression='none')
        schemas: dict[str, int] = {}
        channels = {topic: declare_topic(mcap, schemas, topic, msgtype, store=self._typestore)
                    for topic, msgtype in sorted(self._types.items())}
        for topic, stamp, data in buffer:
            mcap.add_message(channels[topic], stamp, data)
        mcap.finish()

    def metadata(self, *, extra: list[tuple[str, int, bytes]] = ()) -> dict:
        """The ``metadata.yaml`` content for the files written so far.

        ``extra`` are messages just written but not yet in :attr:`counts`.
        """
        info = self._head(extra)
        info['relative_file_paths'] = [f['path'] for f in self._files]
        info['files'] = list(self._files)
        return {'rosbag2_bagfile_information': info}

    def _head(self, extra: list[tuple[str, int, bytes]]) -> dict:
        """Everything of the metadata but the two per-file lists."""
        counts = dict(self.counts)
        for topic, _, _ in extra:
            counts[topic] = counts.get(topic, 0) + 1
        full = [f for f in self._files if f['message_count']]
        start = min((f['starting_time']['nanoseconds_since_epoch'] for f in full), default=0)
        end = max((f['starting_time']['nanoseconds_since_epoch'] + f['duration']['nanoseconds']
                   for f in full), default=0)
        return bag_information(dict(sorted(self._types.items())), counts, start=start, end=end,
                               custom=self._custom, store=self._typestore)

    def _write_metadata(self, *, extra: list[tuple[str, int, bytes]] = ()) -> None:
        # The per-file lists grow by one entry per flush: each entry is rendered once
        # (cached), so a flush costs the same after 10 files as after 10 000.
        while len(self._file_yaml) < len(self._files):
            f = self._files[len(self._file_yaml)]
            self._path_yaml.append(_indent(yaml.dump([f['path']], Dumper=_DUMPER)))
            self._file_yaml.append(_indent(yaml.dump([f], Dumper=_DUMPER,
                                                     default_flow_style=False)))
        text = ''.join([
            yaml.dump({'rosbag2_bagfile_information': self._head(extra)}, Dumper=_DUMPER,
                      default_flow_style=False),
            '  relative_file_paths:\n', *self._path_yaml, '  files:\n', *self._file_yaml])
        replace_metadata(self.path, text)

    def close(self) -> None:
        """Flush what is left and refresh the metadata (custom data); idempotent."""
        if self.closed:
            return
        if not self.flush():
            self._write_metadata()
        self.closed = True
