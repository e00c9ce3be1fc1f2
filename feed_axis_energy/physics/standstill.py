"""The force an axis holds at standstill after it stops: friction kept by the position loop.

While a feed axis moves, its motor works against the friction force of the direction of
motion. When it stops, static friction can hold any force up to the breakaway force, and the
position loop's integrator keeps the force it was applying: the motor goes on pushing in the
last direction of motion until the axis moves again. A drive trace in current, torque or
force shows it as a step at every stop whose sign is the direction just left (on the KIT DMC
60H air cut the anchor's residual at rest, 0.35 A RMS on X, is mostly this). Power does not
see it (``omega = 0`` at rest), so it matters only for those quantities.

Physical form: ``F_hold(t) = h · d_last(t)`` while ``|v| <= v_rest``, 0 while moving, with
``d_last`` the sign of the last velocity beyond ``v_rest`` (0 before the first move) and ``h``
in ``[0, F_breakaway]``: a held force can never exceed what static friction resists, and
it acts in the direction of the last motion (the motor pushes on, friction holds back).

Streaming: :class:`HoldState` carries the last direction from one chunk of samples to the
next, so chunked evaluation equals one pass over the whole record.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ['HoldState', 'last_direction', 'holding_force', 'REST_SPEED_M_S']

REST_SPEED_M_S = 1.0e-4
"""Default speed at or below which an axis counts as at rest [m/s] (0.1 mm/s: above the
velocity noise of drive traces derived from positions, far below any feed)."""


@dataclass
class HoldState:
    """The last direction of motion per axis (-1, 0 or +1), carried across chunks."""

    direction: np.ndarray = field(default_factory=lambda: np.zeros(0))


def last_direction(velocity: np.ndarray, *, rest_speed: float = REST_SPEED_M_S,
                   state: HoldState | None = None) -> np.ndarray:
    """Sign of the last velocity beyond ``rest_speed`` at every sample, ``(n, k)``.

    Samples beyond ``rest_speed`` give their own sign; samples at rest repeat the last
    direction before them (from ``state`` at the start of the chunk, 0 if none). ``state``
    is updated to the direction after the last sample.
    """
    v = np.asarray(velocity, dtype=float)
    if v.ndim == 1:
        v = v[:, None]
    if not rest_speed >= 0.0:
        msg = f'rest_speed must be >= 0 m/s, got {rest_speed!r}'
        raise ValueError(msg)
    n, k = v.shape
    start = np.zeros(k)
    if state is not None and state.direction.shape == (k,):
        start = state.direction.astype(float)
    moving = np.abs(v) > rest_speed
    sign = np.where(moving, np.sign(v), 0.0)
    # index of the latest moving sample at or before each row (-1: none in this chunk)
    idx = np.where(moving, np.arange(n)[:, None], -1)
    np.maximum.accumulate(idx, axis=0, out=idx)
    cols = np.broadcast_to(np.arange(k), (n, k))
    out = np.where(idx >= 0, sign[np.maximum(idx, 0), cols], start[None, :])
    if state is not None:
        state.direction = out[-1].copy() if n else start
    return out


def holding_force(velocity: np.ndarray, hold_n: np.ndarray | float, *,
                  rest_speed: float = REST_SPEED_M_S,
                  state: HoldState | None = None) -> np.ndarray:
    """Force the drive holds at rest [N], ``(n, k)``: ``hold_n · d_last`` at rest, else 0.

    ``hold_n`` [N] per axis (broadcast to ``(k,)``) must be finite and ``>= 0`` (module
    docstring: the held force acts in the last direction of motion).
    """
    v = np.asarray(velocity, dtype=float)
    if v.ndim == 1:
        v = v[:, None]
    hold = np.broadcast_to(np.asarray(hold_n, dtype=float), (v.shape[1],))
    if not np.all(np.isfinite(hold)) or np.any(hold < 0.0):
        msg = f'holding force must be finite and >= 0 N, got {hold.tolist()}'
        raise ValueError(msg)
    direction = last_direction(v, rest_speed=rest_speed, state=state)
    at_rest = np.abs(v) <= rest_speed
    return np.where(at_rest, direction * hold[None, :], 0.0)
