"""The parameter table: numbering, names, scopes and the live provider."""
from __future__ import annotations

import pytest

from feed_axis_energy.gcode.read.params import (MAX_PARAMETER, ParameterError, Parameters,
                                                READ_ONLY_PARAMETERS)


def test_unset_numbered_reads_zero_and_set_values_stay():
    p = Parameters()
    assert p.get(100) == 0.0
    p.set(100, 2.5)
    assert p.get(100) == 2.5


@pytest.mark.parametrize('n', [0, -1, MAX_PARAMETER + 1])
def test_numbers_out_of_range(n):
    with pytest.raises(ParameterError, match='out of range'):
        Parameters().get(n)


@pytest.mark.parametrize('n', sorted(READ_ONLY_PARAMETERS)[:3] + [5420, 5428, 5400])
def test_read_only_numbers_refuse_assignment(n):
    with pytest.raises(ParameterError, match='read-only'):
        Parameters().check_settable(n)


def test_names_ignore_case_and_blanks():
    p = Parameters()
    p.set_named('My Depth', 3.0)
    assert p.get_named('mydepth') == 3.0
    assert p.get_named('MY  DEPTH') == 3.0


def test_unset_name_is_an_error():
    with pytest.raises(ParameterError, match=r'#<depth> is not defined'):
        Parameters().get_named('depth')


def test_locals_belong_to_the_call_and_globals_survive_it():
    p = Parameters()
    p.set_named('depth', 1.0)
    p.set(1, 7.0)
    p.set(2, 8.0)
    saved = p.enter_call([10.0])
    assert p.get(1) == 10.0 and p.get(2) == 0.0      # LinuxCNC 2.9 zeroes #2..#30
    assert not p.exists_named('depth')                # the caller's local is not visible
    p.set_named('depth', 5.0)
    p.set_named('_result', 9.0)
    p.set(2, 99.0)
    p.set(31, 4.0)
    p.leave_call(saved)
    assert p.get_named('depth') == 1.0
    assert p.get_named('_result') == 9.0
    assert (p.get(1), p.get(2), p.get(31)) == (7.0, 8.0, 4.0)


def test_fanuc_calls_keep_the_arguments_global():
    p = Parameters()
    saved = p.enter_call(None)
    p.set(1, 3.0)
    p.leave_call(saved)
    assert p.get(1) == 3.0


def test_provider_is_asked_first():
    p = Parameters(provider=lambda key: {5420: 12.0, '_x': 12.0}.get(key))
    p.set(5421, 1.0)
    assert p.get(5420) == 12.0
    assert p.get(5421) == 1.0          # provider answered None: the table
    assert p.get_named('_X') == 12.0
    assert p.exists_named('_x') and not p.exists_named('_y')


def test_predefined_names():
    p = Parameters()
    assert p.get_named('_vmajor') == 2.0 and p.get_named('_vminor') == 9.0
    assert p.get_named('_value') == 0.0 and p.get_named('_task') == 1.0
    assert p.get_named('_call_level') == 0.0
    saved = p.enter_call([])
    assert p.get_named('_call_level') == 1.0
    p.leave_call(saved)
    for name in ('_value', '_X', '_abs_z', '_metric'):
        with pytest.raises(ParameterError, match='read-only'):
            p.check_settable_named(name)
    p.check_settable_named('_mine')
