"""A rotary feed axis through planner, dynamics and power, against closed forms.

Machine: X (a ball screw) and a C rotary table, gear ratio r, motor inertia J_m, table and
load inertia J_t + J_l, friction torque c + b·omega at the table. With the trapezoid profile a
move of angle d at angular speed w and acceleration a lasts ``d / w + w / a``; the energy
drawn is ``(J_m r^2 + J_t + J_l) w^2 / 2`` to accelerate (divided by eta on the table's
part), and the friction takes ``c d + b w^2 (t_cruise + 2 t_ramp / 3)``.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from feed_axis_energy.gcode import parse_gcode
from feed_axis_energy.machine import machine_from_dict
from feed_axis_energy.sim import simulate_program

R, J_M, J_T, J_L = 10.0, 1.0e-3, 0.5, 0.1
C_NM, B_NMS = 2.0, 0.5
W_MAX, A_MAX = math.radians(90.0), math.pi          # 90 deg/s, 180 deg/s^2

BASE = {
    'name': 'rotary_test', 'braking': 'regenerative', 'load_axis': 'C',
    'planner': {'profile': 'trapezoid', 'rate_hz': 2000.0, 'corner_tolerance_m': 0.0},
    'axes': {
        'X': {'table_mass_kg': 50.0,
              'screw': {'diameter_m': 0.02, 'lead_m': 0.01, 'length_m': 0.5},
              'inertias': {'motor_kg_m2': 0.0, 'screw_kg_m2': 0.0},
              'limits': {'velocity_m_s': 0.5, 'acceleration_m_s2': 2.0, 'jerk_m_s3': 1e6},
              'loss': {'model': 'coulomb_viscous'}},
        'C': {'rides_on': 'X', 'mass_kg': 30.0, 'table_inertia_kg_m2': J_T,
              'load_inertia_kg_m2': J_L, 'gear_ratio': R, 'efficiency': 1.0,
              'inertias': {'motor_kg_m2': J_M},
              'limits': {'velocity_deg_s': 90.0, 'acceleration_deg_s2': 180.0,
                         'jerk_deg_s3': 1.0e9},
              'friction': {'coulomb_nm': C_NM, 'viscous_nm_s_rad': B_NMS}},
    },
}


def _machine(braking='regenerative', **rotary):
    d = copy.deepcopy(BASE)
    d['braking'] = braking
    d['axes']['C'].update(rotary)
    return machine_from_dict(d)


def _run(text, machine):
    program = parse_gcode(text, **machine.gcode_keywords())
    return simulate_program(program, machine)


def _friction_j(d, w, a):
    t_ramp = w / a
    t_cruise = d / w - t_ramp
    return C_NM * d + B_NMS * w * w * (t_cruise + 2.0 * t_ramp / 3.0)


@pytest.mark.parametrize('text', ['G21 G94 G1 C90 F3600\n',     # 60 deg/min... per second
                                  'G21 G93 G1 C90 F40\n'])      # 1/40 min: also 60 deg/s
def test_pure_rotary_move_duration_and_energy(text):
    result = _run(text, _machine())
    d, w = math.pi / 2, math.pi / 3
    assert result.motion.t[-1] == pytest.approx(d / w + w / A_MAX, abs=1e-3)
    j = result.motion.axes.index('C')
    assert result.motion.pos[-1, j] == pytest.approx(d)
    assert np.max(result.motion.vel[:, j]) == pytest.approx(w, rel=1e-9)
    # regenerative, eta = 1: the kinetic energy comes back, the friction stays
    e_c = result.power.energy_j[-1, j]
    assert e_c == pytest.approx(_friction_j(d, w, A_MAX), rel=2e-3)
    assert result.power.energy_j[-1, result.motion.axes.index('X')] == 0.0


def test_accelerating_the_table_costs_its_kinetic_energy_over_the_gear():
    eta = 0.8
    machine = _machine('dissipated', efficiency=eta,
                       friction={'coulomb_nm': 0.0, 'viscous_nm_s_rad': 0.0})
    result = _run('G21 G94 G1 C90 F3600\n', machine)
    w = math.pi / 3
    expected = 0.5 * J_M * (R * w) ** 2 + 0.5 * (J_T + J_L) * w ** 2 / eta
    j = result.motion.axes.index('C')
    assert result.power.energy_j[-1, j] == pytest.approx(expected, rel=2e-3)
    # motor speed is r times the table's
    assert np.max(result.dynamics.omega_rad_s[:, j]) == pytest.approx(R * w, rel=1e-9)


def test_combined_move_feed_on_the_xyz_path_rotary_in_step():
    result = _run('G21 G94 G1 X30 C90 F600\n', _machine())
    length, v = 0.03, 0.01                     # 30 mm at 600 mm/min
    rate = (math.pi / 2) / length              # C [rad] per metre of path
    a_path = min(2.0, A_MAX / rate)            # C limits the path acceleration
    assert result.motion.t[-1] == pytest.approx(length / v + v / a_path, abs=1e-3)
    jx, jc = result.motion.axes.index('X'), result.motion.axes.index('C')
    np.testing.assert_allclose(result.motion.vel[:, jc], rate * result.motion.vel[:, jx],
                               rtol=1e-9, atol=1e-12)
    w = rate * v                               # 30 deg/s
    assert result.power.energy_j[-1, jc] == pytest.approx(
        _friction_j(math.pi / 2, w, rate * a_path), rel=2e-3)


def test_a_pure_rotary_move_meets_linear_moves_at_rest():
    result = _run('G21 G94 G1 X10 F600\nG1 C45 F3600\nG1 X20 F600\n', _machine())
    jx, jc = result.motion.axes.index('X'), result.motion.axes.index('C')
    turning = np.abs(result.motion.vel[:, jc]) > 0.0
    assert np.all(result.motion.vel[turning, jx] == 0.0)
    assert result.motion.pos[-1, jx] == pytest.approx(0.02)
    assert result.motion.pos[-1, jc] == pytest.approx(math.pi / 4)


def test_load_inertia_comes_from_the_machine_file_load_kg_from_the_option():
    m = _machine('dissipated', friction={'coulomb_nm': 0.0, 'viscous_nm_s_rad': 0.0})
    light = _machine('dissipated', load_inertia_kg_m2=0.0,
                     friction={'coulomb_nm': 0.0, 'viscous_nm_s_rad': 0.0})
    program = parse_gcode('G21 G94 G1 X30 C90 F600\n', **m.gcode_keywords())
    jx, jc = 0, 1
    full = simulate_program(program, m, load_kg=20.0)
    none = simulate_program(program, light, load_kg=0.0)
    # C: the load's inertia; X: the workpiece mass (load_axis C rides on X)
    assert full.power.energy_j[-1, jc] > none.power.energy_j[-1, jc]
    assert full.dynamics.mass_kg[jx] == pytest.approx(50.0 + 30.0 + 20.0)
    assert full.dynamics.mass_kg[jc] == pytest.approx(J_T + J_L)


# the corpus's small rotary programs on the shipped 4- and 5-axis configs (the big
# rotation.ngc is planned only: 5.4 h of machine time)
CORPUS_RUNS = [('nc_files__b-index.ngc', 'five_axis_mill.yaml', ()),
               ('nc_files__cone.ngc', 'five_axis_mill.yaml', ('W',)),
               ('nc_files__daisy.ngc', 'four_axis_mill.yaml', ())]


@pytest.mark.parametrize('name, config, ignore', CORPUS_RUNS)
def test_corpus_rotary_programs_simulate_on_the_shipped_configs(name, config, ignore):
    from shared_data import need_shared
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.paths import config_dir
    from feed_axis_energy.gcode import load_gcode
    from feed_axis_energy.gcode.stats import summarize as stats_of
    path = need_shared('corpus', 'gcode', 'LinuxCNC__linuxcnc', name)
    machine = load_machine(config_dir() / config)
    program = load_gcode(path, ignore_axes=ignore, **machine.gcode_keywords())
    stats = stats_of(program.moves)
    result = simulate_program(program, machine)
    motion = result.motion
    # the motion goes where the moves go, and takes at least their nominal feed time
    for j, axis in enumerate(motion.axes):
        if axis in machine.rotary_axes:
            travel = np.sum(np.abs(np.diff(motion.pos[:, j])))
            k = 'ABC'.index(axis)
            moved = sum(abs(m.rot_end[k] - m.rot_start[k]) for m in program.moves
                        if m.rot_end is not None)
            # a rotary reversal passed at speed happens within one cycle, between samples
            assert travel == pytest.approx(moved, rel=1e-4)
            assert (result.power.energy_j[-1, j] > 0.0) == (moved > 0.0)
    assert motion.t[-1] >= stats.nominal_feed_time_s
    assert np.all(np.isfinite(result.power.power_w))


def test_streamed_motion_equals_the_whole_record_plan():
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.paths import config_dir
    from feed_axis_energy.plan import plan
    from feed_axis_energy.plan.stream import concat_motion, iter_motion
    machine = load_machine(config_dir() / 'five_axis_mill.yaml')
    text = ('G21 G94 G64\nG1 X5 F3000\nG1 X10 Y3 C30\nG2 X20 Y3 I5 J0 B10 C60\nG1 B-20 F3600\n'
            'G1 X25 C0 F3000\nG93 G1 X30 B0 F60\nG94 G0 X0 Y0 C0\nM2\n')
    program = parse_gcode(text, **machine.gcode_keywords())
    options = machine.planner.options()
    whole = plan(program, machine.limits(), options=options)
    streamed = concat_motion(iter_motion(program.moves, machine.limits(), options=options,
                                         file='p', chunk_samples=97, window_blocks=2))
    assert streamed.axes == whole.axes == ('X', 'Y', 'Z', 'B', 'C')
    np.testing.assert_array_equal(streamed.t, whole.t)
    for a, b in ((streamed.pos, whole.pos), (streamed.vel, whole.vel),
                 (streamed.acc, whole.acc)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    assert whole.pos[-1, 3] == pytest.approx(0.0, abs=1e-12)
    # the B and C limits hold (sampled acceleration within a cycle's corner step)
    for j, name in ((3, 'B'), (4, 'C')):
        lim = machine.axis(name).limits
        assert np.max(np.abs(whole.vel[:, j])) <= lim.velocity_m_s * (1 + 1e-9)
