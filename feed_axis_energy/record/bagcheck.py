"""Checks of what a bag holds, used by :mod:`.bagio` on every read.

Failures of the ``rosbags`` reader on damaged content become :class:`DataError` naming the
bag (and topic and message index); decoded ``JointTrajectory`` messages are checked before
their arrays are used, so corrupt CDR that still decodes is not passed on.
"""
from __future__ import annotations

from contextlib import contextmanager
import math
from pathlib import Path
from typing import Iterator

import numpy as np

from ..errors import DataError, shorten

__all__ = ['check_trajectory', 'check_joint_state', 'field_layout', 'guard']

_NS = 1_000_000_000
_FIELDS = ('positions', 'velocities', 'accelerations', 'effort')

_MAX_FAILURE_TEXT = 100


def _check_names_and_stamp(names: list, stamp, where: dict) -> None:
    """Joint names unique and the header stamp a valid time (``where``: the DataError's place)."""
    if len(set(names)) != len(names):
        raise DataError('joint names repeat; expected one name per column', **where)
    if stamp.sec < 0 or not 0 <= stamp.nanosec < _NS:
        msg = f'header stamp {stamp.sec} s {stamp.nanosec} ns is not a valid time'
        raise DataError(msg, **where)


@contextmanager
def guard(path: Path, *, topic: str = '', index: int | None = None,
          doing: str = 'read') -> Iterator[None]:
    """Turn whatever rosbags raises on damaged content into a :class:`DataError`."""
    try:
        yield
    except DataError:
        raise
    except RecursionError:
        msg = f'cannot {doing}: the data is nested too deeply; the bag is damaged'
        raise DataError(msg, file=str(path), topic=topic, index=index) from None
    except MemoryError:
        msg = f'cannot {doing}: a size field asks for more memory than exists; the bag is damaged'
        raise DataError(msg, file=str(path), topic=topic, index=index) from None
    # the reader's own errors, and what its decoders raise on corrupt bytes (struct.error,
    # IndexError, UnicodeDecodeError, KeyError, sqlite3 errors, ...): the bag is damaged
    except Exception as err:  # noqa: B902
        text = shorten(str(err), limit=_MAX_FAILURE_TEXT) or type(err).__name__
        if isinstance(err, OSError) and err.strerror:
            text = err.strerror
        msg = f'cannot {doing}: {text} (the bag is damaged or not a rosbag2 bag)'
        raise DataError(msg, file=str(path), topic=topic, index=index) from None


def check_trajectory(msg, *, file: str, topic: str, index: int,
                     max_abs: float = math.inf) -> int:
    """Check one decoded JointTrajectory; return its number of joints.

    Every point's ``positions``, ``velocities``, ``accelerations`` and ``effort`` must be
    empty or have one value per joint name, all values and the stamps must be finite (and
    values at most ``max_abs`` in magnitude), times non-negative, joint names unique.

    Raises
    ------
    DataError
        Naming the bag, the topic and the 0-based message index.
    """
    names = list(msg.joint_names)
    m = len(names)
    where = {'file': file, 'topic': topic, 'index': index}
    _check_names_and_stamp(names, msg.header.stamp, where)
    for j, point in enumerate(msg.points):
        dur = point.time_from_start
        if dur.sec < 0 or not 0 <= dur.nanosec < _NS:
            msg_ = f'point {j}: time_from_start {dur.sec} s {dur.nanosec} ns is not valid'
            raise DataError(msg_, **where)
        for field in _FIELDS:
            arr = getattr(point, field)
            if len(arr) not in (0, m):
                msg_ = (f'point {j}: {field} has {len(arr)} values for {m} joint names; '
                        'expected one per joint or none')
                raise DataError(msg_, **where)
            if len(arr) and not np.isfinite(arr).all():
                msg_ = f'point {j}: {field} holds NaN or infinite values; expected finite ones'
                raise DataError(msg_, **where)
            if len(arr) and np.abs(arr).max() > max_abs:
                msg_ = (f'point {j}: {field} holds {float(np.abs(arr).max()):.3g}; expected '
                        f'magnitudes of at most {max_abs:g}')
                raise DataError(msg_, **where)
    return m


def check_joint_state(msg, *, file: str, topic: str, index: int) -> int:
    """Check one decoded ``sensor_msgs/JointState``; return its number of names.

    ``position``, ``velocity`` and ``effort`` must be empty or have one finite value per
    name, names unique, the stamp a valid time.

    Raises
    ------
    DataError
        Naming the bag, the topic and the 0-based message index.
    """
    names = list(msg.name)
    m = len(names)
    where = {'file': file, 'topic': topic, 'index': index}
    _check_names_and_stamp(names, msg.header.stamp, where)
    for field in ('position', 'velocity', 'effort'):
        arr = getattr(msg, field)
        if len(arr) not in (0, m):
            msg_ = (f'{field} has {len(arr)} values for {m} names; expected one per name '
                    'or none')
            raise DataError(msg_, **where)
        if len(arr) and not np.isfinite(arr).all():
            msg_ = f'{field} holds NaN or infinite values; expected finite ones'
            raise DataError(msg_, **where)
    return m


def field_layout(message) -> tuple[bool, ...]:
    """Which of the four fields the message fills (from its first point)."""
    if not message.points:
        return ()
    point = message.points[0]
    layout = tuple(len(getattr(point, f)) > 0 for f in _FIELDS)
    for p in message.points[1:]:
        if tuple(len(getattr(p, f)) > 0 for f in _FIELDS) != layout:
            return ('mixed',)
    return layout
