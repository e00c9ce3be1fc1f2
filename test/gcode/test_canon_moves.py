"""program.make_move, straight_move and arc_move build the same Move as the dataclass
constructor."""
from __future__ import annotations

import dataclasses

import pytest

from feed_axis_energy.gcode.program import arc_move, make_move, Move, MoveKind, straight_move


@pytest.mark.parametrize('fields', [
    {},
    {'feed_m_s': 0.01, 'exact_stop': True, 'length_m': 2.5},
    {'center': (1.0, 2.0, 3.0), 'plane': 18, 'turns': 2, 'sweep_rad': -7.0},
])
def test_make_move_equals_the_constructor(fields):
    args = (MoveKind.ARC_CW, 12, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    fast = make_move(*args, **fields)
    slow = Move(*args, **fields)
    assert fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
    assert dataclasses.asdict(fast) == dataclasses.asdict(slow)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.line = 3


@pytest.mark.parametrize('kind, fields', [
    (MoveKind.RAPID, (float('inf'), False, 0.0)),
    (MoveKind.LINEAR, (0.02, True, 1.5)),
])
def test_straight_move_equals_the_constructor(kind, fields):
    start, end = (0.0, 1.0, 2.0), (1.0, 1.0, 2.0)
    feed, exact, length = fields
    fast = straight_move(kind, 7, start, end, feed, exact, length)
    slow = Move(kind, 7, start, end, feed_m_s=feed, exact_stop=exact, length_m=length)
    assert fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
    assert dataclasses.asdict(fast) == dataclasses.asdict(slow)
    assert vars(fast) == vars(slow)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.end = start


@pytest.mark.parametrize('plane, turns, sweep', [(17, 0, 1.25), (18, 2, -13.0), (19, 0, 6.0)])
def test_arc_move_equals_the_constructor(plane, turns, sweep):
    start, end, centre = (0.0, 1.0, 2.0), (1.0, 0.0, 2.0), (0.0, 0.0, 2.0)
    kind = MoveKind.ARC_CCW if sweep > 0 else MoveKind.ARC_CW
    fast = arc_move(kind, 9, start, end, 0.01, False, centre, plane, turns, 3.5, sweep)
    slow = Move(kind, 9, start, end, feed_m_s=0.01, exact_stop=False, center=centre,
                plane=plane, turns=turns, length_m=3.5, sweep_rad=sweep)
    assert fast == slow and hash(fast) == hash(slow) and repr(fast) == repr(slow)
    assert vars(fast) == vars(slow)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.sweep_rad = 0.0
