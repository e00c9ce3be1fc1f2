"""The Sinumerik dialect (gcode/siemens/): each construct against a path derived by hand.

Expected values come from the programs' text and plane geometry worked out in the comments,
never from the code's own output. Positions in mm (moves are in metres).
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from feed_axis_energy.errors import GcodeError
from feed_axis_energy.gcode import iter_moves, load_gcode, parse_gcode
from feed_axis_energy.gcode.program import MoveKind

MM = 1e-3


def run(text: str, **kw):
    return parse_gcode(text, dialect='sinumerik', **kw)


def ends(prog, kinds=(MoveKind.RAPID, MoveKind.LINEAR, MoveKind.ARC_CW, MoveKind.ARC_CCW)):
    """End points [mm] of the moves of the given kinds, rounded to 1e-6 mm."""
    return [tuple(round(v / MM, 6) + 0.0 for v in m.end) for m in prog.moves if m.kind in kinds]


def centre_mm(move):
    return tuple(round(v / MM, 6) + 0.0 for v in move.center)


# -- frames ---------------------------------------------------------------------------------
def test_trans_rot_compose_as_the_manual_describes():
    prog = run('G0 X0 Y0 Z0\n'
               'TRANS X10 Y5\n'
               'AROT Z90\n'            # additive: turns about the translated origin
               'G1 X2 Y0 F100\n'       # (2,0) -> turned (0,2) -> + (10,5) = (10,7)
               'ATRANS X1\n'           # along the turned X: +1 on machine Y -> origin (10,6)
               'G1 X0 Y0\n'            # (10,6)
               'ROT Z90\n'             # absolute: replaces the frame (no translation left)
               'G1 X1 Y0\n'            # (0,1)
               'TRANS\n'               # clears the programmable frame
               'G1 X3 Y4\n'            # (3,4)
               'M30\n')
    assert ends(prog)[1:] == [(10.0, 7.0, 0.0), (10.0, 6.0, 0.0), (0.0, 1.0, 0.0),
                              (3.0, 4.0, 0.0)]


def test_missing_axes_keep_their_program_value_in_the_new_frame():
    # At machine (0,0,0); after TRANS X10 the program position is X=-10: "G1 Y5" keeps
    # X=-10 in the program, which is machine X=0 -- the tool does not move in X.
    prog = run('G1 X0 Y0 Z0 F100\nTRANS X10\nG1 Y5\nG1 X0\nM30\n')
    assert ends(prog)[1:] == [(0.0, 5.0, 0.0), (10.0, 5.0, 0.0)]


def test_supa_g53_g153_leave_out_frame_and_offset_for_their_block():
    prog = run('TRANS X100 Y50\nG0 X0 Y0 Z0\nSUPA G0 X1\nG153 G0 Y2\nG53 G0 Z3\n'
               'G0 X0\nM30\n')
    # (100,50,0); SUPA: machine X=1 (Y, Z kept); G153 Y=2; G53 Z=3; then X0 in the frame
    assert ends(prog) == [(100.0, 50.0, 0.0), (1.0, 50.0, 0.0), (1.0, 2.0, 0.0),
                          (1.0, 2.0, 3.0), (100.0, 2.0, 3.0)]


def test_scale_and_mirror_and_a_mirrored_arc_turns_the_other_way():
    prog = run('SCALE X2 Y2\nG0 X1 Y1 Z0\n'           # (2,2)
               'MIRROR X0\nG0 X0 Y0\n'                # mirror replaces scale: (0,0)
               'G2 X10 Y0 CR=5 F100\n'                # program: CW half circle over (5,5)
               'M30\n')
    assert ends(prog)[:3] == [(2.0, 2.0, 0.0), (0.0, 0.0, 0.0), (-10.0, 0.0, 0.0)]
    arc = [m for m in prog.moves if m.kind in (MoveKind.ARC_CW, MoveKind.ARC_CCW)][0]
    # mirrored in X the arc runs from (0,0) over (-5,5) to (-10,0): counter-clockwise
    assert arc.kind == MoveKind.ARC_CCW
    assert centre_mm(arc) == (-5.0, 0.0, 0.0)


def test_settable_offset_is_zero_with_a_warning():
    prog = run('G57\nG0 X1 Y2 Z3\nM30\n')
    assert ends(prog) == [(1.0, 2.0, 3.0)]
    assert any('G57' in w and 'taken as 0' in w for w in prog.warnings)


# -- units, absolute/incremental --------------------------------------------------------------
def test_ac_ic_g90_g91():
    prog = run('G90 G1 X10 F100\nG1 X=IC(5)\nG91 G1 X5\nG1 X=AC(1)\nG1 Y2\nG90 Y1\nM30\n')
    assert [p[:2] for p in ends(prog)] == [
        (10.0, 0.0), (15.0, 0.0), (20.0, 0.0), (1.0, 0.0), (1.0, 2.0), (1.0, 1.0)]


def test_g700_converts_feed_g70_only_lengths():
    prog = run('G700 G1 X1 F10\nG70 G1 X2 F10\nG710 G1 X3\nM30\n')
    lines = [m for m in prog.moves if m.kind == MoveKind.LINEAR]
    assert [round(m.end[0] / MM, 6) for m in lines] == [25.4, 50.8, 3.0]
    # G700: 10 inch/min = 254 mm/min; G70 leaves F in the basic system's mm/min
    assert lines[0].feed_m_s == pytest.approx(0.254 / 60)
    assert lines[1].feed_m_s == pytest.approx(0.010 / 60)


# -- arcs ----------------------------------------------------------------------------------
@pytest.mark.parametrize('cr, centre, sweep_deg', [
    (10, (10.0, 0.0), 90.0),     # short arc: centre right of the chord (0,0)->(10,10)
    (-10, (0.0, 10.0), 270.0),   # over 180 degrees: centre on the other side
])
def test_cr_arc(cr, centre, sweep_deg):
    prog = run(f'G0 X0 Y0 Z0\nG2 X10 Y10 CR={cr} F100\nM30\n')
    arc = prog.moves[1]
    assert arc.kind == MoveKind.ARC_CW
    assert centre_mm(arc)[:2] == pytest.approx(centre)
    # a CW arc of radius 10 over sweep_deg: length 10 * sweep
    assert arc.length_m / MM == pytest.approx(10 * math.radians(sweep_deg))


def test_cip_arc_through_an_intermediate_point():
    # (0,0) -> (5,5) -> (10,0): the circle of radius 5 about (5,0), clockwise (over the top)
    prog = run('G0 X0 Y0 Z0\nCIP X10 Y0 I1=5 J1=5 F100\nM30\n')
    arc = prog.moves[1]
    assert arc.kind == MoveKind.ARC_CW
    assert centre_mm(arc) == pytest.approx((5.0, 0.0, 0.0))
    assert arc.length_m / MM == pytest.approx(5 * math.pi)


def test_ct_arc_tangent_to_the_previous_line():
    # along +X to (10,0), then CT to (20,10): tangent +X at (10,0), so the centre lies on
    # x=10; r^2 = 10^2 + (r-10)^2 -> r=10, centre (10,10); a CCW quarter circle
    prog = run('G0 X0 Y0 Z0\nG1 X10 F100\nCT X20 Y10\nM30\n')
    arc = prog.moves[2]
    assert arc.kind == MoveKind.ARC_CCW
    assert centre_mm(arc) == pytest.approx((10.0, 10.0, 0.0))
    assert arc.length_m / MM == pytest.approx(10 * math.pi / 2)


def test_ij_incremental_and_ac_centre():
    # from (30,20): I=-10 J0 (incremental) and I=AC(20) J=AC(20) name the same centre
    for centre in ('I-10 J0', 'I=AC(20) J=AC(20)'):
        prog = run(f'G0 X30 Y20 Z0\nG3 X10 Y20 {centre} F100\nM30\n')
        assert centre_mm(prog.moves[1]) == pytest.approx((20.0, 20.0, 0.0))
        assert prog.moves[1].kind == MoveKind.ARC_CCW


# -- polar coordinates -----------------------------------------------------------------------
def test_polar_moves_about_the_pole():
    prog = run('G0 X0 Y0 Z0\n'
               'G111 X10 Y10\n'          # pole (10,10), absolute
               'G1 AP=90 RP=5 F100\n'    # (10,15)
               'G1 AP=IC(90)\n'          # angle 180, radius kept: (5,10)
               'G2 AP=0\n'               # arc about the pole, clockwise over the top, (15,10)
               'G110 X5\n'               # pole relative to the last point: (20,10)
               'G1 AP=270 RP=2\n'        # (20,8)
               'M30\n')
    pts = ends(prog)
    assert [c for p in pts[1:] for c in p[:2]] == pytest.approx([10, 15, 5, 10, 15, 10, 20, 8])
    arc = prog.moves[3]
    assert arc.kind == MoveKind.ARC_CW and centre_mm(arc)[:2] == pytest.approx((10, 10))


# -- dwells ----------------------------------------------------------------------------------
def test_g4_f_seconds_and_s_revolutions():
    prog = run('S1200 M3\nG4 F1.5\nG4 S30\nM30\n')
    dwells = [m.dwell_s for m in prog.moves if m.kind == MoveKind.DWELL]
    assert dwells == pytest.approx([1.5, 30 / 1200 * 60])   # 30 rev at 1200 rev/min: 1.5 s


def test_g4_s_without_spindle_speed_is_refused():
    with pytest.raises(GcodeError, match='no spindle speed'):
        run('G4 S10\n')


# -- drilling cycles -------------------------------------------------------------------------
def test_cycle81_approach_depth_and_retract():
    prog = run('G0 X10 Y20 Z50\nF100\nCYCLE81(30, 0, 2, -10)\nCYCLE81(30, 0, 2, , 5)\nM30\n')
    # G0 to RFP+SDIS = 2, G1 to DP = -10, G0 to RTP = 30; then DPR=5: depth RFP-5 = -5
    assert ends(prog)[1:] == [(10, 20, 2), (10, 20, -10), (10, 20, 30),
                              (10, 20, 2), (10, 20, -5), (10, 20, 30)]
    kinds = [m.kind for m in prog.moves if m.kind != MoveKind.STOP][1:4]
    assert kinds == [MoveKind.RAPID, MoveKind.LINEAR, MoveKind.RAPID]


def test_cycle82_dwells_at_depth():
    prog = run('G0 X0 Y0 Z10\nF100 S600 M3\nCYCLE82(10, 0, 1, -3, , 2)\n'
               'CYCLE82(10, 0, 1, -3, , -6)\nM30\n')
    dwells = [m.dwell_s for m in prog.moves if m.kind == MoveKind.DWELL]
    assert dwells == pytest.approx([2.0, 6 / 600 * 60])   # -6: six revolutions at 600/min


def test_cycle83_chip_removal_steps():
    # RTP 30, RFP 0, SDIS 2, DP -10; FDEP -4; DAM 1; VARI 1 (chip removal)
    # steps from the start plane 2: first to -4 (6 mm), then 6-1 = 5 mm to -9, then to -10.
    # After each step but the last: G0 to 2, G0 back to 0.6 mm above the step's end
    # (anticipation distance for a depth of 12 mm <= 30 mm).
    prog = run('G0 X0 Y0 Z40\nF100\nCYCLE83(30, 0, 2, -10, , -4, , 1, 0, 0, 1, 1)\nM30\n')
    z = [p[2] for p in ends(prog)][1:]
    assert z == pytest.approx([2, -4, 2, -3.4, -9, 2, -8.4, -10, 30])


def test_cycle83_chip_breaking_backs_off_1mm():
    prog = run('G0 X0 Y0 Z40\nF100\nCYCLE83(30, 0, 2, -10, , -4, , 0, 0, 0, 1, 0)\nM30\n')
    z = [p[2] for p in ends(prog)][1:]
    # DAM 0: equal steps of 6 mm: -4, then back off to -3 at the feed, on to -10 (clipped),
    # retract in rapid
    assert z == pytest.approx([2, -4, -3, -10, 30])
    kinds = [m.kind for m in prog.moves if m.kind != MoveKind.STOP][1:]
    assert kinds == [MoveKind.RAPID, MoveKind.LINEAR, MoveKind.LINEAR, MoveKind.LINEAR,
                     MoveKind.RAPID]


def test_mcall_runs_the_cycle_after_each_move_until_cancelled():
    prog = run('G0 X0 Y0 Z10\nF100\nMCALL CYCLE81(10, 0, 1, -2)\nG0 X5\nX15\nMCALL\n'
               'G0 X30\nM30\n')
    assert ends(prog)[1:] == [(5, 0, 10), (5, 0, 1), (5, 0, -2), (5, 0, 10),
                              (15, 0, 10), (15, 0, 1), (15, 0, -2), (15, 0, 10),
                              (30, 0, 10)]


def test_holes1_and_holes2_with_mcall():
    prog = run('G0 X0 Y0 Z10\nF100\nMCALL CYCLE81(10, 0, 1, -2)\n'
               'HOLES1(0, 0, 0, 10, 5, 3)\n'          # x = 10, 15, 20 on y = 0
               'HOLES2(0, 0, 10, 90, 90, 2)\n'        # radius 10 at 90 and 180 degrees
               'MCALL\nM30\n')
    holes = [c for p in ends(prog) if p[2] == -2.0 for c in p[:2]]
    assert holes == pytest.approx([10, 0, 15, 0, 20, 0, 0, 10, -10, 0], abs=1e-9)


def test_cycle_in_a_frame():
    prog = run('TRANS X100\nAROT Z90\nG0 X10 Y0 Z5\nF100\nCYCLE81(5, 0, 1, -1)\nM30\n')
    # (10,0) turned by 90 degrees is (0,10), plus (100,0): the hole is at (100,10)
    assert set(p[:2] for p in ends(prog)) == {(100.0, 10.0)}


def test_cycle832_is_accepted_with_a_warning():
    prog = run('CYCLE832(0.01, 1)\nG0 X1\nM30\n')
    assert any('CYCLE832' in w for w in prog.warnings)


# -- variables and control flow ----------------------------------------------------------------
def test_loops_and_branches():
    prog = run('DEF INT CNT\n'
               'FOR CNT=1 TO 3\n  G1 X=CNT*10 F100\nENDFOR\n'          # X 10, 20, 30
               'WHILE R1<2\n  R1=R1+1\n  G1 Y=R1\nENDWHILE\n'          # Y 1, 2
               'IF R1==2\n  G1 Z-1\nELSE\n  G1 Z-99\nENDIF\n'           # Z -1
               'REPEAT\n  R2=R2+1\nUNTIL R2==3\n'
               'G1 Z=-R2\n'                                              # Z -3
               'BACK:\nR3=R3+1\nIF R3<2 GOTOB BACK\n'
               'G1 X=R3*100\n'                                           # X 200
               'LOOP\n  R4=R4+1\n  IF R4>=4 GOTOF OUT\nENDLOOP\nOUT:\n'
               'G1 Y=R4\n'                                               # Y 4
               'GOTOF END_1\nG1 X999\nEND_1: M30\n')
    assert ends(prog) == [(10, 0, 0), (20, 0, 0), (30, 0, 0), (30, 1, 0), (30, 2, 0),
                          (30, 2, -1), (30, 2, -3), (200, 2, -3), (200, 4, -3)]


def test_def_types_and_expressions():
    prog = run('DEF REAL WID=2.5, LEN\nDEF INT NUM=7\nDEF BOOL OK=TRUE\n'
               'LEN=SQRT(POT(3)+POT(4)) + 7 DIV 2 + 7 MOD 4\n'   # 5 + 3 + 3 = 11
               'NUM=NUM/2\n'                                        # INT: 3.5 rounds to 4
               'IF OK AND (NUM==4) GOTOF GO\nG1 X999\nGO:\n'
               'G1 X=LEN Y=WID*2 Z=SIN(30)*-2 F100\nM30\n')
    assert ends(prog) == [(11, 5, -1)]


def test_section_repeats():
    prog = run('G1 X0 F100\nSTART: G91 G1 X1\nG1 Y1\nEND_P: G90\n'
               'REPEAT START END_P P=2\n'         # the section twice more
               'REPEATB START P2\n'               # the START line alone, twice
               'M30\n')
    xs = [p[:2] for p in ends(prog)]
    assert xs == [(0, 0), (1, 0), (1, 1), (2, 1), (2, 2), (3, 2), (3, 3), (4, 3), (5, 3)]


# -- subprograms -----------------------------------------------------------------------------
def test_subprograms_by_name_with_parameters(tmp_path: Path):
    (tmp_path / 'POCKET_SIDE.SPF').write_text(
        'PROC POCKET_SIDE(REAL LEN, INT TIMES)\nDEF INT PASS\n'
        'FOR PASS=1 TO TIMES\n  G91 G1 X=LEN\nENDFOR\nG90\nRET\n')
    (tmp_path / 'L100.SPF').write_text('%_N_L100_SPF\nG91 G1 Y1\nG90\nM17\n')
    sub = tmp_path / 'lib'
    sub.mkdir()
    (sub / 'up.spf').write_text('G1 Z5\nM17\n')
    main = tmp_path / 'MAIN.MPF'
    main.write_text('G1 X0 Y0 Z0 F100\nPOCKET_SIDE(2.5, 2)\nL100 P2\nCALL "UP"\n'
                    'POCKET_SIDE(1)\nM30\n')
    prog = load_gcode(main, search_path=[sub])
    # X +2.5 twice, Y +1 twice, Z to 5, then TIMES missing (0): FOR 1 TO 0 does not run
    assert ends(prog)[1:] == [(2.5, 0, 0), (5, 0, 0), (5, 1, 0), (5, 2, 0), (5, 2, 5)]
    assert prog.moves[1].line == 2         # moves of a subprogram count at the call line


def test_modal_subprogram_call(tmp_path: Path):
    (tmp_path / 'DOWN.SPF').write_text('G91 G1 Z-1\nG90\nRET\n')
    main = tmp_path / 'M.MPF'
    main.write_text('G0 X0 Y0 Z0\nF100\nMCALL DOWN\nG0 X1\nG0 X2\nMCALL\nG0 X3\nM30\n')
    assert ends(load_gcode(main)) == [(0, 0, 0), (1, 0, 0), (1, 0, -1), (2, 0, -1),
                                      (2, 0, -2), (3, 0, -2)]


def test_program_sections_in_one_file(tmp_path: Path):
    main = tmp_path / 'TWO.MPF'
    main.write_text('%_N_TWO_MPF\nG1 X1 F100\nSIDE\nM30\n%_N_SIDE_SPF\nG1 Y7\nM17\n')
    assert ends(load_gcode(main)) == [(1, 0, 0), (1, 7, 0)]


# -- the dialect chosen from the file ---------------------------------------------------------
@pytest.mark.parametrize('name, text', [
    ('PART.MPF', 'G1 X1 F100\nM30\n'),
    ('part.spf', 'G1 X1 F100\nM30\n'),
    ('part.nc', '%_N_PART_MPF\nG1 X1 F100\nM30\n'),
    ('part.nc', '; header\nG90 G710\nG1 X1 F100\nM30\n'),
])
def test_dialect_from_the_file(tmp_path: Path, name, text):
    path = tmp_path / name
    path.write_text(text)
    for prog in (load_gcode(path), parse_gcode(text, file=str(path))):
        assert ends(prog) == [(1, 0, 0)]
        assert any('read in the sinumerik dialect' in w for w in prog.warnings)
    assert [m.end for m in iter_moves(path)] == [m.end for m in load_gcode(path).moves]


def test_a_linuxcnc_program_is_not_taken_for_sinumerik(tmp_path: Path):
    path = tmp_path / 'plain.ngc'
    path.write_text('(G710 in a comment)\nG1 X1 F100\nM2\n')
    prog = load_gcode(path)
    assert not any('sinumerik' in w for w in prog.warnings)


def test_latin1_and_utf8_umlauts_in_comments(tmp_path: Path):
    for encoding in ('latin-1', 'utf-8'):
        path = tmp_path / f'UML_{encoding}.MPF'
        path.write_bytes(';Äußere Bahn, Überschneidung\nG1 X1 F100 ;Schritt ä\nM30\n'
                         .encode(encoding))
        assert ends(load_gcode(path)) == [(1, 0, 0)]
        assert [m.end for m in iter_moves(path)] == [(1 * MM, 0.0, 0.0), (1 * MM, 0.0, 0.0)]


def test_named_tools_and_machine_words_pass():
    prog = run('T="FRAESER_10St"\nM6\nD1\nG64 SOFT FFWON\nMSG("Schlichten")\nSTOPRE\n'
               'GROUP_BEGIN(0,"A",0,0)\nWORKPIECE(,"",,"BOX",0,2,-30,-80,-2,-2,184,170)\n'
               'G0 X1\nGROUP_END(0,0)\nM30\n')
    assert ends(prog) == [(1, 0, 0)]
    assert any('FRAESER_10St' in w for w in prog.warnings)


def test_proc_save_restores_frame_units_and_plane(tmp_path: Path):
    (tmp_path / 'SHIFTED.SPF').write_text('PROC SHIFTED SAVE\nTRANS X100\nG91 G18\n'
                                          'G1 X1\nRET\n')
    (tmp_path / 'PLAIN.SPF').write_text('PROC PLAIN\nTRANS X100\nRET\n')
    main = tmp_path / 'M.MPF'
    main.write_text('G17 G90 G1 X0 Y0 Z0 F100\nSHIFTED\nG1 X5\nG2 X15 Y0 CR=5\n'
                    'PLAIN\nG1 X5\nM30\n')
    prog = load_gcode(main)
    # in SHIFTED: G91 X1 from program X=-100 (machine 0) -> machine 1; after its return the
    # frame, G90 and G17 are back: X5 is machine 5, the arc is in XY; PLAIN keeps its frame:
    # X5 -> machine 105
    assert [p[0] for p in ends(prog)] == [0.0, 1.0, 5.0, 15.0, 105.0]
    assert prog.moves[3].plane == 17


def test_g1_is_the_initial_motion_mode():
    # Siemens' default setting of G group 1 is G1 (the list of G functions, "Def.")
    prog = run('F100\nX10\nM30\n')
    assert [m.kind for m in prog.moves][:1] == [MoveKind.LINEAR]


def test_turn_gives_extra_full_turns_of_a_helix():
    # a full circle of radius 5 (I5 from (0,0): centre (5,0)) with TURN=2: three turns, Z
    # falling 3 mm; the path is sqrt((3 * 2 pi 5)^2 + 3^2)
    prog = run('G0 X0 Y0 Z0\nG3 X0 Y0 Z-3 I5 TURN=2 F100\nM30\n')
    arc = prog.moves[1]
    assert arc.turns == 2
    assert arc.length_m / MM == pytest.approx(math.hypot(3 * 2 * math.pi * 5, 3))


def test_cr_arc_in_the_zx_plane():
    # G18: the arc runs in Z-X; from (0,0,0) to X10 Z0 with radius 5 over the top (Z+ side
    # for G2 seen from +Y): centre (5, 0, 0), a half circle of length 5 pi
    prog = run('G18 G0 X0 Y0 Z0\nG2 X10 Z0 CR=5 F100\nM30\n')
    arc = prog.moves[1]
    assert arc.plane == 18 and arc.kind == MoveKind.ARC_CW
    assert centre_mm(arc) == pytest.approx((5.0, 0.0, 0.0))
    assert arc.length_m / MM == pytest.approx(5 * math.pi)
