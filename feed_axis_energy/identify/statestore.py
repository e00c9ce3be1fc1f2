"""Each run's simulation of the declared model, held within a memory budget during an analysis.

``analyze`` computes every candidate column, the shape refinement and the alternatives from
one :class:`~feed_axis_energy.effects.EffectState` per run: about a dozen arrays of the
simulation's samples (112 bytes per sample of a one-axis run). Held in memory for 15 runs of
10 minutes at 1 kHz that is 1 GB, and it grows with the runs' length and the simulation
rate. A :class:`StateStore` keeps the states in memory while their total stays within a
budget; the states beyond it are written once to a private temporary directory and read back
memory-mapped (read-only, so nothing can change them) one run at a time, when a column is
computed from them. The result is the same bit for bit: the arrays are stored, not converted.

The directory is made by :func:`tempfile.mkdtemp` (mode 0700, under ``TMPDIR``), each file
is created exclusively and not through a link, and :meth:`StateStore.close` (or leaving the
``with`` block, also on an error) removes it and everything in it. A directory that cannot
be made or filled (no space, no permission) is an :class:`~feed_axis_energy.errors.OutputError`
naming it.
"""
from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ..effects import EffectState
from ..errors import OutputError

__all__ = ['STATE_MEMORY_BYTES', 'StateStore']

STATE_MEMORY_BYTES = 64 * 2 ** 20
"""Default budget [bytes] of the states held in memory; the rest are memory-mapped files."""

_PREFIX = 'fae-states-'
_SPILL_FROM = 4096
"""Arrays smaller than this [bytes] (masses, leads) stay in memory with a spilled state."""


@dataclasses.dataclass(frozen=True)
class _Spilled:
    small: EffectState              # the fields kept in memory; the spilled ones None
    files: dict[str, Path]          # spilled field -> its .npy file


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
        self._dir: Path | None = None

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
        size = _nbytes(state)
        key = len(self._entries)
        if self.held_bytes + size <= self.budget_bytes:
            self._entries.append(state)
            self.held_bytes += size
            return key
        files: dict[str, Path] = {}
        try:
            folder = self._folder()
            for f in dataclasses.fields(state):
                value = getattr(state, f.name)
                if isinstance(value, np.ndarray) and value.nbytes >= _SPILL_FROM:
                    path = folder / f'{key}-{f.name}.npy'
                    _write_new(path, value)
                    files[f.name] = path
        except OSError as err:
            # a full or unwritable temporary directory: the store's files go with close()
            where = self._dir if self._dir is not None else tempfile.gettempdir()
            msg = (f'cannot keep a run\'s simulation ({size / 2 ** 20:.1f} MiB) on disk: '
                   f'{err.strerror or err}; give the analysis more memory '
                   '(analyze --state-memory MIB) or another temporary directory (TMPDIR)')
            raise OutputError(msg, path=where, option='TMPDIR') from err
        blank: dict[str, Any] = {name: None for name in files}
        self._entries.append(_Spilled(dataclasses.replace(state, **blank), files))
        return key

    def get(self, key: int) -> EffectState:
        """The state stored under ``key`` (spilled arrays as read-only memory maps)."""
        entry = self._entries[key]
        if not isinstance(entry, _Spilled):
            return entry
        if self._dir is None:
            raise RuntimeError('the state store is closed')
        return dataclasses.replace(entry.small, **{
            name: np.load(path, mmap_mode='r', allow_pickle=False)
            for name, path in entry.files.items()})

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


def _nbytes(state: EffectState) -> int:
    return sum(int(v.nbytes) for f in dataclasses.fields(state)
               if isinstance(v := getattr(state, f.name), np.ndarray))


def _write_new(path: Path, value: np.ndarray) -> None:
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, 'O_NOFOLLOW', 0)
    fd = os.open(path, flags, 0o600)
    with os.fdopen(fd, 'wb') as fh:
        np.save(fh, value, allow_pickle=False)
