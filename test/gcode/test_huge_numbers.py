"""Numbers too large for the reader on plain lines (issue 9: a 309+-digit G word raised
OverflowError, a 400-digit coordinate reached the JSON as NaN with exit 0)."""
import math

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.load import parse_gcode

BIG = '1' + '0' * 400


@pytest.mark.parametrize('line, column', [
    (f'G1 X{BIG} F100', 5),          # coordinate: float() gives inf
    ('G' + '1' * 320 + ' X1', 2),    # G code: round(inf) raised OverflowError
    ('M' + '3' * 310, 2),
    (f'G1 X1 F{BIG}', 8),
    (f'G4 P{BIG}', 5),
    ('G1 X1 Y1 2345 6789 01234 F100', 7),   # blanks inside a number (LinuxCNC rule)
    ('G1 X10000000000000.0 F100', 4),       # 1e13 mm: beyond the 1e12 limit
])
def test_too_large_is_an_error_at_its_column(line: str, column: int) -> None:
    with pytest.raises(GcodeError) as err:
        parse_gcode(f'G21 G90\n{line}\n', file='p.ngc')
    assert err.value.line == 2
    assert err.value.column == column
    assert len(str(err.value)) < 300


def test_long_numbers_within_the_limit_are_read() -> None:
    # leading zeros and many decimals are long but harmless; 1.2e11 mm is within the limit
    program = parse_gcode('G21 G90\nG1 X0000000000000000000012.5 F100\n'
                          'G1 Y12.3456789012345678\nG1 Y123456789012.5\n')
    ends = [m.end for m in program.moves]
    assert ends[0][0] == pytest.approx(0.0125)
    assert ends[1][1] == pytest.approx(0.0123456789012345678)
    assert ends[2][1] == pytest.approx(123456789.0125)
    assert all(math.isfinite(v) for end in ends for v in end)
