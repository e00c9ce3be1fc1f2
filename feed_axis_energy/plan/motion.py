"""Sampled motion of the machine axes: the contract between trajectory and dynamics.

Arrays follow one convention: time is ``(n,)`` float seconds, per-axis quantities are
``(n, k)`` in SI units with columns in the order of ``axes``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ['Motion']


@dataclass(frozen=True)
class Motion:
    """Positions, velocities and accelerations of named axes on a uniform or measured time base.

    Attributes
    ----------
    t
        Sample times [s], strictly increasing, shape ``(n,)``.
    axes
        Axis names, e.g. ``('X', 'Y', 'Z')``.
    pos, vel, acc
        [m], [m/s], [m/s^2], shape ``(n, k)``.
    line
        Source line of every sample (``int32``, 0 where none), shape ``(n,)``.
    source
        Where the motion came from (program file or measured data file).
    gaps
        Standstill samples left out (:mod:`.standstill`): ``(row, first_index, count)``
        means that ``count`` samples of the uniform grid, from grid index ``first_index`` on,
        lie between row ``row - 1`` (the previous chunk's last row when ``row == 0``) and
        row ``row``; both neighbours are at rest at the same position, so every omitted
        sample equals row ``row`` except its time. Empty for a fully sampled motion.
    """

    t: np.ndarray
    axes: tuple[str, ...]
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    line: np.ndarray
    source: str = ''
    gaps: tuple[tuple[int, int, int], ...] = ()

    def __post_init__(self) -> None:
        n = self.t.shape[0]
        k = len(self.axes)
        for name in ('pos', 'vel', 'acc'):
            arr = getattr(self, name)
            if arr.shape != (n, k):
                msg = f'Motion.{name} has shape {arr.shape}, expected ({n}, {k})'
                raise ValueError(msg)
        if self.line.shape != (n,):
            msg = f'Motion.line has shape {self.line.shape}, expected ({n},)'
            raise ValueError(msg)
        for row, _first, count in self.gaps:
            if not (0 <= row < n and count >= 1):
                msg = f'Motion.gaps entry ({row}, {_first}, {count}) outside {n} rows'
                raise ValueError(msg)

    @property
    def n_samples(self) -> int:
        """Number of samples held (rows; see ``gaps`` for samples left out)."""
        return int(self.t.shape[0])

    @property
    def omitted_samples(self) -> int:
        """Number of standstill samples left out (the ``gaps``)."""
        return sum(count for _row, _first, count in self.gaps)

    @property
    def duration_s(self) -> float:
        """Time from first to last sample [s]."""
        return float(self.t[-1] - self.t[0]) if self.n_samples else 0.0

    def select(self, axes: tuple[str, ...]) -> 'Motion':
        """Return the motion of ``axes`` only, in that order (missing axes raise ``KeyError``)."""
        idx = [self.axes.index(a) for a in axes]
        return Motion(t=self.t, axes=tuple(axes), pos=self.pos[:, idx], vel=self.vel[:, idx],
                      acc=self.acc[:, idx], line=self.line, source=self.source,
                      gaps=self.gaps)
