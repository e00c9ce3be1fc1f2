"""Coordinate systems, offsets and the tool table (gcode/interp/coords.py), checked by hand.

Every expected machine position below is computed by hand from LinuxCNC's rules
(machine = program + G5x origin + G92 offset + tool length offset).
"""
import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode.interp.coords import COORD_G_CODES, Coords, ParamTable, system_param
from feed_axis_energy.gcode.settings import ToolSpec


class Failed(Exception):
    pass


def fail(message, letter):
    raise Failed(letter, message)


def approx3(v):
    return pytest.approx(v, abs=1e-12)


def test_fresh_state_is_the_identity_like_the_reference_set_up():
    c = Coords()
    assert c.offset == (0.0, 0.0, 0.0) and c.system == 1
    assert c.to_machine((0.01, 0.02, 0.03)) == (0.01, 0.02, 0.03)
    assert c.params.get(5220) == 1.0 and c.params.get(5221) == 0.0
    assert c.stored_home('G28') == (0.0, 0.0, 0.0)


def test_g10_l2_then_g55_moves_the_program_origin():
    c = Coords()
    # G10 L2 P2 X100 Y50 (mm): G55 origin at machine (0.1, 0.05, 0)
    c.g10(2.0, 2.0, {'X': 0.1, 'Y': 0.05}, (0.0, 0.0, 0.0), fail=fail)
    assert c.params.get(system_param(2, 0)) == pytest.approx(100.0)
    assert c.params.get(5241) == pytest.approx(100.0) and c.params.get(5242) == 50.0
    assert c.offset == (0.0, 0.0, 0.0)           # G54 still active
    c.select_system(2)
    assert c.params.get(5220) == 2.0
    # program X10 Y10 Z-5 in G55 is machine X110 Y60 Z-5
    assert c.to_machine((0.01, 0.01, -0.005)) == approx3((0.11, 0.06, -0.005))
    c.select_system(1)
    assert c.to_machine((0.01, 0.01, -0.005)) == approx3((0.01, 0.01, -0.005))


def test_g10_l2_p0_changes_the_active_system_at_once():
    c = Coords()
    c.select_system(3)                          # G56
    c.g10(2.0, 0.0, {'Z': -0.02}, (0.0, 0.0, 0.0), fail=fail)
    assert c.params.get(5263) == pytest.approx(-20.0)
    assert c.to_machine((0.0, 0.0, 0.005)) == approx3((0.0, 0.0, -0.015))


def test_g10_l20_makes_the_current_point_read_the_given_value():
    c = Coords()
    pos = (0.2, 0.1, -0.05)                     # machine position of the tool
    c.g10(20.0, 1.0, {'X': 0.0, 'Y': 0.01}, pos, fail=fail)
    # the current point now reads X0 Y10 in G54: origin at machine X200 Y90
    assert c.to_program(pos) == approx3((0.0, 0.01, -0.05))
    assert (c.params.get(5221), c.params.get(5222)) == pytest.approx((200.0, 90.0))


def test_g92_offset_with_g54_origin_and_its_cancel_codes():
    c = Coords()
    c.g10(2.0, 1.0, {'X': 0.1}, (0.0, 0.0, 0.0), fail=fail)   # G54 X100
    pos = (0.13, 0.0, 0.0)                       # program X30 in G54
    c.axis_offsets('G92', {'X': 0.0}, pos)                # the current point becomes X0
    assert c.to_program(pos) == approx3((0.0, 0.0, 0.0))
    assert c.g92 == approx3((0.03, 0.0, 0.0))
    assert c.params.get(5210) == 1.0 and c.params.get(5211) == pytest.approx(30.0)
    # program X10 is machine 100 + 30 + 10 mm
    assert c.to_machine((0.01, 0.0, 0.0)) == approx3((0.14, 0.0, 0.0))
    c.axis_offsets('G92.2', {}, pos)                      # off, parameters kept
    assert c.to_program(pos) == approx3((0.03, 0.0, 0.0))
    assert c.params.get(5210) == 0.0 and c.params.get(5211) == pytest.approx(30.0)
    c.axis_offsets('G92.3', {}, pos)                      # back from the parameters
    assert c.to_program(pos) == approx3((0.0, 0.0, 0.0))
    c.axis_offsets('G92.1', {}, pos)                      # off and parameters cleared
    assert c.params.get(5211) == 0.0 and c.offset == approx3((0.1, 0.0, 0.0))
    c.axis_offsets('G92.3', {}, pos)
    assert c.offset == approx3((0.1, 0.0, 0.0))


def test_g92_applies_to_every_coordinate_system():
    c = Coords()
    c.g10(2.0, 2.0, {'Y': 0.05}, (0.0, 0.0, 0.0), fail=fail)  # G55 Y50
    c.axis_offsets('G92', {'Y': 0.01}, (0.0, 0.0, 0.0))  # current Y0 reads Y10: g92 Y = -10
    c.select_system(2)
    # in G55 program Y0 is machine 50 - 10 mm
    assert c.to_machine((0.0, 0.0, 0.0)) == approx3((0.0, 0.04, 0.0))


def test_g52_sets_the_offset_to_the_values_not_relative_to_the_point():
    c = Coords()
    c.axis_offsets('G52', {'X': 0.01, 'Z': -0.002}, (0.5, 0.5, 0.5))
    assert c.g92 == approx3((0.01, 0.0, -0.002))
    assert c.to_machine((0.0, 0.0, 0.0)) == approx3((0.01, 0.0, -0.002))
    c.axis_offsets('G52', {'X': 0.0}, (0.5, 0.5, 0.5))   # G52 X0 cancels X only
    assert c.g92 == approx3((0.0, 0.0, -0.002))


def test_tool_length_offset_from_the_table_and_its_variants():
    c = Coords(tools={1: ToolSpec(radius_m=0.003, length_m=0.05), 2: ToolSpec(length_m=0.02)})
    c.select_tool(1)
    c.change_tool()                              # T1 M6
    c.tool_length('G43', None, {}, fail=fail)    # G43: the loaded tool
    assert c.to_machine((0.0, 0.0, 0.0)) == approx3((0.0, 0.0, 0.05))
    c.tool_length('G43', 2.0, {}, fail=fail)     # G43 H2
    assert c.offset == approx3((0.0, 0.0, 0.02))
    c.tool_length('G43.2', 1.0, {}, fail=fail)   # G43.2 H1 adds tool 1's length
    assert c.offset == approx3((0.0, 0.0, 0.07))
    c.tool_length('G43.1', None, {'Z': -0.01}, fail=fail)
    assert c.offset == approx3((0.0, 0.0, -0.01))
    c.tool_length('G43.2', None, {'Z': 0.004}, fail=fail)
    assert c.offset == approx3((0.0, 0.0, -0.006))
    c.tool_length('G49', None, {}, fail=fail)
    assert c.offset == (0.0, 0.0, 0.0)
    assert c.cutter_radius(1.0, fail=fail) == 0.003
    assert c.cutter_radius(None, fail=fail) == 0.003      # D absent: the loaded tool
    assert c.cutter_radius(0.0, fail=fail) == 0.0


@pytest.mark.parametrize('call, letter, words', [
    (lambda c: c.tool_length('G43', 7.0, {}, fail=fail), 'H', 'tool 7 is not in the tool'),
    (lambda c: c.tool_length('G43', 1.5, {}, fail=fail), 'H', 'whole number'),
    (lambda c: c.tool_length('G43.2', None, {}, fail=fail), 'G', 'No axes'),
    (lambda c: c.tool_length('G43.2', 1.0, {'Z': 0.1}, fail=fail), 'H', 'both H'),
    (lambda c: c.cutter_radius(3.0, fail=fail), 'D', 'tool 3 is not in the tool'),
    (lambda c: c.g10(None, 1.0, {}, (0, 0, 0), fail=fail), 'G', 'needs an L word'),
    (lambda c: c.g10(3.0, 1.0, {}, (0, 0, 0), fail=fail), 'L', 'not supported'),
    (lambda c: c.g10(2.0, None, {}, (0, 0, 0), fail=fail), 'G', 'needs a P word'),
    (lambda c: c.g10(2.0, 10.0, {}, (0, 0, 0), fail=fail), 'P', 'out of range (0-9)'),
    (lambda c: c.g10(2.0, 1.5, {}, (0, 0, 0), fail=fail), 'P', 'not an integer'),
    (lambda c: c.g10(20.0, 1.0, {'R': 0.0}, (0, 0, 0), fail=fail), 'R', 'R not allowed'),
    (lambda c: c.g10(2.0, 1.0, {'R': 1e300}, (0, 0, 0), fail=fail), 'R', 'plausible angle'),
    (lambda c: c.g10(1.0, 0.0, {}, (0, 0, 0), fail=fail), 'P', 'tool number'),
])
def test_errors_name_the_word(call, letter, words):
    c = Coords(tools={1: ToolSpec()}, strict_tools=True)
    with pytest.raises(Failed) as err:
        call(c)
    assert err.value.args[0] == letter and words in err.value.args[1]


def test_missing_loaded_tool_is_an_error_at_the_g_word():
    c = Coords(strict_tools=True)
    c.select_tool(4)
    c.change_tool()
    with pytest.raises(Failed) as err:
        c.tool_length('G43', None, {}, fail=fail)
    assert err.value.args[0] == 'G' and 'tool 4' in err.value.args[1]


def test_missing_tools_have_zero_length_and_radius_and_are_reported():
    # without strict_tools a tool the table lacks is tool 0's data, and on_missing_tool hears
    # of it (the interpreter turns that into one warning per tool number)
    c = Coords(tools={1: ToolSpec(radius_m=0.003, length_m=0.05)})
    heard = []
    c.on_missing_tool = heard.append
    c.tool_length('G43', 1.0, {}, fail=fail)
    assert c.tlo == approx3((0.0, 0.0, 0.05))
    c.tool_length('G43', 7.0, {}, fail=fail)
    assert c.tlo == approx3((0.0, 0.0, 0.0))
    assert c.cutter_radius(3.0, fail=fail) == 0.0
    c.check_tool_number(9, letter='T', fail=fail)       # selecting uses no data: silent
    assert heard == [7, 3]
    # G10 L1 on a missing tool adds it, from length and radius 0
    c.g10(1.0, 8.0, {'R': 0.002}, (0, 0, 0), fail=fail)
    assert c.tools[8] == ToolSpec(radius_m=0.002, length_m=0.0) and heard == [7, 3, 8]


def test_g10_l1_writes_the_tool_table():
    c = Coords(tools={5: ToolSpec(radius_m=0.001, length_m=0.01)})
    c.g10(1.0, 5.0, {'Z': 0.04, 'R': 0.002}, (0, 0, 0), fail=fail)
    assert c.tools[5] == ToolSpec(radius_m=0.002, length_m=0.04)
    c.tool_length('G43', 5.0, {}, fail=fail)
    assert c.offset == approx3((0.0, 0.0, 0.04))
    c.g10(1.0, 5.0, {'R': 0.003}, (0, 0, 0), fail=fail)     # R alone keeps the length
    assert c.tools[5] == ToolSpec(radius_m=0.003, length_m=0.04)


def test_g10_l10_and_l11_set_the_length_from_the_current_point():
    c = Coords(tools={3: ToolSpec()})
    c.g10(2.0, 1.0, {'Z': -0.2}, (0, 0, 0), fail=fail)     # G54 Z-200 mm
    c.g10(2.0, 9.0, {'Z': -0.3}, (0, 0, 0), fail=fail)     # G59.3 Z-300 mm
    c.axis_offsets('G52', {'Z': 0.01}, (0, 0, 0))           # G92-type offset Z10 mm
    pos = (0.0, 0.0, -0.05)                                 # machine Z-50 mm
    # L10 Z0: with the new length the point reads Z0 in G54: -50 = 0 + (-200) + 10 + L
    c.g10(10.0, 3.0, {'Z': 0.0}, pos, fail=fail)
    assert c.tools[3].length_m == pytest.approx(0.14)
    # L11 Z5: in G59.3 without G92: -50 = 5 + (-300) + L
    c.g10(11.0, 3.0, {'Z': 0.005}, pos, fail=fail)
    assert c.tools[3].length_m == pytest.approx(0.245)
    c.tool_length('G43', 3.0, {}, fail=fail)
    c.select_system(9)
    c.axis_offsets('G92.2', {}, pos)
    assert c.to_program(pos)[2] == pytest.approx(0.005)


def test_g28_goes_through_the_via_point_to_the_stored_position():
    c = Coords(home_m=(0.0, 0.0, 0.1))
    assert c.params.get(5163) == pytest.approx(100.0)
    c.g10(2.0, 1.0, {'Z': -0.05}, (0, 0, 0), fail=fail)
    # G91 G28 Z0 at machine (0.02, 0.03, 0.01): via = the current point, Z only goes home
    via = (0.02, 0.03, 0.01)
    assert c.home_path('G28', via, (False, False, True)) == [via, (0.02, 0.03, 0.1)]
    # no axis words: every axis goes home (LinuxCNC, Haas), whatever the work offset
    assert c.home_path('G28', via, (False, False, False)) == [via, (0.0, 0.0, 0.1)]
    # G30.1 stores the current machine position, G30 returns to it
    c.save_home('G30.1', (0.3, 0.2, 0.1))
    assert (c.params.get(5181), c.params.get(5182)) == pytest.approx((300.0, 200.0))
    assert c.home_path('G30', via, (True, True, False))[1] == approx3((0.3, 0.2, 0.01))


def test_live_values_in_program_units():
    c = Coords(tools={3: ToolSpec(radius_m=0.005, length_m=0.1)})
    c.g10(2.0, 1.0, {'X': 0.1}, (0, 0, 0), fail=fail)
    pos = (0.1254, 0.0, 0.0)
    assert c.system_value(5420, pos, 0.001) == pytest.approx(25.4)
    assert c.system_value('_x', pos, 0.0254) == pytest.approx(1.0)
    assert c.system_value('_abs_x', pos, 0.001) == pytest.approx(125.4)
    assert c.system_value(5424, pos, 0.001) == 0.0          # A axis: not simulated
    assert c.system_value('_coord_system', pos, 0.001) == 540.0
    c.select_system(7)
    assert c.system_value('_coord_system', pos, 0.001) == 591.0
    c.select_tool(3)
    c.change_tool()
    assert c.system_value(5400, pos, 0.001) == 3.0
    assert c.system_value(5403, pos, 0.001) == pytest.approx(100.0)
    assert c.system_value(5410, pos, 0.001) == pytest.approx(10.0)
    assert c.system_value('_tool_offset', pos, 0.001) == 0.0
    assert c.system_value(31, pos, 0.001) is None and c.system_value('_foo', pos, 1) is None


def test_a_rotation_written_into_the_parameters_applies_when_selected():
    params = ParamTable()
    params.set(5250, 90.0)                       # G55 rotated 90 degrees (a program wrote it)
    c = Coords(params=params)
    assert not c.rotated
    c.select_system(2, fail=fail)
    assert c.rotated and c.to_machine((0.001, 0.0, 0.0)) == approx3((0.0, 0.001, 0.0))
    params.set(5270, float('inf'))
    with pytest.raises(Failed, match='plausible angle'):
        c.select_system(3, fail=fail)


def test_code_table_covers_every_system_and_offset_code():
    assert {COORD_G_CODES[k][1] for k in (540, 550, 560, 570, 580, 590, 591, 592, 593)} \
        == set(range(1, 10))
    for k in (100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923, 430, 431, 432, 490):
        assert k in COORD_G_CODES


def run(c, codes, words, *, position=(0.0, 0.0, 0.0), scale=0.001, motion=1, absolute=True,
        comp=False):
    return c.execute(codes, words.get, position=position, scale=scale, motion=motion,
                     absolute=absolute, comp_active=comp, fail=fail)


def test_execute_g10_line_uses_its_axis_words_as_data():
    c = Coords(tools={2: ToolSpec()})
    eff = run(c, {'nonmodal': 'G10'}, {'L': 2.0, 'P': 1.0, 'X': 10.0, 'Y': 20.0})
    assert eff.axes_used and eff.home is None
    assert eff.frame == approx3((0.01, 0.02, 0.0)) and c.offset == eff.frame
    # G10 L1 R in program units is a radius; in inches too
    run(c, {'nonmodal': 'G10'}, {'L': 1.0, 'P': 2.0, 'R': 0.1, 'Z': 1.0}, scale=0.0254)
    assert c.tools[2].radius_m == pytest.approx(0.00254)
    assert c.tools[2].length_m == pytest.approx(0.0254)


def test_execute_order_is_tool_length_then_system_then_g92():
    c = Coords(tools={1: ToolSpec(length_m=0.1)})
    run(c, {'nonmodal': 'G10'}, {'L': 2.0, 'P': 2.0, 'Z': -200.0})       # G55 Z-200 mm
    # G43 H1 G55 G92 Z0 at machine Z = -0.05: G92 sees the new TLO and the G55 origin
    eff = run(c, {'tool_length': 'G43', 'coord': 2, 'nonmodal': 'G92'}, {'H': 1.0, 'Z': 0.0},
              position=(0.0, 0.0, -0.05))
    assert eff.axes_used
    # the current point reads Z0: g92 Z = -0.05 - 0.1 - (-0.2) = 0.05
    assert c.g92 == approx3((0.0, 0.0, 0.05))
    assert c.to_program((0.0, 0.0, -0.05)) == approx3((0.0, 0.0, 0.0))


def test_execute_g43_with_an_axis_word_is_a_move_and_g53_uses_no_offset():
    c = Coords(tools={1: ToolSpec(length_m=0.1)})
    eff = run(c, {'tool_length': 'G43'}, {'H': 1.0, 'Z': 5.0}, motion=0)
    assert not eff.axes_used and eff.frame == approx3((0.0, 0.0, 0.1))
    eff = run(c, {'nonmodal': 'G53'}, {'Z': 0.0}, motion=0)
    assert eff.frame == (0.0, 0.0, 0.0) and not eff.axes_used
    with pytest.raises(Failed, match='G0 or G1'):
        run(c, {'nonmodal': 'G53'}, {'X': 0.0}, motion=2)
    with pytest.raises(Failed, match='incremental'):
        run(c, {'nonmodal': 'G53'}, {'X': 0.0}, motion=0, absolute=False)


def test_execute_marks_g28_and_g30_and_stores_with_g28_1():
    c = Coords()
    eff = run(c, {'nonmodal': 'G28.1'}, {}, position=(0.1, 0.2, 0.3))
    assert eff.home is None and c.stored_home('G28') == approx3((0.1, 0.2, 0.3))
    assert run(c, {'nonmodal': 'G28'}, {'Z': 0.0}).home == 'G28'
    assert run(c, {'nonmodal': 'G30'}, {}).home == 'G30'


@pytest.mark.parametrize('codes, words', [
    ({'nonmodal': 'G92'}, {'X': 0.0}), ({'nonmodal': 'G52'}, {'X': 0.0}),
    ({'nonmodal': 'G28'}, {}), ({'nonmodal': 'G30.1'}, {}), ({'tool_length': 'G49'}, {}),
    ({'nonmodal': 'G10'}, {'L': 2.0, 'P': 0.0, 'X': 1.0}),
    ({'nonmodal': 'G10'}, {'L': 20.0, 'P': 1.0, 'X': 1.0}),
])
def test_execute_refuses_what_linuxcnc_refuses_under_cutter_compensation(codes, words):
    with pytest.raises(Failed, match='cutter'):
        run(Coords(), codes, words, comp=True)


def test_execute_allows_g10_of_another_system_under_cutter_compensation():
    c = Coords()
    run(c, {'nonmodal': 'G10'}, {'L': 2.0, 'P': 3.0, 'X': 1.0}, comp=True)
    assert c.params.get(5261) == pytest.approx(1.0)


def test_tools_given_as_radius_length_pairs():
    c = Coords(tools={7: (0.0, 0.0), 8: (0.002, 0.03)})
    assert c.tools[8] == ToolSpec(radius_m=0.002, length_m=0.03) and c.tools[7] == ToolSpec()


# -- through the interpreter: programs with hand-checked machine positions -------------------

def ends_mm(text, **kw):
    from feed_axis_energy.gcode.load import parse_gcode
    prog = parse_gcode(text, file='t.nc', **kw)
    return [tuple(round(v * 1000.0, 9) for v in m.end) for m in prog.moves
            if m.length_m > 0.0]


def test_program_with_g10_l2_and_g55():
    text = 'G21 G90\nG10 L2 P1 X100 Y50\nG10 L2 P2 Z-100\nG0 X10 Y10\nG55\nG0 Z5\nG54 X0\n'
    # G54: X10 Y10 is machine 110 60; G55: Z5 is machine -95; G54 X0: machine X100
    assert ends_mm(text) == [(110.0, 60.0, 0.0), (110.0, 60.0, -95.0), (100.0, 60.0, -95.0)]


def test_program_with_g92_and_its_cancel():
    text = 'G21 G90\nG0 X30\nG92 X0\nG0 X10\nG92.1\nG0 X10\nG92.3\nG0 X5\n'
    # G92 X0 at X30: offset 30; X10 -> 40; G92.1: X10 -> 10; G92.3 restores 0?: no, .1
    # cleared the parameters, so X5 -> 5
    assert ends_mm(text) == [(30.0, 0, 0), (40.0, 0, 0), (10.0, 0, 0), (5.0, 0, 0)]
    text = 'G21 G90\nG0 X30\nG92 X0\nG92.2\nG0 X10\nG92.3\nG0 X5\n'
    # G92.2 keeps the parameters: G92.3 brings the offset 30 back
    assert ends_mm(text) == [(30.0, 0, 0), (10.0, 0, 0), (35.0, 0, 0)]


def test_program_with_g52_in_inches():
    text = 'G20 G90\nG52 X1 Y-1\nG1 X1 Y1 F10\nG52 X0 Y0\nG0 X1 Y1\n'
    assert ends_mm(text) == [(50.8, 0.0, 0.0), (25.4, 25.4, 0.0)]


def test_g53_is_machine_coordinates_for_its_line_only():
    text = 'G21 G90\nG10 L2 P1 X100 Z-50\nG0 X0 Z0\nG53 G0 Z0\nG0 X20\nG53 X-10\n'
    assert ends_mm(text) == [(100.0, 0, -50.0), (100.0, 0, 0.0), (120.0, 0, 0.0),
                             (-10.0, 0, 0.0)]


def test_tool_length_offset_and_g10_l1():
    tools = {1: ToolSpec(radius_m=0.003, length_m=0.1), 2: ToolSpec()}
    text = ('G21 G90\nT1 M6\nG43 G0 Z10\nG10 L1 P2 Z20 R1\nG43 H2 Z10\nG43.1 Z-5\nG0 Z10\n'
            'G49 Z10\n')
    assert ends_mm(text, tools=tools) == [(0, 0, 110.0), (0, 0, 30.0), (0, 0, 5.0),
                                          (0, 0, 10.0)]


def test_g28_and_g30_through_the_intermediate_point():
    text = ('G21 G90\nG10 L2 P1 Z-20\nG1 X10 Y20 Z5 F600\nG28 Z10\nG0 X50 Y60\nG30.1\n'
            'G0 X0 Y0\nG91 G30 X0\n')
    # via program Z10 = machine Z-10, then Z to the reference Z100 (home_m); G30.1 stores
    # machine (50, 60, 100); G91 G30 X0: via = here, then X only
    assert ends_mm(text, home=(0.0, 0.0, 0.1)) == [
        (10.0, 20.0, -15.0), (10.0, 20.0, -10.0), (10.0, 20.0, 100.0), (50.0, 60.0, 100.0),
        (0.0, 0.0, 100.0), (50.0, 0.0, 100.0)]


def test_absolute_arc_centres_follow_the_work_offset():
    from feed_axis_energy.gcode.load import parse_gcode
    prog = parse_gcode('G21 G90 G90.1\nG10 L2 P1 X100\nG0 X10 Y0\nG2 X-10 Y0 I0 J0 F100\n')
    arc = prog.moves[-1]
    assert arc.center == approx3((0.1, 0.0, 0.0)) and arc.end == approx3((0.09, 0.0, 0.0))
    assert arc.length_m == pytest.approx(3.141592653589793 * 0.01, rel=1e-12)


def test_live_position_reads_program_coordinates():
    c = Coords()
    c.g10(2.0, 1.0, {'X': 0.1}, (0.0, 0.0, 0.0), fail=fail)
    assert c.system_value('_x', (0.1, 0.0, 0.0), 0.001) == pytest.approx(0.0)


@pytest.mark.parametrize('text, line, column, words', [
    ('G43 H1', 1, 5, 'not in the tool table'),
    ('G10 L3 P1', 1, 5, 'L10, L11 and L20'),
    ('G10 L1 P4 Z1', 1, 8, 'tool 4 is not in the tool table'),
    ('G10 L2 P10 X1', 1, 8, 'out of range'),
    ('G10 P1 X1', 1, 1, 'needs an L word'),
    ('G91 G0 G53 X1', 1, 8, 'G53 incremental'),
    ('G1 F100\nG53 G2 X1 I1', 2, 1, 'G0 or G1'),
    ('G10 L2 P1 R30\nG81 X1 Y1 Z-1 R1 F100', 2, 1, 'rotated coordinate system'),
    ('G10 L2 P1 R30\nG18 G0 X1\nG2 X0 Z1 I-1 K0 F100', 3, 10, 'G18 arcs in a rotated'),
    ('G41 D0 G1 X10 F100\nG92 X0', 2, 1, 'cutter radius'),
    ('G1 X1 F100\nG4 G92 X0 P1', 2, 4, 'same modal group'),
    ('G0 G92 X0', 1, 4, 'both use axis values'),
    ('G10 L2 P1 G1 X1 F100', 1, 1, 'both use axis values'),
    ('G92', 1, 1, 'All axes missing'),
    ('G52 (no axes)', 1, 1, 'All axes missing'),
])
def test_errors_name_line_and_column(text, line, column, words):
    from feed_axis_energy.gcode.load import parse_gcode
    with pytest.raises(GcodeError) as err:
        parse_gcode(text, file='t.nc', strict_tools=True)
    assert (err.value.line, err.value.column) == (line, column)
    assert words in str(err.value)


def test_g28_issues_both_rapids_even_of_zero_length_as_linuxcnc():
    from feed_axis_energy.gcode.load import parse_gcode
    from feed_axis_energy.gcode.program import MoveKind
    prog = parse_gcode('G21 G90\nG0 X10\nG91 G28 X0\n', home=(0.0, 0.0, 0.0))
    rapids = [m for m in prog.moves if m.line == 3]
    assert [m.kind for m in rapids] == [MoveKind.RAPID, MoveKind.RAPID]
    assert rapids[0].length_m == 0.0 and rapids[1].end == (0.0, 0.0, 0.0)
    assert rapids[1].length_m == pytest.approx(0.01)


def test_interpreter_supplies_live_values_for_the_parameter_provider():
    from feed_axis_energy.gcode.interp.interpreter import Interpreter
    text = 'G21 G90\nG10 L2 P1 X100\nG0 X10 Y5\nT3 M6\n'
    lines = text.splitlines()
    p = Interpreter('t.nc', (0.0, 0.0, 0.0), 2e-6, lines=lines, tools={3: (0.002, 0.05)})
    for n, line in enumerate(lines, 1):
        p.lineno = n
        p.line([(w[0], w[1:]) for w in line.split()])
    assert p.system_value(5420) == pytest.approx(10.0)     # program X, mm
    assert p.system_value('_abs_x') == pytest.approx(110.0)
    assert p.system_value(5400) == 3.0 and p.system_value(5410) == pytest.approx(4.0)
    assert p.system_value('_coord_system') == 540.0 and p.system_value(1) is None


BIG = '1' + '0' * 300


@pytest.mark.parametrize('text, line, column', [
    (f'G10 L2 P1 X{BIG}\nG0 X0\n', 1, 11),
    (f'G0 X1\nG92 Y{BIG}\n', 2, 5),
    (f'G43.1 Z{BIG}\n', 1, 7),
    (f'G52 X1{"0" * 400}\n', 1, 6),        # a literal beyond float range: at its first digit
    (f'G10 L1 P{BIG} Z1\n', 1, 8),
    ('G10 L1 P2 R2000\n', 1, 11),
    (f'G53 G0 X-1{"0" * 320}\n', 1, 9),
    ('G53 G0 Z2000000\n', 1, 8),
    # each offset is plausible, G92 (-900 m) plus the G55 origin (-900 m) is not
    ('G10 L2 P1 X900000\nG10 L2 P2 X-900000\nG92 X0\nG55\n', 4, 1),
])
def test_absurd_offsets_are_errors_not_inf(text, line, column):
    from feed_axis_energy.gcode.load import parse_gcode
    with pytest.raises(GcodeError) as err:
        parse_gcode(text, file='t.nc', tools={2: (0.0, 0.0)})
    assert (err.value.line, err.value.column) == (line, column)
    assert len(err.value.reason) < 120 and 'inf' not in err.value.reason


def test_absurd_stored_home_is_an_error_at_g28():
    params = ParamTable()
    params.set(5161, 1e300)
    c = Coords(params=params)
    with pytest.raises(Failed, match='stored G28'):
        c.home_path('G28', (0.0, 0.0, 0.0), (False, False, False), fail=fail)


# -- rotation (G10 L2 R): machine = R (program + G92) + G5x + TLO, hand-checked -----------------

def test_rotated_system_turns_absolute_and_incremental_moves():
    text = 'G21 G90\nG10 L2 P1 X10 R90\nG0 X1 Y0\nG0 Y2\nG91 G1 X1 F100\n'
    # (1,0) turned 90 deg is (0,1), + origin (10,0); (1,2) -> (-2,1) + (10,0); G91 X1 moves
    # the program point by (1,0) = machine (0,1)
    assert ends_mm(text) == [(10.0, 1.0, 0.0), (8.0, 1.0, 0.0), (8.0, 2.0, 0.0)]


def test_rotated_arc_keeps_its_direction_and_length():
    from feed_axis_energy.gcode.load import parse_gcode
    prog = parse_gcode('G21 G90\nG10 L2 P1 R90\nG0 X1 Y0\nG3 X-1 Y0 I-1 J0 F100\n')
    arc = prog.moves[-1]
    assert arc.start == approx3((0.0, 0.001, 0.0)) and arc.end == approx3((0.0, -0.001, 0.0))
    assert arc.center == approx3((0.0, 0.0, 0.0))
    assert arc.length_m == pytest.approx(3.141592653589793e-3, rel=1e-12)
    # counter-clockwise from +Y to -Y passes through -X (the turned +Y of the program)
    assert getattr(arc, 'sweep_rad', 3.141592653589793) == pytest.approx(3.141592653589793)


def test_g92_and_g10_l20_in_a_rotated_system():
    # at program (1,0) = machine (0,1): G92 X0 Y0 makes it read (0,0); X1 is then program
    # (1,0) + G92 (1,0) = (2,0) turned = machine (0,2)
    text = 'G21 G90\nG10 L2 P1 R90\nG0 X1 Y0\nG92 X0 Y0\nG0 X1\n'
    assert ends_mm(text) == [(0.0, 1.0, 0.0), (0.0, 2.0, 0.0)]
    # G10 L20 X0 at program (1,0): the origin moves by the turned difference (0,1)
    text = 'G21 G90\nG10 L2 P1 R90\nG0 X1 Y0\nG10 L20 P1 X0\nG0 X1 Y0\n'
    assert ends_mm(text) == [(0.0, 1.0, 0.0), (0.0, 2.0, 0.0)]


def test_g53_in_a_rotated_system_is_still_machine_coordinates():
    text = 'G21 G90\nG10 L2 P1 X10 R90\nG53 G0 X5\nG0 X0 Y0\nG53 G0 Y-3\n'
    assert ends_mm(text) == [(5.0, 0.0, 0.0), (10.0, 0.0, 0.0), (10.0, -3.0, 0.0)]


def test_probe_result_is_the_end_of_the_probe_move_in_program_coordinates():
    from feed_axis_energy.gcode.load import parse_gcode
    # G20, G54 origin X1 in: probe to program (0.5, 0, -0.1) in; then #5063 reads -0.1 and a
    # move to Z[#5063 + 1] goes to program Z0.9 in = machine 22.86 mm
    text = ('G20 G90\nG10 L2 P1 X1\nG0 X0.5\nG38.2 Z-0.1 F10\n#1 = #5063\nG0 Z[#1 + 1]\n'
            'G0 X[#5061]\n')
    prog = parse_gcode(text, file='p.nc')
    assert prog.moves[-2].end == approx3((0.0381, 0.0, 0.02286))
    assert prog.moves[-1].end == approx3((0.0381, 0.0, 0.02286))   # #5061 = 0.5 in
    c = Coords()
    c.params.set(5070, 1.0)
    c.probe_result((0.01, 0.02, -0.003), 0.001)
    assert [c.params.get(n) for n in (5061, 5062, 5063, 5064, 5070)] == \
        pytest.approx([10.0, 20.0, -3.0, 0.0, 0.0])


def test_programs_read_and_write_the_offset_parameters():
    # G10 L2 P2 X5 stores #5241 = 5 (mm); a program may read it, or write a system's origin
    # directly, which takes effect when the system is selected (LinuxCNC)
    text = ('G21 G90\nG10 L2 P2 X5\n#1 = #5241\nG0 X#1\n#5261 = 7\nG56\nG0 X0\n'
            'G0 Y[#<_coord_system> / 10]\nG0 Z[#5420 + 1]\n')
    # X5 in G54 = machine 5; G56 X0 = machine 7; Y = 560 / 10 = 56; Z = X (0) + 1
    assert ends_mm(text) == [(5.0, 0.0, 0.0), (7.0, 0.0, 0.0), (7.0, 56.0, 0.0),
                             (7.0, 56.0, 1.0)]


def test_grbl_dialect_warns_once_per_code_grbl_lacks():
    from feed_axis_energy.gcode.load import parse_gcode
    text = 'G21 G90\nG52 X1\nG0 X0\nG52 X2\nG43 H1 Z5\nG59.1\nG10 L2 P1 X1\nG92 X0\n'
    prog = parse_gcode(text, file='g.nc', dialect='grbl', tools={1: (0.0, 0.0)})
    assert [w.split(':')[1] for w in prog.warnings] == ['2', '5', '6']
    assert 'G52 is not a grbl 1.1 code' in prog.warnings[0]
    assert parse_gcode(text, file='l.nc', tools={1: (0.0, 0.0)}).warnings == ()


def test_g10_with_an_absurd_p_under_cutter_compensation_is_a_clean_error():
    from feed_axis_energy.gcode.load import parse_gcode
    with pytest.raises(GcodeError) as err:
        parse_gcode('G41 D0 G1 X10 F100\nG10 L2 P1' + '0' * 400 + ' X1\n', file='t.nc')
    assert err.value.line == 2


def test_live_tool_values_after_a_tool_change():
    # #5400 is the loaded tool, #5410 its diameter in mm (tool table radius 2.5 mm)
    text = 'G21 G90\nT3 M6\nG0 X#5400 Y#5410\n'
    assert ends_mm(text, tools={3: (0.0025, 0.0)}) == [(3.0, 5.0, 0.0)]
