"""Program text: line ends, encodings and the subroutine search path."""
from __future__ import annotations

from pathlib import Path

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.read.source import (decode_program, find_subroutine_file, read_program,
                                                split_lines)


@pytest.mark.parametrize('text', ['G0 X1\nG1 X2\nM2\n', 'G0 X1\r\nG1 X2\r\nM2\r\n',
                                  'G0 X1\rG1 X2\rM2\r', 'G0 X1\rG1 X2\r\nM2'])
def test_every_line_end_gives_the_same_three_lines(text):
    assert split_lines(text) == ['G0 X1', 'G1 X2', 'M2']


def test_form_feed_stays_inside_its_line():
    # str.splitlines() would split here; a control does not.
    assert split_lines('G0 X1\x0c\nM2\n') == ['G0 X1\x0c', 'M2']


def test_empty_lines_are_kept_and_a_final_line_end_adds_none():
    assert split_lines('\n\nM2\n') == ['', '', 'M2']
    assert split_lines('M2') == ['M2']


def test_bom_is_dropped():
    assert decode_program(b'\xef\xbb\xbfG0 X1\n', file='p.nc') == 'G0 X1\n'


@pytest.mark.parametrize('data, line, column', [
    (b'G0 X1\nG1 X\xff2\n', 2, 5),
    (b'G0 X1\rG1 X2\r\xe9\r', 3, 1),          # CR-only file: the third line
    (b'G0\r\nG1\r\n  (caf\xe9)\r\n', 3, 7),
])
def test_bad_byte_is_named_by_line_and_column(data, line, column):
    with pytest.raises(GcodeError) as info:
        decode_program(data, file='p.nc')
    assert (info.value.line, info.value.column) == (line, column)
    assert 'not UTF-8' in str(info.value)


def test_read_program_missing_file(tmp_path):
    with pytest.raises(GcodeError, match='cannot read the program'):
        read_program(tmp_path / 'none.ngc')


def test_subroutine_file_is_lower_case_and_program_dir_comes_first(tmp_path):
    prog, lib = tmp_path / 'prog', tmp_path / 'lib'
    prog.mkdir()
    lib.mkdir()
    (lib / 'pocket.ngc').write_text('x')
    (lib / 'only_lib.ngc').write_text('x')
    (prog / 'pocket.ngc').write_text('x')
    assert find_subroutine_file('POCKET', program_dir=prog, search_path=(lib,)) == \
        prog / 'pocket.ngc'
    assert find_subroutine_file('only_lib', program_dir=prog, search_path=(lib,)) == \
        lib / 'only_lib.ngc'
    assert find_subroutine_file('nothing', program_dir=prog, search_path=(lib,)) is None


@pytest.mark.parametrize('name', ['../pocket', 'a/b', '', 'x.y'])
def test_subroutine_names_cannot_leave_the_directories(tmp_path, name):
    (tmp_path / 'pocket.ngc').write_text('x')
    sub = tmp_path / 'sub'
    sub.mkdir()
    assert find_subroutine_file(name, program_dir=sub, search_path=()) is None


def test_a_directory_named_like_the_subroutine_is_not_a_file(tmp_path):
    (tmp_path / 'pocket.ngc').mkdir()
    assert find_subroutine_file('pocket', program_dir=Path(tmp_path)) is None
