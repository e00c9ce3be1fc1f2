"""A rotary axis word alone in a Sinumerik block (``G1 B0``, the KIT DMC 60H programs) moves
the axis in the block's modal G0/G1, as on the control; before, the front handed the word on
without its motion mode and the interpreter refused the line."""
import math

import pytest

from feed_axis_energy.gcode import parse_gcode


@pytest.mark.parametrize('mode', ['G1', 'G0'])
def test_rotary_word_alone_moves_the_axis(mode):
    text = f'G90 G710 G94\n{mode} B90 F1500\nG1 X10 F600\nM30\n'
    program = parse_gcode(text, dialect='sinumerik', rotary_axes=('B',))
    turn = [m for m in program.moves if m.rot_end is not None and m.rot_end != m.rot_start]
    assert len(turn) == 1
    assert turn[0].rot_end == pytest.approx((0.0, math.radians(90.0), 0.0))    # (A, B, C)
    assert program.moves[-1].end[0] == pytest.approx(0.010)
