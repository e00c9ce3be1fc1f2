"""Each run's simulation of the declared model, held within a memory budget during an analysis.

``analyze`` computes every candidate column, the shape refinement and the alternatives from
one :class:`~feed_axis_energy.effects.EffectState` per run: about a dozen arrays of the
simulation's samples (112 bytes per sample of a one-axis run). Held in memory for 15 runs of
10 minutes at 1 kHz that is 1 GB, and it grows with the runs' length and the simulation
rate. A :class:`StateStore` keeps the states in memory while their total stays within a
budget; the states beyond it are written once to a private temporary directory and read back
memory-mapped (read-only, so nothing can change them) one run at a time, when a column is
computed from them. The result is the same bit for bit: the arrays are stored, not converted.
A state may also arrive in pieces (:meth:`StateStore.writer`, one simulated chunk after the
other): pieces are kept in memory while the budget allows and, from the first piece that
would exceed it, every piece is appended to the state's files, so a long run's simulation is
never whole in memory. :meth:`StateStore.hold` does the same for any array read many times
and never changed (a measured record, a comparison's simulated power): itself within the
budget, else a read-only memory map of a copy whose file is removed as soon as it is mapped
(the map keeps the data until its last view goes; nothing is left behind, even on a crash);
:meth:`StateStore.drop_pages` lets the pages of those maps leave the process's memory between
two passes over the runs (the kernel reads them again when they are next used).
``analyze`` holds its measured data the same way, for the whole analysis: each run's record
(:func:`held_record`, the loaded runs as a :class:`HeldRecords` mapping whose every lookup
drops the pages first, so a pass over the runs keeps about one run's mapped data resident)
and the comparisons it keeps across a round (:func:`held_comparison`, :func:`held_runs`,
:func:`held_run`).

The directory is made by :func:`tempfile.mkdtemp` (mode 0700, under ``TMPDIR``), each file
is created exclusively and not through a link, and :meth:`StateStore.close` (or leaving the
``with`` block, also on an error) removes it and everything in it. A directory that cannot
be made or filled (no space, no permission) is an :class:`~feed_axis_energy.errors.OutputError`
naming it.
"""
from __future__ import annotations

import dataclasses
import mmap
import os
import shutil
import tempfile
from pathlib import Path
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, BinaryIO
import weakref

import numpy as np

from ...effects import EffectState
from ...errors import OutputError
from ...measured import CampaignComparison, MeasuredRun, RunComparison

__all__ = ['HeldRecords', 'STATE_MEMORY_BYTES', 'StateStore', 'StateWriter', 'held_comparison',
           'held_record', 'held_run', 'held_runs']

STATE_MEMORY_BYTES = 64 * 2 ** 20
"""Default budget [bytes] of the states held in memory; the rest are memory-mapped files."""

_PREFIX = 'fae-states-'
SAMPLE_FIELDS = EffectState.SAMPLE_FIELDS
"""The fields a state's pieces are joined along and a spilled state keeps on disk (the rest,
masses and leads per axis, stay in memory): :attr:`EffectState.SAMPLE_FIELDS`."""


@dataclasses.dataclass(frozen=True)
class _File:
    path: Path
    dtype: np.dtype
    shape: tuple[int, ...]


@dataclasses.dataclass(frozen=True)
class _Spilled:
    small: EffectState              # the fields kept in memory; the spilled ones None
    files: dict[str, _File]         # spilled field -> its raw file


class StateStore:
    """Per-run :class:`EffectState` objects within a memory budget.

    Parameters
    ----------
    budget_bytes
        Total size [bytes] of the states kept in memory; a state that would exceed it is
        written to the store's temporary directory instead. ``0`` spills every state.
    """

    def __init__(self, budget_bytes: int = STATE_MEMORY_BYTES) -> None:
        if budget_bytes < 0:
            raise ValueError(f'budget_bytes must be >= 0, got {budget_bytes}')
        self.budget_bytes = int(budget_bytes)
        self.held_bytes = 0
        # per key: the state itself, or a spilled one as (its small fields, its files)
        self._entries: list[EffectState | _Spilled] = []
        self._serial = 0                    # writers made, for unique file names
        self._dir: Path | None = None
        # arrays hold() kept in memory, by id while they live (counted once in held_bytes)
        self._kept: weakref.WeakValueDictionary[int, np.ndarray] = weakref.WeakValueDictionary()
        self._maps: list[weakref.ref[mmap.mmap]] = []     # the maps hold() made, while alive

    def __enter__(self) -> StateStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def spilled(self) -> int:
        """How many states are on disk."""
        return sum(isinstance(e, _Spilled) for e in self._entries)

    def put(self, state: EffectState) -> int:
        """Keep ``state``; returns its key for :meth:`get`."""
        writer = self.writer()
        writer.add(state)
        return writer.finish()

    def hold(self, array: np.ndarray) -> np.ndarray:
        """``array`` itself while the budget allows, else a read-only memory map of a copy on
        disk (a measured record, a comparison's columns: data read many times, never
        changed). The copy's file is removed as soon as it is mapped: the map keeps the data
        until the last view of it goes, and nothing is left behind. A memory map is returned
        as it is (no second copy)."""
        size = int(array.nbytes)
        if _map_of(array) is not None:
            return array                    # a map (or a view of one): no second copy
        if self._kept.get(id(array)) is array:
            return array                    # held before: counted once
        if array.dtype.hasobject:
            return array                    # references, not data: nothing to map
        if self.held_bytes + size <= self.budget_bytes or size == 0:
            self.held_bytes += size
            self._kept[id(array)] = array
            return array
        serial, self._serial = self._serial, self._serial + 1
        try:
            path = self._folder() / f'{serial}-held.raw'
            try:
                with _open_new(path) as fh:
                    fh.write(np.ascontiguousarray(array).data)
                fd = os.open(path, os.O_RDONLY | getattr(os, 'O_NOFOLLOW', 0))
                try:
                    mm = mmap.mmap(fd, size, access=mmap.ACCESS_READ)
                finally:
                    os.close(fd)
            finally:
                path.unlink(missing_ok=True)
        except OSError as err:
            msg = (f'cannot keep a run\'s data on disk: {err.strerror or err}; give the '
                   'analysis more memory (analyze --state-memory MIB) or another temporary '
                   'directory (TMPDIR)')
            raise OutputError(msg, path=self._dir or tempfile.gettempdir(),
                              option='TMPDIR') from err
        self._maps = [m for m in self._maps if m() is not None]
        self._maps.append(weakref.ref(mm))
        return np.frombuffer(mm, dtype=array.dtype, count=array.size).reshape(array.shape)

    def drop_pages(self) -> None:
        """Let the pages of every map :meth:`hold` made leave this process's memory
        (``madvise(MADV_DONTNEED)``): they are read again from the page cache or the disk
        when next used. The data stay the same; what the process holds in RAM between two
        passes over the runs is what the next pass touches, not everything read before."""
        advice = getattr(mmap, 'MADV_DONTNEED', None)
        if advice is None:
            return
        for ref in self._maps:
            mm = ref()
            if mm is not None and not mm.closed:
                mm.madvise(advice)

    def writer(self) -> StateWriter:
        """A :class:`StateWriter` that takes one state in pieces; its ``finish`` gives the key."""
        return StateWriter(self)

    def get(self, key: int) -> EffectState:
        """The state stored under ``key`` (spilled arrays as read-only memory maps)."""
        entry = self._entries[key]
        if not isinstance(entry, _Spilled):
            return entry
        if self._dir is None:
            raise RuntimeError('the state store is closed')
        mapped: dict[str, Any] = {name: _mapped(f) for name, f in entry.files.items()}
        return dataclasses.replace(entry.small, **mapped)

    def close(self) -> None:
        """Forget every state and remove the temporary directory."""
        self._entries.clear()
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    def _folder(self) -> Path:
        if self._dir is None:
            self._dir = Path(tempfile.mkdtemp(prefix=_PREFIX))
        return self._dir


class StateWriter:
    """One run's state, taken in pieces along the samples (:meth:`StateStore.writer`).

    The pieces must come in order, with the same axes and per-axis fields (the same run).
    They are kept in memory while the store's held states and these pieces together stay
    within the budget, and joined by :meth:`finish`; from the first piece that would exceed
    it, the pieces so far and every later one are appended to the state's files.
    """

    def __init__(self, store: StateStore) -> None:
        self._store = store
        self._serial = store._serial        # names the files (keys are given by finish)
        store._serial += 1
        self._small: EffectState | None = None     # the first piece's per-axis fields
        self._like: dict[str, tuple[np.dtype, tuple[int, ...]]] = {}     # per field
        self._pieces: list[EffectState] = []       # held while the budget allows
        self._bytes = 0
        self._files: dict[str, tuple[BinaryIO, _File]] | None = None
        self._rows = 0
        self._done = False

    def add(self, piece: EffectState) -> None:
        """Append the samples of ``piece``."""
        if self._done:
            raise RuntimeError('the state is finished')
        rows = {name: getattr(piece, name) for name in SAMPLE_FIELDS}
        if self._small is None:
            blank: dict[str, Any] = {name: None for name in SAMPLE_FIELDS}
            self._small = dataclasses.replace(piece, **blank)
            self._like = {name: (value.dtype, value.shape[1:]) for name, value in rows.items()}
        for name, value in rows.items():
            dtype, tail = self._like[name]
            if value.dtype != dtype or value.shape[1:] != tail:
                raise ValueError(f'a piece\'s {name} is {value.dtype} {value.shape}, the '
                                 f'state\'s {dtype} (n,) + {tail}')
        size = sum(int(a.nbytes) for a in rows.values())
        self._rows += int(piece.t.shape[0])
        store = self._store
        if (self._files is None
                and store.held_bytes + self._bytes + size <= store.budget_bytes):
            self._pieces.append(piece)
            self._bytes += size
            return
        try:
            if self._files is None:
                self._files = self._open(rows)
                for kept in self._pieces:
                    self._append(kept)
                self._pieces.clear()
            self._append(piece)
        except OSError as err:
            raise self._failed(err) from err

    def finish(self) -> int:
        """End the state; returns its key for :meth:`StateStore.get`."""
        if self._small is None:
            raise ValueError('a state needs at least one piece')
        if self._done:
            raise RuntimeError('the state is finished')
        self._done = True
        store = self._store
        if self._files is None:
            # one piece is the state as it came (no copy); more are joined
            store._entries.append(EffectState.joined(self._pieces))
            self._pieces.clear()
            store.held_bytes += self._bytes
            return len(store._entries) - 1
        files = {name: dataclasses.replace(f, shape=(self._rows,) + f.shape[1:])
                 for name, (_, f) in self._files.items()}
        try:
            self._close_files()
        except OSError as err:
            raise self._failed(err) from err
        store._entries.append(_Spilled(self._small, files))
        return len(store._entries) - 1

    def _failed(self, err: OSError) -> OutputError:
        """The error of a full or unwritable temporary directory; the writer is finished
        and its files go with the store's :meth:`~StateStore.close`."""
        self._done = True
        try:
            self._close_files()
        except OSError:
            pass
        store = self._store
        where = store._dir if store._dir is not None else tempfile.gettempdir()
        msg = (f'cannot keep a run\'s simulation on disk: {err.strerror or err}; give the '
               'analysis more memory (analyze --state-memory MIB) or another temporary '
               'directory (TMPDIR)')
        return OutputError(msg, path=where, option='TMPDIR')

    def _open(self, rows: dict[str, np.ndarray]) -> dict[str, tuple[BinaryIO, _File]]:
        folder = self._store._folder()
        out: dict[str, tuple[BinaryIO, _File]] = {}
        try:
            for name, value in rows.items():
                path = folder / f'{self._serial}-{name}.raw'
                out[name] = (_open_new(path), _File(path, value.dtype, value.shape))
        except OSError:
            for fh, _ in out.values():
                fh.close()
            raise
        return out

    def _append(self, piece: EffectState) -> None:
        assert self._files is not None
        for name, (fh, _) in self._files.items():
            value = getattr(piece, name)
            if value.size:
                fh.write(np.ascontiguousarray(value).data)

    def _close_files(self) -> None:
        files, self._files = self._files, None
        if files is not None:
            errors = []
            for fh, _ in files.values():
                try:
                    fh.close()
                except OSError as err:
                    errors.append(err)
            if errors:
                raise errors[0]


def _mapped(f: _File) -> np.ndarray:
    if 0 in f.shape:
        empty = np.empty(f.shape, dtype=f.dtype)     # nothing to map
        empty.flags.writeable = False
        return empty
    return np.memmap(f.path, dtype=f.dtype, mode='r', shape=f.shape)


def _open_new(path: Path) -> BinaryIO:
    """``path`` created for writing: exclusively (never an existing file), not through a
    link, readable by the owner only."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, 'O_NOFOLLOW', 0)
    return os.fdopen(os.open(path, flags, 0o600), 'wb')


def _map_of(array: np.ndarray) -> mmap.mmap | None:
    """The memory map ``array`` is a view of (:meth:`StateStore.hold`'s), if any."""
    base: Any = array
    while base is not None:
        if isinstance(base, mmap.mmap):
            return base
        base = base.obj if isinstance(base, memoryview) else getattr(base, 'base', None)
    return None


class HeldRecords(Mapping[str, MeasuredRun]):
    """The loaded runs by name. Each lookup first lets the pages of the store's maps go
    (:meth:`StateStore.drop_pages`): a pass over the runs (a comparison of each,
    the preparation of each) keeps about one run's mapped data in memory, not every run's
    read so far."""

    def __init__(self, runs: dict[str, MeasuredRun], store: StateStore) -> None:
        self._runs = runs
        self._store = store

    def __getitem__(self, name: str) -> MeasuredRun:
        self._store.drop_pages()
        return self._runs[name]

    def __contains__(self, name: object) -> bool:
        return name in self._runs

    def __iter__(self) -> Iterator[str]:
        return iter(self._runs)

    def __len__(self) -> int:
        return len(self._runs)


_RECORD_FIELDS = ('t', 'power_w', 'position_m', 'velocity_m_s', 'acceleration_m_s2',
                  'command_position_m', 'command_velocity_m_s', 'command_acceleration_m_s2')
"""The sample arrays of a :class:`~feed_axis_energy.measured.MeasuredRun` that are held."""


def held_record(run: MeasuredRun, store: StateStore) -> MeasuredRun:
    """``run`` with its sample arrays held by ``store`` (in memory or memory-mapped)."""
    arrays: dict[str, Any] = {
        name: store.hold(value) for name in _RECORD_FIELDS
        if isinstance(value := getattr(run, name), np.ndarray)}
    extra = {key: _held_extra(value, store) for key, value in run.extra.items()}
    return dataclasses.replace(run, extra=extra, **arrays)


def _held_extra(value: Any, store: StateStore) -> Any:
    """A record's ``extra`` entry held by ``store``: an array (the file rows), or a dict of
    arrays per axis (currents, torques); anything else as it is."""
    if isinstance(value, np.ndarray):
        return store.hold(value)
    if (isinstance(value, dict) and value
            and all(isinstance(v, np.ndarray) for v in value.values())):
        return {axis: store.hold(v) for axis, v in value.items()}
    return value


def held_comparison(cmp: CampaignComparison, store: StateStore) -> CampaignComparison:
    """``cmp`` with its runs' sample arrays held by ``store`` (:func:`held_runs`)."""
    return dataclasses.replace(cmp, runs=tuple(held_runs(cmp.runs, store)))


def held_runs(runs: Sequence[RunComparison], store: StateStore) -> list[RunComparison]:
    """``runs``, each with its sample arrays held by ``store`` (:func:`held_run`)."""
    return [held_run(r, store) for r in runs]


def held_run(run: RunComparison, store: StateStore) -> RunComparison:
    """``run`` with its sample arrays held by ``store`` (an array two fields share, the
    measured power of a power trace, held once)."""
    memo: dict[int, np.ndarray] = {}

    def hold(a: np.ndarray) -> np.ndarray:
        if id(a) not in memo:
            memo[id(a)] = store.hold(a)
        return memo[id(a)]

    return dataclasses.replace(
        run, t=hold(run.t), power_meas_w=hold(run.power_meas_w),
        power_sim_w=hold(run.power_sim_w),
        signal_meas=None if run.signal_meas is None else hold(run.signal_meas),
        signal_sim=None if run.signal_sim is None else hold(run.signal_sim))
