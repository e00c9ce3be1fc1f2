"""Roll-ups: operation names of the CAM formats, energy per operation, subroutine, tool, axis."""
import math
from pathlib import Path

import pytest

from feed_axis_energy.gcode.load import iter_moves
from feed_axis_energy.gcode.context import operation_name
from feed_axis_energy.machine.file import load_machine, machine_to_dict
from feed_axis_energy.sim.stream import simulate_stream
from shared_data import need_shared

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize('line,name', [
    ('(2D ADAPTIVE1)', '2D ADAPTIVE1'),                        # Fusion 360
    ('(begin operation: Profile)', 'Profile'),                 # FreeCAD linuxcnc post
    ('(Begin operation: 3mm Endmill001)', '3mm Endmill001'),   # FreeCAD script_module
    ('(finish operation: Profile)', None),
    ('(Block-name: Fixture)', None),
    ('; Operation:    0', 'operation 0'),                      # jscut
    ('; Type:         Engrave', None),
    ('( holes )', 'holes'),                                    # CamBam
    ('( T3 : 0.125 )', None),
    ('(T2  D=3.175 CR=0. - ZMIN=-5. - FLAT END MILL)', None),  # Fusion tool list
    ('(Toolpath:Projected01)', 'Projected01'),
    ('(MSG, Attach the probe tool)', None),                    # LinuxCNC active comments
    ('(debug, x=#1)', None),
    ('(' + 'x' * 61 + ')', None),
    # Mastercam (operation comments are plain lines; header and tool lines are not names)
    ('(CONTOUR)', 'CONTOUR'),
    ('(OD ROUGH RIGHT - 80 DEG.)', 'OD ROUGH RIGHT - 80 DEG.'),
    ('(PROGRAM NAME - HELLOWORLD)', None),
    ('(MATERIAL - ALUMINUM MM - 2024)', None),
    ('(POST DEV - IN-HOUSE SOLUTIONS)', None),
    ('( DATE - NOV. 15 2019 )', None),
    ('(T1|.25 SPOT|H1|D1|TOOL DIA. - .25)', None),
    ('( 1/16 FLAT ENDMILL TOOL - 1 DIA. OFF. - 1 LEN. - 1 DIA. - .0625)', None),
    ('(TOOL - 7 DIA. OFF. - 7 LEN. - 7 DIA. - .5)', None),
    ('(TOOL - 1 OFFSET - 1)', None),
    ('( MACHINE GROUP-1 )', None),
    # Estlcam's operation start text, and its header
    ('(No. 1: Engraving 1)', 'Engraving 1'),
    ('(No. 12: Pocket 3)', 'Pocket 3'),
    ('(Required tools:)', None),
    # Vectric-style posts
    ('(Toolpath:- Profile 1)', 'Profile 1'),
    ('(Toolpath: Pocket 2 Tool: 6mm End Mill)', 'Pocket 2'),
    ('(Toolpaths used in this file:)', None),
])
def test_operation_names(line, name):
    assert operation_name(line) == name


# Two operations with their own tool run the same subroutine from the same point at rest:
# by symmetry they take the same energy; the dwell between them is roughing's time.
PROGRAM = """o100 sub
  G1 X50 F3000
  G1 Y20
  G2 X30 Y40 I-20 J0
  G0 Z5
  G0 X0 Y0 Z0
o100 endsub
(Program header comment)
G21 G90 G94 G61
G0 X0 Y0 Z0
(Roughing)
T1 M6
o100 call
G4 P0.2
(Finishing)
T2 M6
o100 call
M30
"""


def _run(tmp_path, chunk_samples, machine_file='three_axis_mill.yaml'):
    machine = load_machine(REPO / 'config' / machine_file)
    path = tmp_path / 'ops.ngc'
    path.write_text(PROGRAM)
    stream = iter_moves(path, home=machine.home_point(), tools=dict(machine.gcode.tools))
    summary, _ = simulate_stream(stream, machine, file=stream.file, rollup=True,
                                 context=stream.context, chunk_samples=chunk_samples)
    return summary


@pytest.mark.parametrize('chunk_samples', [257, 100_000])
def test_operations_tools_and_subroutines(tmp_path, chunk_samples):
    s = _run(tmp_path, chunk_samples)
    roll = s['rollups']
    total, duration = s['energy_j']['total'], s['duration_s']
    for group in ('operation', 'subroutine', 'tool'):
        assert math.isclose(math.fsum(r['energy_j'] for r in roll[group]), total,
                            rel_tol=1e-9)
        assert math.isclose(math.fsum(r['duration_s'] for r in roll[group]), duration,
                            rel_tol=1e-9)
    op = {r['name']: r for r in roll['operation']}
    assert set(op) == {'Roughing', 'Finishing'}      # the header comment names nothing
    # equal but for where the 1 ms sample grid falls in each (discretisation)
    assert math.isclose(op['Roughing']['energy_j'], op['Finishing']['energy_j'],
                        rel_tol=1e-4)
    assert op['Roughing']['duration_s'] == pytest.approx(op['Finishing']['duration_s'] + 0.2,
                                                         abs=2e-3)
    tool = {r['name']: r['energy_j'] for r in roll['tool']}
    assert tool == {'T1': op['Roughing']['energy_j'], 'T2': op['Finishing']['energy_j']}
    sub = {r['name']: r for r in roll['subroutine']}
    # the main program only dwells (G0 X0 Y0 Z0 from the start point does not move)
    assert set(sub) == {'o<100>', '(main program)'}
    # (but for the interval into the dwell: its end sample is the dwell's)
    assert abs(sub['(main program)']['energy_j']) < 1e-5 * total
    assert sub['(main program)']['duration_s'] == pytest.approx(0.2, abs=2e-3)
    axis = {r['name']: r for r in roll['axis']}
    assert {a: axis[a]['energy_j'] for a in 'XYZ'} == {a: s['energy_j'][a] for a in 'XYZ'}
    assert 0.0 < axis['Z']['duration_s'] < axis['X']['duration_s'] < duration


@pytest.mark.parametrize('chunk_samples', [257, 100_000])
def test_electrical_energy_per_operation_adds_up(tmp_path, chunk_samples):
    """With declared drives every roll-up item has its energy at the motor terminals and at
    the supply side; operations, subroutines and tools add up to the electrical totals
    (cabinet standby included), the axes are the summary's, and the dwell in the main
    program draws electrical energy while the shafts take none."""
    s = _run(tmp_path, chunk_samples, 'three_axis_mill_drives.yaml')
    machine = load_machine(REPO / 'config' / 'three_axis_mill_drives.yaml')
    e = s['electrical']
    roll = s['rollups']
    for key in ('motor_energy_j', 'supply_energy_j'):
        for group in ('operation', 'subroutine', 'tool'):
            assert math.isclose(math.fsum(r[key] for r in roll[group]), e[key]['total'],
                                rel_tol=1e-9), (key, group)
        axis = {r['name']: r[key] for r in roll['axis']}
        assert axis == {a: e[key][a] for a in 'XYZ'}
    for r in roll['operation']:
        # only losses come in between the terminals and the supply (none negative)
        assert r['supply_energy_j'] >= r['motor_energy_j'] + e['cabinet_standby_w'] * (
            r['duration_s']) - 1e-9
    sub = {r['name']: r for r in roll['subroutine']}
    standby = e['cabinet_standby_w'] + sum(a['drive']['standby_w'] for a in
                                           machine_to_dict(machine)['axes'].values())
    main = sub['(main program)']
    # at standstill the shafts take nothing, but the standby runs and the vertical Z
    # holds its carriage against gravity (copper losses): more than the standby alone
    assert abs(main['energy_j']) < 1e-5 * s['energy_j']['total']
    assert main['motor_energy_j'] > 0.0
    assert main['supply_energy_j'] > standby * main['duration_s']


def test_chunking_does_not_change_the_rollups(tmp_path):
    small, large = _run(tmp_path, 257), _run(tmp_path, 100_000)
    for group, items in large['rollups'].items():
        got = {r['name']: r for r in small['rollups'][group]}
        for r in items:
            assert got[r['name']]['energy_j'] == pytest.approx(r['energy_j'], rel=1e-9)
            assert got[r['name']]['duration_s'] == pytest.approx(r['duration_s'], rel=1e-9)


@pytest.mark.parametrize('name,operations,tools', [
    # CamBam: section comments after a tool list in the header
    ('jbeuckm__thrust_bucket/cambam__load_cell_spacer.nc', {'holes', 'cutout'}, {3}),
    # a CAMotics script: section comments and three tool changes
    ('CauldronDevelopmentLLC__CAMotics/examples__botomata_bottom__botomata_bottom.nc',
     {'Pockets', 'Profiles', 'Cutout', 'Cleanup'}, {1, 2, 3}),
    # jscut: "; Operation: 0", then step notes ("; plunge") that name nothing
    ('cncjs__cncjs/examples__gcode__jsdc.gcode', {'operation 0'}, set()),
])
def test_corpus_operations(name, operations, tools):
    corpus = need_shared('corpus', 'gcode')
    stream = iter_moves(corpus / name, ignore_axes=('A', 'B', 'C'))
    n = sum(1 for _ in stream)
    used = {stream.context.table[i] for _, i in stream.context.marks} | {
        stream.context.table[stream.context.index_at(n - 1)]}
    assert {op for op, _, _ in used} - {''} == operations
    assert {tool for _, _, tool in used} - {0} == tools


def test_axis_time_is_the_time_the_axis_moves(tmp_path):
    machine = load_machine(REPO / 'config' / 'three_axis_mill.yaml')
    path = tmp_path / 'x.ngc'
    path.write_text('G21 G90 G94 G61\nG1 X100 F3000\nG4 P0.5\nG1 X0\nM30\n')
    stream = iter_moves(path, home=machine.home_point())
    s, _ = simulate_stream(stream, machine, file=stream.file, rollup=True,
                           context=stream.context, chunk_samples=300)
    axis = {r['name']: r['duration_s'] for r in s['rollups']['axis']}
    # everything but the 0.5 s dwell (one sample interval at each end of it)
    assert axis['X'] == pytest.approx(s['duration_s'] - 0.5, abs=2.5e-3)
    assert axis['Y'] == 0.0 and axis['Z'] == 0.0


def _operations(tmp_path, text):
    """Operation of every move, in order, and the tools used, of a hand-written program."""
    path = tmp_path / 'p.nc'
    path.write_text(text)
    stream = iter_moves(path)
    n = sum(1 for _ in stream)
    ctx = stream.context
    ops = [ctx.table[ctx.index_at(i)][0] for i in range(n)]
    return [op for i, op in enumerate(ops) if i == 0 or op != ops[i - 1]], {
        ctx.table[ctx.index_at(i)][2] for i in range(n)}


# as Mastercam's generic Fanuc post writes a program: header after the program number, a
# tool line and the operation comment before each tool change
MASTERCAM = """%
O1000
(PROGRAM NAME - HELLOWORLD)
(DATE=DD-MM-YY - 30-06-05 TIME=HH:MM - 19:37)
(MCX FILE - C:\\JOBS\\HELLO.MCX-8)
(MATERIAL - ALUMINUM MM - 2024)
(T1|.25 SPOT|H1|D1|TOOL DIA. - .25)
N10G21
N20G0G17G40G49G80G90
( 1/16 FLAT ENDMILL TOOL - 1 DIA. OFF. - 1 LEN. - 1 DIA. - 1.5)
(CONTOUR)
N60T1M6
N70G0G90X0.Y10.S5000M3
N100G1Z-.5F50.
N110Y0.F500.
N120G0Z5.
(TOOL - 2 DIA. OFF. - 2 LEN. - 2 DIA. - 3.)
( MACHINE GROUP-1 )
(POCKET - STANDARD)
N130T2M6
N140G0X5.Y5.
N150G1Z-1.F300.
N160X20.
M30
%
"""

# Estlcam's default post: header before the first code, "(No. N: NAME)" per operation
ESTLCAM = """(Project 004)
(Created by Estlcam version 11 build 11.245)
(Machining time about 00:00:07 hours)

(Required tools:)
(End mill 3mm)
G21
G90
G94
M03 S24000
G00 Z5.0000


(No. 1: Engraving 1)
G00 X0.0000 Y25.4000
G01 Z-1.0000 F600
G01 Y0.0000 F1200
G00 Z5.0000

(No. 2: Pocket 1)
G00 X10 Y10
G01 Z-1.0000 F600
(plunge done)
G01 X20 F1200
G00 Z5.0000
M05
M30
"""

# a Vectric-style post: toolpath name after the tool change, then its notes
VECTRIC = """( Material Size)
( X= 100.000, Y= 100.000, Z= 10.000)
(Toolpaths used in this file:)
(Profile 1)
G00 G21 G17 G90 G40 G49 G80
T1 M6
(Toolpath:- Profile 1)
(cut the outline)
G0 X0 Y0 Z5
G1 Z-1 F300
G1 X50 F1200
G0 Z5
T2 M6
(Toolpath:- Pocket 1)
G0 X10 Y10
G1 Z-1 F300
G1 X20 F1200
M30
"""


@pytest.mark.parametrize('text,operations,tools', [
    (MASTERCAM, ['', 'CONTOUR', 'POCKET - STANDARD'], {0, 1, 2}),
    (ESTLCAM, ['', 'Engraving 1', 'Pocket 1'], {0}),
    (VECTRIC, ['', 'Profile 1', 'Pocket 1'], {0, 1, 2}),
])
def test_cam_programs_operations(tmp_path, text, operations, tools):
    assert _operations(tmp_path, text) == (operations, tools)
