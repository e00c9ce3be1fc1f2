"""Spatial alignment: the work offset between machine positions of a trace and the program.

The "measured" trace is written here from the core's simulation of a program: positions
shifted by a known work offset (machine = program + offset), read a known time later at
100 Hz with noise, and the motor current. ``compare`` must find the time offset and the work
offset; a declared one (manifest) wins; one the machine config declares (gcode.work_offsets_m,
the program selecting G55) is already in the simulated positions, and what is left is 0.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from feed_axis_energy.cli import main
from feed_axis_energy.gcode.load import load_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.spatial import estimate_work_offset
from feed_axis_energy.sim.simulate import simulate_program

MACHINE = """\
name: xy
braking: regenerative
load_axis: X
planner: {profile: jerk, corner_tolerance_m: 1.0e-4, rate_hz: 500.0}
axes:
  X:
    table_mass_kg: 15.0
    rides_on: null
    inclination_deg: 0.0
    screw: {diameter_m: 0.020, lead_m: 0.010, length_m: 0.6, starts: 1, efficiency: 1.0}
    inertias: {motor_kg_m2: 1.1e-4, coupling_kg_m2: 2.0e-5}
    limits: {velocity_m_s: 0.5, acceleration_m_s2: 2.5, jerk_m_s3: 50.0}
    loss: {model: coulomb_viscous, coulomb_n: 40.0, viscous_n_s_m: 200.0}
    drive: {kt_nm_a: 0.12, resistance_ohm: 1.0, resistance_between: terminals}
  Y:
    table_mass_kg: 8.0
    rides_on: null
    inclination_deg: 0.0
    screw: {diameter_m: 0.016, lead_m: 0.005, length_m: 0.4, starts: 1, efficiency: 1.0}
    inertias: {motor_kg_m2: 6.0e-5, coupling_kg_m2: 1.0e-5}
    limits: {velocity_m_s: 0.3, acceleration_m_s2: 2.0, jerk_m_s3: 40.0}
    loss: {model: coulomb_viscous, coulomb_n: 25.0, viscous_n_s_m: 150.0}
    drive: {kt_nm_a: 0.08, resistance_ohm: 1.0, resistance_between: terminals}
"""
PROGRAM = """\
G21 G90 G94 G61
SYSTEM
G0 X0 Y0
G4 P0.5
G1 X200 F9000
G4 P0.7
G1 Y120 F4200
G4 P0.3
G1 X60 Y40 F12000
G4 P1.1
G1 X0 Y0 F7000
G4 P0.5
M30
"""
WORK = {'X': -0.1234, 'Y': 0.3456}     # machine - program [m]
LAG_S = 0.6


def _campaign(tmp_path: Path, *, machine_extra: str = '', system: str = 'G54',
              declared: dict | None = None) -> Path:
    machine_file = tmp_path / 'machine.yaml'
    machine_file.write_text(MACHINE + machine_extra, encoding='utf-8')
    program = tmp_path / 'program.ngc'
    program.write_text(PROGRAM.replace('SYSTEM', system), encoding='ascii')
    truth = load_machine(tmp_path / 'machine.yaml')
    # the truth: the program as it runs in machine coordinates with the whole offset
    plain = load_machine_text(tmp_path, MACHINE)
    sim = simulate_program(load_gcode(program, **plain.gcode_keywords()), truth)
    dyn = sim.dynamics
    rng = np.random.default_rng(2)
    t = np.arange(0.0, float(sim.power.t[-1]) + LAG_S + 0.5, 0.01)
    cols, header = [t], ['t']
    kt = {'X': 0.12, 'Y': 0.08}
    for j, axis in enumerate(dyn.axes):
        at = t - LAG_S
        pos = np.interp(at, dyn.t, dyn.position_m[:, j]) + WORK[axis]
        cur = np.interp(at, dyn.t, dyn.torque_nm[:, j] / kt[axis])
        cols += [1e3 * pos + rng.normal(0.0, 1e-3, t.size), cur + rng.normal(0.0, 0.01, t.size)]
        header += [f'{axis}_pos', f'{axis}_i']
    data = tmp_path / 'trace.csv'
    with data.open('w', encoding='ascii') as fh:
        fh.write(','.join(header) + '\n')
        np.savetxt(fh, np.column_stack(cols), delimiter=',', fmt='%.9g')
    run = {'name': 'r', 'load_kg': 0.0, 'motion': {'program': str(program)},
           'data': str(data), 'time': {'column': 't', 'unit': 's'},
           'instrument': {'measures': 'current'},
           'axes': {a: {'position': {'column': f'{a}_pos', 'unit': 'mm'},
                        'current': {'column': f'{a}_i', 'unit': 'A'}} for a in ('X', 'Y')}}
    if declared is not None:
        run['work_offset_m'] = declared
    manifest = tmp_path / 'c.yaml'
    manifest.write_text(yaml.safe_dump({'machine': str(machine_file), 'runs': [run]}),
                        encoding='utf-8')
    return manifest


def load_machine_text(tmp_path: Path, text: str):
    file = tmp_path / 'plain.yaml'
    file.write_text(text, encoding='utf-8')
    return load_machine(file)


def test_time_and_work_offset_are_found(tmp_path):
    run = compare_campaign(load_campaign(_campaign(tmp_path))).runs[0]
    assert run.offset_used_s == pytest.approx(LAG_S, abs=0.003)
    w = run.work_offset
    assert w is not None and w.status == 'ok', w
    assert w.axes == ('X', 'Y')
    assert w.found_m == pytest.approx((WORK['X'], WORK['Y']), abs=2e-5)
    assert w.used_m == w.found_m and max(w.spread_m) < 1e-3


def test_a_declared_offset_wins_and_the_estimate_is_shown(tmp_path, capsys):
    declared = {'X': -0.1, 'Y': 0.3}
    manifest = _campaign(tmp_path, declared=declared)
    assert main(['compare', str(manifest), '--json', '--quiet']) == 0
    w = json.loads(capsys.readouterr().out)['runs'][0]['work_offset']
    assert w['status'] == 'declared'
    assert w['used_m'] == pytest.approx(declared) and w['declared_m'] == pytest.approx(declared)
    assert w['found_m'] == pytest.approx(WORK, abs=2e-5)
    assert set(w) == {'found_m', 'used_m', 'declared_m', 'spread_m', 'status', 'message',
                      'n_samples'}
    assert main(['compare', str(manifest), '--quiet']) == 0
    text = capsys.readouterr().out
    assert 'work offset (machine - program' in text and 'X -100.000 mm' in text


def test_the_machine_configs_work_offset_is_in_the_simulated_positions(tmp_path):
    # G55 declared with the X part of the offset: the estimate is what is left (Y)
    extra = f'gcode:\n  work_offsets_m:\n    G55: {{X: {WORK["X"]}}}\n'
    run = compare_campaign(load_campaign(_campaign(tmp_path, machine_extra=extra,
                                                   system='G55'))).runs[0]
    assert run.work_offset.found_m == pytest.approx((0.0, WORK['Y']), abs=2e-5)


def test_a_trace_that_is_no_translation_is_loose():
    t = np.linspace(0.0, 10.0, 1001)
    sim = np.column_stack([np.sin(t), t])
    meas = np.column_stack([np.sin(t) + 0.2, 3.0 * t])        # Y stretched, not shifted
    w = estimate_work_offset(t, meas, t, sim, axes=('X', 'Y'), offset_s=0.0)
    assert w.status == 'loose' and 'did not run as simulated' in w.message
    assert w.found_m[0] == pytest.approx(0.2)
    none = estimate_work_offset(t, meas, t, sim, axes=('X', 'Y'), offset_s=100.0)
    assert none.status == 'loose' and all(math.isnan(v) for v in none.found_m)


def test_the_program_starts_where_motion_start_m_says(tmp_path):
    manifest = _campaign(tmp_path)
    doc = yaml.safe_load(manifest.read_text(encoding='utf-8'))
    doc['runs'][0]['motion']['start_m'] = {'X': 0.05, 'Y': -0.02}
    manifest.write_text(yaml.safe_dump(doc), encoding='utf-8')
    from feed_axis_energy.measured.compare import MotionCache
    spec = load_campaign(manifest).runs[0]
    assert spec.motion_start_m == (0.05, -0.02, 0.0)
    machine = load_machine(tmp_path / 'machine.yaml')
    motion = MotionCache(machine).program_motion(spec.motion_program, spec.motion_start_m)
    assert tuple(motion.pos[0]) == pytest.approx((0.05, -0.02))
    doc['runs'][0]['motion'] = {'from_data': 'actual', 'start_m': {'X': 0.0}}
    manifest.write_text(yaml.safe_dump(doc), encoding='utf-8')
    from feed_axis_energy.errors import ConfigError
    with pytest.raises(ConfigError) as err:
        load_campaign(manifest)
    assert 'runs[0].motion.start_m' in str(err.value)
