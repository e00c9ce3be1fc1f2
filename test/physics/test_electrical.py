"""Electrical power from the declared drives: hand calculations and exact bookkeeping."""
import math
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.physics.breakdown import BRAKING_CAUSE, FIXED_CAUSES
from feed_axis_energy.physics.electrical import ELECTRICAL_CAUSES
from feed_axis_energy.gcode.load import load_gcode, parse_gcode
from feed_axis_energy.units import GRAVITY_M_S2
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.machine.mass import moved_mass_kg
from feed_axis_energy.plan.fromsamples import motion_from_samples
from feed_axis_energy.sim.stream import simulate_stream
from feed_axis_energy.sim.simulate import line_table, simulate_motion, simulate_program, summarize

REPO = Path(__file__).resolve().parents[2]
DRIVES = REPO / 'config' / 'three_axis_mill_drives.yaml'

MIXED = """G21 G90 G94 G17 G64
G0 X0 Y0 Z20
G1 Z-2 F600
G1 X30 Y5 F2400
G2 X40 Y15 I0 J10
G3 X30 Y25 I-10 J0
G4 P0.5
G1 X0 Y0 F3000
G0 Z40
M30
"""

KT, R, P0, RPM, SHARE, STANDBY, ETA, CABINET = 1.2, 2.0, 30.0, 3000.0, 0.4, 12.0, 0.9, 50.0


def _one_axis(*, inclination=0.0, coulomb=100.0, braking='regenerative', limit=None):
    """The demonstrator's axis with a Coulomb loss, a drive and a cabinet (values above)."""
    data = machine_to_dict(load_machine(REPO / 'config' / 'demonstrator.yaml'))
    axis = data['axes']['X']
    axis['inclination_deg'] = inclination
    axis['loss'] = {'model': 'coulomb_viscous', 'coulomb_n': coulomb, 'viscous_n_s_m': 0.0,
                    'mu': 0.0}
    axis['drive'] = {'kt_nm_a': KT, 'resistance_ohm': R, 'resistance_between': 'terminals',
                     'iron': {'no_load_w': P0, 'speed_rpm': RPM, 'eddy_share': SHARE},
                     'standby_w': STANDBY, 'converter_efficiency': ETA}
    if limit is not None:
        axis['drive']['regeneration_limit_w'] = limit
    data['braking'] = braking
    data['supply'] = {'standby_w': CABINET, 'measured_at': 'supply'}
    return machine_from_dict(data)


def _constant_speed(machine, v, seconds, *, n=2001):
    t = np.linspace(0.0, seconds, n)
    pos = (0.1 + v * t)[:, None]
    motion = motion_from_samples(t, pos, axes=('X',), vel=np.full((n, 1), v),
                                 acc=np.zeros((n, 1)))
    result = simulate_motion(motion, machine)
    return result, summarize(result)


def _iron_w(omega):
    w0 = RPM * 2.0 * math.pi / 60.0
    return (1.0 - SHARE) * P0 * abs(omega) / w0 + SHARE * P0 * (omega / w0) ** 2


def test_constant_torque_hand_calculation():
    # horizontal, constant speed: F = coulomb, M = F lead / (2 pi) (eta = 1), omega = 2 pi v / lead
    machine = _one_axis()
    v, seconds, coulomb = 0.1, 2.0, 100.0
    _, s = _constant_speed(machine, v, seconds)
    lead = machine.axis('X').screw.lead_m
    torque = coulomb * lead / (2.0 * math.pi)
    omega = 2.0 * math.pi * v / lead
    copper_w = 1.5 * R * (torque / KT) ** 2            # IEC 60034-2-1, R between terminals
    iron_w = _iron_w(omega)
    motor_w = torque * omega + copper_w + iron_w
    e = s['electrical']
    by = e['energy_by_cause_j']
    assert by['copper']['X'] == pytest.approx(copper_w * seconds, rel=1e-9)
    assert by['iron']['X'] == pytest.approx(iron_w * seconds, rel=1e-9)
    assert by['friction']['X'] == pytest.approx(coulomb * v * seconds, rel=1e-9)
    assert by['converter']['X'] == pytest.approx(motor_w * (1.0 / ETA - 1.0) * seconds,
                                                 rel=1e-9)
    assert by['standby']['X'] == pytest.approx(STANDBY * seconds, rel=1e-12)
    assert by['standby']['cabinet'] == pytest.approx(CABINET * seconds, rel=1e-12)
    assert by[BRAKING_CAUSE]['total'] == 0.0
    assert e['motor_energy_j']['X'] == pytest.approx(motor_w * seconds, rel=1e-9)
    supply = motor_w / ETA + STANDBY
    assert e['supply_energy_j']['X'] == pytest.approx(supply * seconds, rel=1e-9)
    assert e['supply_energy_j']['total'] == pytest.approx((supply + CABINET) * seconds,
                                                          rel=1e-9)
    assert e['energy_j'] == e['supply_energy_j'] and e['measured_at'] == 'supply'
    assert e['supply_peak_power_w']['total'] == pytest.approx(supply + CABINET, rel=1e-9)
    # the mechanical result is untouched by the drive
    assert s['energy_j']['X'] == pytest.approx(torque * omega * seconds, rel=1e-9)


@pytest.mark.parametrize('braking,limit', [('regenerative', None), ('regenerative', 1.0),
                                           ('regenerative', 0.0), ('dissipated', 500.0)])
def test_lowering_returns_up_to_the_limit_and_burns_the_rest(braking, limit):
    # vertical axis moving down at constant speed: F = m g - coulomb (loss opposes the motion)
    machine = _one_axis(inclination=90.0, coulomb=20.0, braking=braking, limit=limit)
    v, seconds = -0.05, 1.0
    _, s = _constant_speed(machine, v, seconds)
    lead = machine.axis('X').screw.lead_m
    m = moved_mass_kg(machine, 'X', 0.0)
    force = m * GRAVITY_M_S2 - 20.0
    torque = force * lead / (2.0 * math.pi)
    omega = 2.0 * math.pi * v / lead
    motor_w = torque * omega + 1.5 * R * (torque / KT) ** 2 + _iron_w(omega)
    assert motor_w < 0.0                                 # the weight drives the motor
    assert -motor_w * ETA > 1.0                          # limit 1 W: part burned, part returned
    conv_w = motor_w * ETA                               # the converter returns less
    cap = 0.0 if braking == 'dissipated' else (math.inf if limit is None else limit)
    returned_w = min(-conv_w, cap)
    burned_w = -conv_w - returned_w
    e = s['electrical']
    by = e['energy_by_cause_j']
    assert by['converter']['X'] == pytest.approx(-motor_w * (1.0 - ETA) * seconds, rel=1e-9)
    assert by[BRAKING_CAUSE]['X'] == pytest.approx(burned_w * seconds, rel=1e-9, abs=1e-12)
    assert e['returned_j'] == pytest.approx(returned_w * seconds, rel=1e-9, abs=1e-12)
    assert e['supply_energy_j']['X'] == pytest.approx((STANDBY - returned_w) * seconds,
                                                      rel=1e-9)
    assert e['motor_energy_j']['X'] == pytest.approx(motor_w * seconds, rel=1e-9)


def _drives(*, braking=None, effects=None, measured_at=None):
    data = machine_to_dict(load_machine(DRIVES))
    if braking is not None:
        data['braking'] = braking
    if effects is not None:
        data['effects'] = effects
    if measured_at is not None:
        data['supply']['measured_at'] = measured_at
    return machine_from_dict(data)


def _check_sums(e):
    by = e['energy_by_cause_j']
    assert list(by) == e['causes']
    for key, energy in e['supply_energy_j'].items():
        parts = math.fsum(row[key] for row in by.values())
        assert abs(parts - energy) <= 1e-9 * max(abs(energy), 1e-300), (key, parts, energy)
    # the motor terminals: everything but what the drive and the cabinet add
    drive_side = ('converter', 'standby', BRAKING_CAUSE)
    for key, energy in e['motor_energy_j'].items():
        parts = math.fsum(row[key] for c, row in by.items() if c not in drive_side)
        assert abs(parts - energy) <= 1e-9 * max(abs(energy), 1.0), (key, parts, energy)


EFFECTS = [{'id': 'standby', 'params': {'p0_w': 15.0}},
           {'id': 'copper', 'axis': 'Z', 'params': {'k_w_nm2': 2.0}}]


@pytest.mark.parametrize('braking', ['regenerative', 'dissipated'])
@pytest.mark.parametrize('program,effects', [('three_axis_contour.nc', None), (None, None),
                                             (None, EFFECTS)])
def test_causes_add_up_to_the_electrical_energy(program, effects, braking):
    machine = _drives(braking=braking, effects=effects)
    if program is None:
        prog = parse_gcode(MIXED, file='mixed.nc', home=machine.home_point())
    else:
        prog = load_gcode(REPO / 'config' / 'programs' / program, home=machine.home_point())
    chunks = []
    # 777 samples: chunk boundaries inside moves, arcs and the dwell (left out of the rows)
    summary, _ = simulate_stream(prog.moves, machine, file=prog.file, load_kg=20.0,
                                 chunk_samples=777, on_chunk=chunks.append)
    assert len(chunks) > 3
    e = summary['electrical']
    _check_sums(e)
    names = e['causes']
    assert names[:len(FIXED_CAUSES)] == list(FIXED_CAUSES) and names[-1] == BRAKING_CAUSE
    assert names[-1 - len(ELECTRICAL_CAUSES):-1] == list(ELECTRICAL_CAUSES)
    whole = summarize(simulate_program(prog, machine, load_kg=20.0))['electrical']
    _check_sums(whole)
    scale = max(abs(whole['supply_energy_j']['total']), 1.0)
    for cause, row in whole['energy_by_cause_j'].items():
        for key, value in row.items():
            assert abs(e['energy_by_cause_j'][cause][key] - value) <= 1e-9 * scale
    for key in ('motor_energy_j', 'supply_energy_j', 'motor_peak_power_w',
                'supply_peak_power_w'):
        for axis, value in whole[key].items():
            assert abs(e[key][axis] - value) <= 1e-9 * scale, (key, axis)
    assert e['returned_j'] == pytest.approx(whole['returned_j'], rel=1e-9, abs=1e-9)
    # the streamed chunks carry the electrical power at the full rate (dwell put back)
    n = sum(c.power.t.shape[0] for c in chunks)
    assert n == summary['samples']
    assert all(c.power.electrical.supply_w.shape == c.power.power_w.shape for c in chunks)
    # losses are never negative; the mechanical causes are those of the mechanical breakdown
    for cause in ELECTRICAL_CAUSES + (BRAKING_CAUSE,):
        assert min(e['energy_by_cause_j'][cause].values()) >= 0.0
    mech = summary['energy_by_cause_j']
    for cause in FIXED_CAUSES:
        assert e['energy_by_cause_j'][cause]['total'] == pytest.approx(
            mech[cause]['total'], rel=1e-12, abs=1e-12)
    if braking == 'dissipated':
        assert e['returned_j'] == 0.0


@pytest.mark.parametrize('braking', ['regenerative', 'dissipated'])
def test_energy_per_block_adds_up_to_the_electrical_totals(braking):
    """Each source line's energy at the motor terminals and at the supply side (cabinet
    standby for the line's time included): the lines add up to the totals, streamed in small
    chunks as in one piece, and the top blocks carry their line's values."""
    machine = _drives(braking=braking, effects=EFFECTS)
    prog = parse_gcode(MIXED, file='mixed.nc', home=machine.home_point())
    summary, blocks = simulate_stream(prog.moves, machine, file=prog.file, load_kg=20.0,
                                      chunk_samples=777, block_breakdown=True, top_blocks=3)
    e = summary['electrical']
    assert blocks.motor_j is not None and blocks.supply_j is not None
    for values, key in ((blocks.motor_j, 'motor_energy_j'),
                        (blocks.supply_j, 'supply_energy_j')):
        total = e[key]['total']
        assert math.fsum(values.tolist()) == pytest.approx(total, rel=1e-9)
    # the cabinet's share of a line is its standby power times the line's time
    assert math.fsum(blocks.duration_s.tolist()) * e['cabinet_standby_w'] == pytest.approx(
        e['supply_energy_j']['cabinet'], rel=1e-9)
    # between the terminals and the supply only losses come in (converter, standby, burned
    # braking, cabinet), none negative: no line takes less at the supply than at the motor
    assert np.all(blocks.supply_j - blocks.motor_j >= -1e-9)
    assert np.all(blocks.supply_j - blocks.motor_j
                  >= blocks.duration_s * e['cabinet_standby_w'] - 1e-9)
    whole = simulate_program(prog, machine, load_kg=20.0)
    table = line_table(whole)
    np.testing.assert_array_equal(table.lines, blocks.lines)
    scale = max(abs(e['supply_energy_j']['total']), 1.0)
    assert np.max(np.abs(table.motor_j - blocks.motor_j)) <= 1e-9 * scale
    assert np.max(np.abs(table.supply_j - blocks.supply_j)) <= 1e-9 * scale
    row = {int(ln): i for i, ln in enumerate(blocks.lines)}
    assert len(summary['top_blocks']) == 3
    for b in summary['top_blocks']:
        assert b['motor_energy_j'] == pytest.approx(blocks.motor_j[row[b['line']]], rel=1e-12)
        assert b['supply_energy_j'] == pytest.approx(blocks.supply_j[row[b['line']]],
                                                     rel=1e-12)
    for a, b in zip(summarize(whole, top_blocks=3)['top_blocks'], summary['top_blocks']):
        assert a['line'] == b['line']
        for key in ('motor_energy_j', 'supply_energy_j'):
            assert abs(a[key] - b[key]) <= 1e-9 * scale


def test_measured_at_motor_reports_the_terminals():
    machine = _drives(measured_at='motor')
    prog = parse_gcode(MIXED, file='mixed.nc', home=machine.home_point())
    summary, _ = simulate_stream(prog.moves, machine, file='mixed.nc')
    e = summary['electrical']
    assert e['measured_at'] == 'motor' and 'motor terminals' in e['point']
    assert e['energy_j'] == e['motor_energy_j'] and 'cabinet' not in e['energy_j']


def test_no_drive_no_electrical_output():
    machine = load_machine(REPO / 'config' / 'three_axis_mill.yaml')
    prog = parse_gcode(MIXED, file='mixed.nc', home=machine.home_point())
    summary, _ = simulate_stream(prog.moves, machine, file='mixed.nc')
    assert 'electrical' not in summary
    assert 'electrical' not in summarize(simulate_program(prog, machine))


def test_a_machine_built_in_code_without_every_drive_is_refused():
    from dataclasses import replace

    from feed_axis_energy.errors import ConfigError
    machine = _drives()
    axes = tuple(replace(a, drive=None) if a.name == 'Y' else a for a in machine.axes)
    partial = replace(machine, axes=axes)
    prog = parse_gcode(MIXED, file='mixed.nc', home=machine.home_point())
    with pytest.raises(ConfigError) as info:
        simulate_stream(prog.moves, partial, file='mixed.nc')
    assert info.value.key == 'axes.Y.drive'
