"""program.make_move builds the same Move as the dataclass constructor."""
from __future__ import annotations

import dataclasses

import pytest

from feed_axis_energy.core.program import make_move, Move, MoveKind


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
