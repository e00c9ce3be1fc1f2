"""Expressions: LinuxCNC's operators, precedence, functions and domain errors."""
from __future__ import annotations

import math

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.read.expr import compact, MAX_MAGNITUDE, Reader
from feed_axis_energy.gcode.read.params import Parameters


def value(text: str, params: Parameters | None = None) -> float:
    s, cols = compact(text.upper())
    r = Reader(s, cols, text, file='t.ngc', line=7, params=params or Parameters())
    v = r.value()
    assert r.at_end(), f'left over: {s[r.pos:]}'
    return v


def error(text: str, params: Parameters | None = None) -> GcodeError:
    with pytest.raises(GcodeError) as info:
        value(text, params)
    assert info.value.file == 't.ngc' and info.value.line == 7
    return info.value


@pytest.mark.parametrize('text, expected', [
    ('[1 + 2 * 3]', 7.0),
    ('[[1 + 2] * 3]', 9.0),
    ('[2 ** 3 ** 2]', 64.0),          # left to right, as LinuxCNC: (2**3)**2
    ('[2 * 3 ** 2]', 18.0),
    ('[10 - 4 - 3]', 3.0),
    ('[12 / 3 / 2]', 2.0),
    ('[7 MOD 3]', 1.0),
    ('[-7 MOD 3]', 2.0),              # always non-negative
    ('[7 MOD -3]', 1.0),
    ('[1 + 2 EQ 3]', 1.0),            # + binds tighter than EQ
    ('[1 EQ 1 + 0.0000001]', 1.0),    # EQ within 1e-6
    ('[1 NE 1.00001]', 1.0),
    ('[2 GT 1 AND 1 GT 2]', 0.0),
    ('[2 GT 1 OR 1 GT 2]', 1.0),
    ('[1 XOR 1]', 0.0),
    ('[0 XOR 3]', 1.0),
    ('[3 LE 3]', 1.0), ('[3 LT 3]', 0.0), ('[3 GE 3.0000001]', 1.0),
    ('[-2 ** 2]', 4.0),               # "-2" is one number in LinuxCNC
    ('-[2]', -2.0),
    ('+-[2]', -2.0),
    ('[ABS[-2.5]]', 2.5),
    ('SIN[30]', 0.5),
    ('COS[60]', 0.5),
    ('TAN[45]', 1.0),
    ('ASIN[1]', 90.0),
    ('ACOS[0]', 90.0),
    ('ATAN[1]/[1]', 45.0),
    ('ATAN[1]/[-1]', 135.0),
    ('SQRT[16]', 4.0),
    ('EXP[0]', 1.0),
    ('LN[1]', 0.0),
    ('FIX[-2.5]', -3.0), ('FUP[-2.5]', -2.0), ('FIX[2.5]', 2.0), ('FUP[2.1]', 3.0),
    ('ROUND[2.5]', 3.0), ('ROUND[-2.5]', -3.0), ('ROUND[2.49]', 2.0),
    ('[s i n [ 3 0 ] ]', 0.5),       # blanks anywhere
    ('1 0.5', 10.5),
    ('.5', 0.5), ('-.5', -0.5), ('5.', 5.0),
])
def test_values(text, expected):
    assert value(text) == pytest.approx(expected, abs=1e-12)


def test_parameters_in_expressions():
    p = Parameters()
    p.set(1, 3.0)
    p.set(3, 10.0)
    p.set_named('depth', 2.0)
    p.set_named('_safe', 5.0)
    assert value('#1', p) == 3.0
    assert value('##1', p) == 10.0                 # #[#1] = #3
    assert value('#[#1 + 0]', p) == 10.0
    assert value('[#<depth> * #<_SAFE>]', p) == 10.0
    assert value('[#<De Pth>]', p) == 2.0          # case and blanks do not count
    assert value('EXISTS[#<depth>]', p) == 1.0
    assert value('EXISTS[#<nothing>]', p) == 0.0
    assert value('-#1', p) == -3.0


@pytest.mark.parametrize('text, message, column', [
    ('[1 / 0]', 'divide by zero', 4),
    ('[1 MOD 0]', 'MOD by zero', 4),
    ('SQRT[-1]', 'SQRT', 1),
    ('LN[0]', 'LN', 1),
    ('ACOS[2]', 'ACOS', 1),
    ('ASIN[-1.5]', 'ASIN', 1),
    ('[-8 ** 0.5]', 'non-integer power', 5),
    ('[0 ** -1]', 'zero to a negative power', 4),
    ('[10 ** 400]', 'too large', 5),
    ('EXP[1000]', 'too large', 1),
    ('[1 + 2', 'without a closing', 7),
    ('[1 ? 2]', 'unknown operator', 4),
    ('FOO[1]', 'unknown function', 1),
    ('SIN 30', '"[" missing', 5),
    ('ATAN[1]', '"/" missing', 8),
    ('#<depth>', '#<depth> is not defined', 1),
    ('#0', 'out of range', 1),
    ('#5602', 'out of range', 1),
    ('#1.5', 'integer expected', 2),
    ('1.2.3', 'bad number', 1),
    ('[9' + '9' * 400 + ']', 'too large', 2),
    ('[1E300 * 1E300]', 'unknown operator', 3),     # no exponent notation in G-code
])
def test_errors_name_the_column(text, message, column):
    err = error(text)
    assert message in str(err)
    assert err.column == column


def test_overflow_in_a_product_is_an_error_not_inf():
    p = Parameters()
    p.set(1, 1e300)
    err = error('[#1 * #1]', p)
    assert 'infinity' in str(err)


def test_checked_refuses_values_too_large_to_mean_anything():
    s, cols = compact('X[10**13]')
    r = Reader(s, cols, 'X[10**13]', file='t', line=1, params=Parameters())
    r.pos = 1
    v = r.value()
    assert v == 1e13 > MAX_MAGNITUDE
    with pytest.raises(GcodeError, match='too large'):
        r.checked(v, 1)
    assert r.checked(-MAX_MAGNITUDE, 1) == -MAX_MAGNITUDE
    with pytest.raises(GcodeError):
        r.checked(math.nan, 1)


def test_error_text_is_bounded():
    err = error('[1 / 0' + ' + 1' * 500 + ']')
    assert len(str(err)) < 200
