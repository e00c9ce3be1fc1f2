"""Moves kept between two passes over a program: an unnamed temporary file, not memory.

``simulate --out`` (and ``--max-samples``) plans the program once without samples to know
its cost before any output, then simulates it. Reading the G-code a second time costs the
parser and the checks again (about a third of a dense contour's time); holding the parsed
moves costs about 0.55 kB each (a 24-hour contour: about 1 GB). :class:`MoveSpool` instead
writes the moves of the first pass, as they stream by, into an anonymous temporary file
(:func:`tempfile.TemporaryFile`: unlinked at creation, so nothing is left behind whatever
happens) as fixed-size binary records of :data:`RECORD_BYTES` bytes, and gives them back in
the second pass in batches of :data:`BATCH_MOVES`. Memory holds one batch either way.

The moves read back equal the moves written (every field of :class:`~.program.Move`,
floats bit for bit, ``None`` centres and sweeps kept), so the simulation is the same as
from the parser.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
import os

import numpy as np

from .errors import PlanningError
from .program import arc_move, make_move, Move, MoveKind, straight_move

__all__ = ['MoveSpool', 'RECORD_BYTES', 'BATCH_MOVES', 'MOVE_DTYPE']

BATCH_MOVES = 4096
"""Moves written or read at a time (memory: one batch of records and of moves)."""

# flags: which optional fields hold a value, and the two booleans
_EXACT, _TAP, _CENTRE, _SWEEP = 1, 2, 4, 8

MOVE_DTYPE = np.dtype([('kind', 'u1'), ('flags', 'u1'), ('plane', 'i2'), ('turns', 'i8'),
                       ('line', 'i8'), ('start', 'f8', 3), ('end', 'f8', 3),
                       ('center', 'f8', 3), ('feed', 'f8'), ('dwell', 'f8'),
                       ('length', 'f8'), ('sweep', 'f8')])
"""One move on disk (``center``/``sweep`` are 0 where the move has none: see ``flags``)."""
RECORD_BYTES = MOVE_DTYPE.itemsize
"""Bytes per spooled move (124)."""

_KINDS = tuple(MoveKind)
_STRAIGHT = (int(MoveKind.RAPID), int(MoveKind.LINEAR))
_ARCS = (int(MoveKind.ARC_CW), int(MoveKind.ARC_CCW))
_NO_CENTRE = (0.0, 0.0, 0.0)


class MoveSpool:
    """Moves written once while they stream by, read back any number of times.

    Parameters
    ----------
    file
        The program's name: ``file`` of the moves read back, and of error messages.

    Notes
    -----
    Use :meth:`record` around the first pass (it yields the moves unchanged), then iterate
    the spool itself. :meth:`close` (or ``with``) frees the temporary file; it is removed by
    the operating system in any case when the process ends.
    """

    def __init__(self, *, file: str = '') -> None:
        self.file = file
        self.count = 0
        self._fh = None
        self._complete = False

    def __enter__(self) -> MoveSpool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Free the temporary file."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def record(self, moves: Iterable[Move]) -> Iterator[Move]:
        """Yield ``moves`` unchanged, writing them to the spool in batches.

        The spool can be read once this generator has run to its end.

        Raises
        ------
        PlanningError
            The temporary file cannot be created or written (e.g. the disk is full).
        """
        import tempfile
        if self._fh is not None or self._complete:
            raise RuntimeError('MoveSpool.record: the spool has been written already')
        try:
            self._fh = tempfile.TemporaryFile(prefix='fae-moves-')
        except OSError as err:
            raise self._error('cannot create the temporary file for the moves', err) from err
        batch: list[Move] = []
        for mv in moves:
            batch.append(mv)
            if len(batch) >= BATCH_MOVES:
                self._write(batch)
                batch = []
            yield mv
        if batch:
            self._write(batch)
        self._complete = True

    def _write(self, batch: list[Move]) -> None:
        rows = [(int(m.kind),
                 (_EXACT if m.exact_stop else 0) | (_TAP if m.tap_return else 0)
                 | (0 if m.center is None else _CENTRE) | (0 if m.sweep_rad is None else _SWEEP),
                 m.plane, m.turns, m.line, m.start, m.end,
                 _NO_CENTRE if m.center is None else m.center, m.feed_m_s, m.dwell_s,
                 m.length_m, 0.0 if m.sweep_rad is None else m.sweep_rad) for m in batch]
        data = np.array(rows, dtype=MOVE_DTYPE)
        try:
            self._fh.write(data.tobytes())
        except OSError as err:
            raise self._error('cannot write the moves to a temporary file', err) from err
        self.count += len(batch)

    def _error(self, what: str, err: OSError) -> PlanningError:
        import tempfile
        reason = err.strerror or type(err).__name__
        where = tempfile.gettempdir()
        msg = (f'{what} in {where} ({reason}); the first pass of --out/--max-samples keeps '
               f'the program\'s moves there ({RECORD_BYTES} bytes per move; TMPDIR chooses '
               'the directory)')
        return PlanningError(msg, file=self.file)

    def __iter__(self) -> Iterator[Move]:
        """The recorded moves, in order, rebuilt batch by batch."""
        if not self._complete or self._fh is None:
            raise RuntimeError('MoveSpool: iterate only after record() has run to its end')
        fh = self._fh
        fh.seek(0, os.SEEK_SET)
        left = self.count
        while left > 0:
            n = min(left, BATCH_MOVES)
            buf = fh.read(n * RECORD_BYTES)
            if len(buf) != n * RECORD_BYTES:
                msg = 'the temporary file of the moves was cut short'
                raise PlanningError(msg, file=self.file)
            left -= n
            yield from _moves(np.frombuffer(buf, dtype=MOVE_DTYPE))


def _moves(data: np.ndarray) -> Iterator[Move]:
    """Moves of a block of records (the fields as Python values, as the parser makes them)."""
    kind = data['kind']
    flags = data['flags']
    dwell = data['dwell']
    # the usual moves take the positional builders; the rest (dwells, stops, taps, helices,
    # other planes, a -0.0 anywhere it is not the default) the general one
    usual = ((flags & (_TAP | _CENTRE | _SWEEP)) == 0) & (data['plane'] == 17) \
        & (data['turns'] == 0) & (dwell == 0.0) & ~np.signbit(dwell)
    straight = usual & ((kind == _STRAIGHT[0]) | (kind == _STRAIGHT[1]))
    arc = ((kind == _ARCS[0]) | (kind == _ARCS[1])) & ((flags & _TAP) == 0) \
        & ((flags & (_CENTRE | _SWEEP)) == (_CENTRE | _SWEEP)) & (dwell == 0.0) \
        & ~np.signbit(dwell)
    way = (straight.astype(np.int8) + 2 * arc.astype(np.int8)).tolist()
    kinds = kind.tolist()
    flag = flags.tolist()
    planes = data['plane'].tolist()
    turns = data['turns'].tolist()
    lines = data['line'].tolist()
    starts = data['start'].tolist()
    ends = data['end'].tolist()
    centres = data['center'].tolist()
    feeds = data['feed'].tolist()
    dwells = dwell.tolist()
    lengths = data['length'].tolist()
    sweeps = data['sweep'].tolist()
    build = straight_move
    for i, w in enumerate(way):
        if w == 1:
            yield build(_KINDS[kinds[i]], lines[i], tuple(starts[i]), tuple(ends[i]),
                        feeds[i], flag[i] == _EXACT, lengths[i])
            continue
        f = flag[i]
        if w == 2:
            yield arc_move(_KINDS[kinds[i]], lines[i], tuple(starts[i]), tuple(ends[i]),
                           feeds[i], bool(f & _EXACT), tuple(centres[i]), planes[i],
                           turns[i], lengths[i], sweeps[i])
        else:
            yield make_move(_KINDS[kinds[i]], lines[i], tuple(starts[i]), tuple(ends[i]),
                            feed_m_s=feeds[i], exact_stop=bool(f & _EXACT),
                            center=tuple(centres[i]) if f & _CENTRE else None,
                            plane=planes[i], turns=turns[i], dwell_s=dwells[i],
                            length_m=lengths[i],
                            sweep_rad=sweeps[i] if f & _SWEEP else None,
                            tap_return=bool(f & _TAP))
