"""Energy by cause: the parts add up to the total; single terms against hand calculations."""
import math
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.physics.breakdown import BRAKING_CAUSE, cause_names, FIXED_CAUSES
from feed_axis_energy.gcode.load import load_gcode, parse_gcode
from feed_axis_energy.units import GRAVITY_M_S2
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.machine.mass import moved_mass_kg
from feed_axis_energy.sim.stream import simulate_stream
from feed_axis_energy.sim.simulate import simulate_program, summarize

REPO = Path(__file__).resolve().parents[2]

# arcs, a dwell long enough to be left out of the rows (compact), a vertical lift and drop
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


def _machine(name, *, braking=None, effects=None, **axis_changes):
    data = machine_to_dict(load_machine(REPO / 'config' / name))
    if braking is not None:
        data['braking'] = braking
    if effects is not None:
        data['effects'] = effects
    for axis, changes in axis_changes.items():
        for key, value in changes.items():
            section = data['axes'][axis]
            *path, last = key.split('.')
            for part in path:
                section = section[part]
            section[last] = value
    return machine_from_dict(data)


def _check_sums(summary, blocks=None):
    by_cause = summary['energy_by_cause_j']
    assert list(by_cause) == summary['causes']
    for axis, energy in summary['energy_j'].items():
        parts = math.fsum(values[axis] for values in by_cause.values())
        assert abs(parts - energy) <= 1e-9 * max(abs(energy), 1e-300), (axis, parts, energy)
    if blocks is not None:
        assert blocks.by_cause_j is not None and blocks.by_axis_j is not None
        scale = max(abs(summary['energy_j']['total']), 1e-300)
        np.testing.assert_allclose(blocks.by_cause_j.sum(axis=1), blocks.energy_j,
                                   rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(blocks.by_axis_j.sum(axis=1), blocks.energy_j,
                                   rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(blocks.by_cause_j.sum(axis=0),
                                   [by_cause[c]['total'] for c in blocks.causes],
                                   rtol=0, atol=1e-9 * scale)


EFFECTS = [{'id': 'standby', 'params': {'p0_w': 15.0}},
           {'id': 'copper', 'axis': 'Z', 'params': {'k_w_nm2': 2.0}},
           {'id': 'braking_loss', 'params': {'fraction': 0.3}}]


@pytest.mark.parametrize('per_line', [True, False])
@pytest.mark.parametrize('braking', ['regenerative', 'dissipated'])
@pytest.mark.parametrize('config,program,effects', [
    ('demonstrator.yaml', 'demonstrator_f300.nc', None),
    ('three_axis_mill.yaml', 'three_axis_contour.nc', None),
    ('three_axis_mill.yaml', None, None),
    ('three_axis_mill.yaml', None, EFFECTS),
])
def test_causes_add_up_to_the_energy(config, program, effects, braking, per_line):
    # per_line=False: the sums are taken without a power row per cause (_add_sums); they
    # must agree with the rows of the whole record (simulate_program, per line)
    machine = _machine(config, braking=braking, effects=effects)
    if program is None:
        prog = parse_gcode(MIXED, file='mixed.nc', home=machine.home_point())
    else:
        prog = load_gcode(REPO / 'config' / 'programs' / program, home=machine.home_point())
    # 777 samples: chunk boundaries fall inside moves, arcs and the dwell
    chunks = []
    summary, blocks = simulate_stream(prog.moves, machine, file=prog.file, load_kg=20.0,
                                      chunk_samples=777, block_breakdown=per_line,
                                      on_chunk=chunks.append, top_blocks=3)
    assert len(chunks) > 3
    _check_sums(summary, blocks if per_line else None)
    whole = summarize(simulate_program(prog, machine, load_kg=20.0), top_blocks=3)
    _check_sums(whole)
    for key in ('energy_by_cause_j', 'gross_by_cause_j'):
        for cause, values in whole[key].items():
            for axis, value in values.items():
                got = summary[key][cause][axis]
                assert abs(got - value) <= 1e-9 * max(abs(whole['energy_j']['total']), 1.0)
    for block in summary['top_blocks'] if per_line else ():
        assert math.isclose(sum(block['energy_by_cause_j'].values()), block['energy_j'],
                            rel_tol=1e-9, abs_tol=1e-9)
    names = summary['causes']
    assert names[:len(FIXED_CAUSES)] == list(FIXED_CAUSES) and names[-1] == BRAKING_CAUSE
    if effects:
        assert names == list(cause_names(['effect:standby', 'effect:copper:Z',
                                          'effect:braking_loss']))
        assert summary['energy_by_cause_j']['effect:standby']['total'] > 0.0
        assert summary['energy_by_cause_j']['effect:copper:Z']['X'] == 0.0
    burned = summary['energy_by_cause_j'][BRAKING_CAUSE]['total']
    if braking == 'regenerative':
        assert burned == 0.0
    else:
        # what the axes gave back while braking is burned instead of credited
        assert math.isclose(burned, summary['regenerated_energy_j'], rel_tol=1e-9)
    friction = summary['energy_by_cause_j']['friction']['total']
    assert math.isclose(friction, summary['loss_energy_j'], rel_tol=1e-9)
    assert summary['gross_by_cause_j']['gravity_lower']['total'] == 0.0


def _one_axis(program, machine, *, load_kg=0.0):
    prog = parse_gcode(program, file='p.nc', home=machine.home_point())
    summary, _ = simulate_stream(prog.moves, machine, file='p.nc', load_kg=load_kg,
                                 chunk_samples=500)
    return summary


def test_friction_only_at_constant_speed_and_coulomb_times_distance():
    # horizontal X, Coulomb friction only, eta = 1, no rotary inertia in the way of the sum:
    # the whole move (ramps included) costs F_c * s in friction; everything else nets to 0
    machine = _machine('three_axis_mill.yaml', braking='regenerative', X={
        'loss': {'model': 'coulomb_viscous', 'coulomb_n': 150.0, 'viscous_n_s_m': 0.0,
                 'mu': 0.0},
        'screw.efficiency': 1.0})
    s = _one_axis('G21 G90 G94\nG0 X0 Y0 Z0\nG1 X200 F3000\nM30\n', machine)
    by = s['energy_by_cause_j']
    assert math.isclose(by['friction']['X'], 150.0 * 0.2, rel_tol=1e-6)
    assert by['screw']['X'] == 0.0
    assert by['gravity_lift']['X'] == 0.0 and by['gravity_lower']['X'] == 0.0
    # starts and ends at rest: the kinetic energy put in comes back, the net is ~0
    gross = s['gross_by_cause_j']
    assert abs(by['linear_inertia']['X']) < 1e-3 * gross['linear_inertia']['X']
    m = moved_mass_kg(machine, 'X', 0.0)
    v = 3.0 / 60.0
    # put in: the kinetic energy at the cruise speed, 1/2 m v^2 (and 1/2 J omega^2)
    assert math.isclose(gross['linear_inertia']['X'], 0.5 * m * v * v, rel_tol=1e-3)
    spec = machine.axis('X')
    omega = 2.0 * math.pi * v / spec.screw.lead_m
    assert math.isclose(gross['rotary_inertia']['X'],
                        0.5 * spec.rotary_inertia_kg_m2 * omega * omega, rel_tol=1e-3)


def test_constant_speed_part_is_friction_only():
    # a move at constant speed has no acceleration: the middle block of three tangent
    # G64 blocks along X at one feed is friction only (with a Coulomb + viscous loss)
    machine = _machine('three_axis_mill.yaml', braking='regenerative', X={
        'screw.efficiency': 1.0})
    prog = parse_gcode('G21 G90 G94 G64\nG0 X0 Y0 Z0\nG1 X100 F1200\nX300\nX400\nM30\n',
                       file='p.nc', home=machine.home_point())
    _, blocks = simulate_stream(prog.moves, machine, file='p.nc', block_breakdown=True)
    row = int(np.nonzero(blocks.lines == 4)[0][0])
    causes = dict(zip(blocks.causes, blocks.by_cause_j[row]))
    v = 1.2 / 60.0
    spec = machine.axis('X')
    normal = moved_mass_kg(machine, 'X', 0.0) * GRAVITY_M_S2
    force = 150.0 + 0.005 * normal + 400.0 * v       # coulomb + mu N + viscous v (the yaml)
    # intervals go to the line of their end sample: the block's ends are off by at most
    # one sample interval (1 ms) of the power F v
    one_sample = force * v * 1e-3 * (1.0 + 1e-9)
    assert abs(causes['friction'] - force * 0.2) <= one_sample
    assert abs(blocks.energy_j[row] - force * 0.2) <= one_sample
    assert causes['friction'] == pytest.approx(blocks.energy_j[row], rel=1e-12)
    for name in ('linear_inertia', 'rotary_inertia', 'gravity_lift', 'screw'):
        assert abs(causes[name]) < 1e-9, name
    assert spec.screw.efficiency == 1.0


@pytest.mark.parametrize('eta', [1.0, 0.9])
def test_vertical_lift_is_m_g_h_and_lowering_gives_it_back(eta):
    machine = _machine('three_axis_mill.yaml', braking='regenerative', Z={
        'screw.efficiency': eta})
    m = moved_mass_kg(machine, 'Z', 0.0)
    h = 0.05
    s = _one_axis('G21 G90 G94\nG0 X0 Y0 Z0\nG1 Z50 F1200\nG4 P0.2\nG1 Z0\nM30\n', machine)
    by = s['energy_by_cause_j']
    assert math.isclose(by['gravity_lift']['Z'], m * GRAVITY_M_S2 * h, rel_tol=1e-6)
    assert math.isclose(by['gravity_lower']['Z'], -m * GRAVITY_M_S2 * h, rel_tol=1e-6)
    if eta == 1.0:
        assert by['screw']['Z'] == 0.0
    else:
        # the screw loses (1/eta - 1) of F v while lifting and (1 - eta) of it while the
        # weight back-drives it on the way down; F ~ m g + friction at constant speed
        loss_n = 180.0 + 400.0 * 0.02
        lift = (m * GRAVITY_M_S2 + loss_n) * h * (1.0 / eta - 1.0)
        lower = (m * GRAVITY_M_S2 - loss_n) * h * (1.0 - eta)
        assert math.isclose(by['screw']['Z'], lift + lower, rel_tol=2e-2)


def test_dissipated_braking_burns_what_the_axis_returns():
    # a horizontal move with no friction: all drawn energy is kinetic, burned when braking
    machine = _machine('three_axis_mill.yaml', braking='dissipated', X={
        'loss': {'model': 'coulomb_viscous', 'coulomb_n': 0.0, 'viscous_n_s_m': 0.0,
                 'mu': 0.0},
        'screw.efficiency': 1.0})
    s = _one_axis('G21 G90 G94\nG0 X0 Y0 Z0\nG1 X200 F6000\nM30\n', machine)
    by, gross = s['energy_by_cause_j'], s['gross_by_cause_j']
    put_in = gross['linear_inertia']['X'] + gross['rotary_inertia']['X']
    assert math.isclose(s['energy_j']['X'], put_in, rel_tol=1e-6)
    assert math.isclose(by[BRAKING_CAUSE]['X'], put_in, rel_tol=1e-3)
    assert by['friction']['X'] == 0.0


@pytest.mark.parametrize('braking', ['regenerative', 'dissipated'])
@pytest.mark.parametrize('given_burned', [False, True])
def test_sums_without_rows_equal_the_rows_with_extra_causes_and_a_given_burned_row(
        braking, given_burned):
    # the summary's fast path (no per-line table: _add_sums) and the per-row path must give
    # the same energy, gross energy and cause names with extra causes after the effects (the
    # electrical losses) and a burned row handed in by the caller
    from feed_axis_energy.physics.breakdown import BreakdownAccumulator
    machine = _machine('three_axis_mill.yaml', braking=braking)
    result = simulate_program(parse_gcode(MIXED), machine, load_kg=20.0)
    dyn, mech = result.dynamics, result.power.mechanical_w
    n, k = mech.shape
    rng = np.random.default_rng(3)
    effects = [('standby', np.full((n, k), 2.0))]
    extra = [('copper', rng.uniform(0.0, 5.0, (n, k))),
             ('converter', rng.uniform(-1.0, 3.0, (n, k)))]
    burned = rng.uniform(0.0, 4.0, (n, k)) if given_burned else None
    accs = [BreakdownAccumulator(per_line=flag) for flag in (True, False)]
    for acc in accs:
        acc.add(dyn, mech, braking=braking, effects=effects, extra=extra, burned=burned)
    rows, sums = accs
    assert rows.causes == sums.causes and rows.causes[-1] == BRAKING_CAUSE
    scale = float(np.abs(rows.energy).max())
    np.testing.assert_allclose(sums.energy, rows.energy, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(sums.gross, rows.gross, rtol=0, atol=1e-12 * scale)
    burned_j = rows.energy[-1]
    if given_burned or braking == 'dissipated':
        assert np.all(burned_j > 0.0)
    else:
        assert np.all(burned_j == 0.0)
