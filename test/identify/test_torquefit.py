"""fit-loss --method samples on drive traces: current (kt declared or fitted), torque, force.

Truth: a machine with known Coulomb and viscous friction simulates a program; its motor torque
becomes a current with a known torque constant (or a force ``M·2·pi/lead``) plus Gaussian
noise, written as CSV at 1 kHz with the commanded kinematics beside it. The fit starts from a
machine file that says the axes are frictionless and must find the truth again.
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
from feed_axis_energy.identify import fit_drive_samples
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured import load_campaign, load_run
from feed_axis_energy.sim.simulate import simulate_program

TRUTH = """\
name: stand_xy
braking: regenerative
load_axis: X
planner: {profile: jerk, corner_tolerance_m: 1.0e-4, rate_hz: 1000.0}
axes:
  X:
    table_mass_kg: 15.0
    rides_on: null
    inclination_deg: 0.0
    screw: {diameter_m: 0.020, lead_m: 0.010, length_m: 0.6, starts: 1, efficiency: 1.0}
    inertias: {motor_kg_m2: 1.1e-4, coupling_kg_m2: 2.0e-5}
    limits: {velocity_m_s: 0.5, acceleration_m_s2: 2.5, jerk_m_s3: 50.0}
    loss: {model: coulomb_viscous, coulomb_n: FC_X, viscous_n_s_m: CV_X}
  Y:
    table_mass_kg: 8.0
    rides_on: null
    inclination_deg: 90.0
    screw: {diameter_m: 0.016, lead_m: 0.005, length_m: 0.4, starts: 1, efficiency: 1.0}
    inertias: {motor_kg_m2: 6.0e-5, coupling_kg_m2: 1.0e-5}
    limits: {velocity_m_s: 0.3, acceleration_m_s2: 2.0, jerk_m_s3: 40.0}
    loss: {model: coulomb_viscous, coulomb_n: FC_Y, viscous_n_s_m: CV_Y}
"""
LOSS = {'X': (40.0, 200.0), 'Y': (25.0, 150.0)}
KT = {'X': 0.12, 'Y': 0.08}

PROGRAM = """\
( strokes of X and Y at several feeds, both ways )
G21 G90 G94 G61
G0 X0 Y0
G1 X150 F3000
G1 X0 F6000
G1 Y80 F2400
G1 Y0 F4800
G1 X250 Y60 F9000
G1 X20 Y10 F12000
G1 X300 F15000
G1 X0 Y0 F7200
M30
"""


def _machine_text(loss: dict) -> str:
    text = TRUTH
    for axis, (fc, cv) in loss.items():
        text = text.replace(f'FC_{axis}', f'{fc:g}').replace(f'CV_{axis}', f'{cv:g}')
    return text


def _held_force(v: np.ndarray, hold: float, rest_speed: float = 5.0e-4) -> np.ndarray:
    """Truth of the force held at rest after a stop, written out sample by sample (not with
    the package's vectorised physics/standstill.py): +hold after a move in +, -hold after -."""
    out = np.zeros_like(v)
    last = 0.0
    for i, vi in enumerate(v):
        if abs(vi) > rest_speed:
            last = 1.0 if vi > 0 else -1.0
        else:
            out[i] = hold * last
    return out


def write_fit_campaign(tmp_path: Path, *, measures: str = 'current', noise: float = 0.01,
                       declare_kt: bool = True, flip: tuple[str, ...] = (), seed: int = 3,
                       program_text: str = PROGRAM, hold: dict | None = None):
    truth_file = tmp_path / 'truth.yaml'
    truth_file.write_text(_machine_text(LOSS), encoding='utf-8')
    start = tmp_path / 'machine.yaml'          # what the fit starts from: no friction
    start.write_text(_machine_text({'X': (0.0, 0.0), 'Y': (0.0, 0.0)}), encoding='utf-8')
    program = tmp_path / 'program.nc'
    program.write_text(program_text, encoding='ascii')
    truth = load_machine(truth_file)
    sim = simulate_program(load_gcode(program), truth)
    dyn = sim.dynamics
    rng = np.random.default_rng(seed)
    unit = {'current': 'A', 'torque': 'N*m', 'force': 'N'}[measures]
    header = ['t']
    cols = [dyn.t]
    for j, axis in enumerate(dyn.axes):
        gain = {'current': KT[axis], 'torque': 1.0,
                'force': truth.axis(axis).screw.lead_m / (2.0 * math.pi)}[measures]
        torque = dyn.torque_nm[:, j]
        if hold:
            lead = truth.axis(axis).screw.lead_m
            held = _held_force(dyn.velocity_m_s[:, j], hold[axis], rest_speed=1.0e-4)
            # at rest friction is static: the held force acts, not the kinetic F_c·sgn(v)
            # (eta = 1 in the truth: the loss torque is F_loss·lead/(2·pi))
            torque = torque - np.where(held != 0.0, dyn.loss_force_n[:, j], 0.0) * lead / (
                2.0 * math.pi)
            torque = torque + held * lead / (2.0 * math.pi)
        q = torque / gain + rng.normal(0.0, noise, dyn.t.size)
        header += [f'{axis}_pos', f'{axis}_vel', f'{axis}_acc', f'{axis}_q']
        cols += [dyn.position_m[:, j], dyn.velocity_m_s[:, j], dyn.acceleration_m_s2[:, j],
                 -q if axis in flip else q]
    table = np.column_stack(cols)
    data = tmp_path / 'trace.csv'
    with data.open('w', encoding='ascii') as fh:
        fh.write(','.join(header) + '\n')
        np.savetxt(fh, table, delimiter=',', fmt='%.9g')
    meter: dict = {'measures': measures}
    if measures == 'current' and declare_kt:
        meter['kt_nm_a'] = dict(KT)
    run = {'name': 'stand', 'load_kg': 0.0,
           'motion': {'from_data': 'commanded', 'reconstruct': 'samples'},
           'data': str(data), 'time': {'column': 't', 'unit': 's'}, 'instrument': meter,
           'axes': {a: {'command_position': {'column': f'{a}_pos', 'unit': 'm'},
                        'command_velocity': {'column': f'{a}_vel', 'unit': 'm/s'},
                        'command_acceleration': {'column': f'{a}_acc', 'unit': 'm/s^2'},
                        measures: {'column': f'{a}_q', 'unit': unit}}
                    for a in dyn.axes}}
    manifest = tmp_path / 'campaign.yaml'
    manifest.write_text(yaml.safe_dump({'name': 'stand', 'machine': str(start),
                                        'runs': [run]}, sort_keys=False), encoding='utf-8')
    return manifest, load_machine(start)


@pytest.mark.parametrize('measures, noise', [('current', 0.01), ('torque', 0.002),
                                             ('force', 2.0)])
def test_declared_gain_recovers_the_friction_and_inertia(tmp_path, measures, noise):
    manifest, machine = write_fit_campaign(tmp_path, measures=measures, noise=noise)
    spec = load_campaign(manifest).runs[0]
    run = load_run(spec)
    gains = {'current': KT, 'torque': {'X': 1.0, 'Y': 1.0},
             'force': {a: machine.axis(a).screw.lead_m / (2 * math.pi) for a in KT}}[measures]
    fits = fit_drive_samples([run], machine=machine, measures=measures, gains=gains,
                             velocity='commanded')
    for axis, (fc, cv) in LOSS.items():
        f = fits[axis]
        assert f.ok, f.message
        assert f.coulomb_n == pytest.approx(fc, rel=0.05)
        assert f.viscous_n_s_m == pytest.approx(cv, rel=0.1)
        assert f.motor_kg_m2 == pytest.approx(machine.axis(axis).inertias.motor_kg_m2, rel=0.1)
        assert f.rmse == pytest.approx(noise, rel=0.1)
        assert not f.gain_fitted


def test_current_without_kt_fits_the_torque_constant(tmp_path):
    manifest, machine = write_fit_campaign(tmp_path, declare_kt=False)
    run = load_run(load_campaign(manifest).runs[0])
    fits = fit_drive_samples([run], machine=machine, measures='current',
                             gains={'X': None, 'Y': None}, velocity='commanded')
    for axis, kt in KT.items():
        f = fits[axis]
        assert f.ok and f.gain_fitted, f.message
        assert f.gain == pytest.approx(kt, rel=0.02)
        assert f.gain_se is not None and f.gain_se < 0.01 * kt
        assert f.coulomb_n == pytest.approx(LOSS[axis][0], rel=0.05)
        assert f.viscous_n_s_m == pytest.approx(LOSS[axis][1], rel=0.1)
        assert not f.inertia_fitted


def test_wrong_sign_is_a_status_naming_invert(tmp_path):
    manifest, machine = write_fit_campaign(tmp_path, flip=('X',))
    run = load_run(load_campaign(manifest).runs[0])
    fits = fit_drive_samples([run], machine=machine, measures='current', gains=KT,
                             velocity='commanded')
    assert fits['X'].status == 'wrong_sign'
    assert 'instrument.invert: [X]' in fits['X'].message
    assert fits['Y'].ok
    fits = fit_drive_samples([run], machine=machine, measures='current', gains=KT,
                             velocity='commanded', invert=[('X',)])
    assert fits['X'].ok and fits['X'].coulomb_n == pytest.approx(40.0, rel=0.05)


def test_fit_loss_cli_on_current_writes_the_machine_and_json(tmp_path, capsys):
    manifest, _ = write_fit_campaign(tmp_path, declare_kt=False)
    out = tmp_path / 'fitted.yaml'
    code = main(['fit-loss', str(manifest), '--method', 'samples', '--json',
                 '--out-machine', str(out)])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    assert doc['measures'] == 'current'
    x = doc['fits']['X']
    assert x['measures'] == 'current' and x['unit'] == 'A'
    assert x['torque_per_unit'] == pytest.approx(KT['X'], rel=0.02)
    assert x['torque_per_unit_fitted'] is True
    assert x['rmse'] == pytest.approx(0.01, rel=0.1) and x['rmse_w'] is None
    fitted = load_machine(out)
    assert fitted.axis('X').loss.coulomb_n == pytest.approx(40.0, rel=0.05)
    # the table form says where a fitted kt goes when the machine has no drive block
    assert main(['fit-loss', str(manifest), '--method', 'samples']) == 0
    text = capsys.readouterr().out
    assert 'kt [N·m/A]' in text and 'RMS [A]' in text
    assert 'declare instrument.kt_nm_a: {X:' in text


def test_fit_loss_steady_refuses_a_drive_trace(tmp_path, capsys):
    manifest, _ = write_fit_campaign(tmp_path)
    assert main(['fit-loss', str(manifest)]) == 1
    assert '--method samples' in capsys.readouterr().err


def test_fit_kt_replaces_a_wrong_declared_torque_constant(tmp_path, capsys):
    manifest, _ = write_fit_campaign(tmp_path)
    doc = yaml.safe_load(manifest.read_text(encoding='utf-8'))
    doc['runs'][0]['instrument']['kt_nm_a'] = {a: 1.3 * kt for a, kt in KT.items()}
    manifest.write_text(yaml.safe_dump(doc), encoding='utf-8')
    assert main(['fit-loss', str(manifest), '--method', 'samples', '--json']) == 0
    declared = json.loads(capsys.readouterr().out)['fits']
    assert declared['X']['torque_per_unit'] == pytest.approx(1.3 * KT['X'])
    assert not declared['X']['torque_per_unit_fitted']
    # horizontal X: a wrong kt is absorbed (friction and inertia come out 1.3 times too
    # large, the residual stays); vertical Y: gravity pins the scale, the residual shows it
    assert declared['X']['coulomb_n'] == pytest.approx(1.3 * LOSS['X'][0], rel=0.05)
    assert declared['Y']['rmse'] > 5 * 0.01
    assert main(['fit-loss', str(manifest), '--method', 'samples', '--fit-kt', '--json']) == 0
    fitted = json.loads(capsys.readouterr().out)['fits']
    for axis in ('X', 'Y'):
        assert fitted[axis]['torque_per_unit'] == pytest.approx(KT[axis], rel=0.02)
        assert fitted[axis]['coulomb_n'] == pytest.approx(LOSS[axis][0], rel=0.05)
        assert fitted[axis]['rmse'] == pytest.approx(0.01, rel=0.1)


def test_fit_kt_needs_samples_and_current(tmp_path, capsys):
    manifest, _ = write_fit_campaign(tmp_path, measures='torque')
    assert main(['fit-loss', str(manifest), '--method', 'samples', '--fit-kt']) == 1
    assert '--fit-kt fits torque constants' in capsys.readouterr().err


DWELL_PROGRAM = """\
( strokes of X and Y both ways, each followed by a rest of 0.4 s )
G21 G90 G94 G61
G0 X0 Y0
G1 X150 F3000
G4 P0.4
G1 X0 F6000
G4 P0.4
G1 Y80 F2400
G4 P0.4
G1 Y0 F4800
G4 P0.4
G1 X250 Y60 F9000
G4 P0.4
G1 X20 Y10 F12000
G4 P0.4
M30
"""


def test_standstill_hold_is_fitted_and_predicted(tmp_path):
    """The drive keeps 30 N (X) and 12 N (Y) after each stop in the direction just left: the
    fit finds them from the resting samples, and compare with the fitted machine predicts the
    resting current (before: the weight alone, so the rest residual is the held force)."""
    hold = {'X': 30.0, 'Y': 12.0}
    manifest, machine = write_fit_campaign(tmp_path, program_text=DWELL_PROGRAM, hold=hold)
    run = load_run(load_campaign(manifest).runs[0])
    fits = fit_drive_samples([run], machine=machine, measures='current', gains=KT,
                             velocity='commanded')
    for axis, h in hold.items():
        f = fits[axis]
        assert f.ok, f.message
        assert f.standstill_hold_n == pytest.approx(h, rel=0.03), f.message
        assert f.n_rest > 100
        assert f.rest_rmse == pytest.approx(0.01, rel=0.2)     # the noise written in
        assert 'holds' in f.message
    # no hold in the truth: the fit says none (a hold within 2 standard errors of 0 is
    # none: declared, even a tiny one would replace the kinetic friction at rest)
    (tmp_path / 'none').mkdir()
    manifest0, machine0 = write_fit_campaign(tmp_path / 'none', program_text=DWELL_PROGRAM)
    run0 = load_run(load_campaign(manifest0).runs[0])
    fits0 = fit_drive_samples([run0], machine=machine0, measures='current', gains=KT,
                              velocity='commanded')
    for axis in hold:
        assert fits0[axis].standstill_hold_n is None, fits0[axis].message
        assert 'holds' not in fits0[axis].message


def test_compare_predicts_the_held_current_with_the_fitted_machine(tmp_path):
    from dataclasses import replace as _replace

    from feed_axis_energy.identify import machine_with_sample_fits
    from feed_axis_energy.measured import compare_campaign
    hold = {'X': 30.0, 'Y': 12.0}
    manifest, machine = write_fit_campaign(tmp_path, program_text=DWELL_PROGRAM, hold=hold)
    campaign = load_campaign(manifest)
    run = load_run(campaign.runs[0])
    fits = fit_drive_samples([run], machine=machine, measures='current', gains=KT,
                             velocity='commanded')
    fitted = machine_with_sample_fits(machine, fits)
    assert {a.name: a.standstill_hold_n for a in fitted.axes} == pytest.approx(hold, rel=0.03)
    without = _replace(fitted, axes=tuple(_replace(a, standstill_hold_n=0.0)
                                          for a in fitted.axes))
    after = compare_campaign(campaign, machine=fitted).runs[0]
    before = compare_campaign(campaign, machine=without).runs[0]
    for axis in after.axes:
        a, b = after.signal_metrics[axis], before.signal_metrics[axis]
        # with the hold the residual is the 0.01 A noise (plus what the fit left), without
        # it the held current is missing at every rest
        assert a.rmse < 0.02 < b.rmse, (axis, a.rmse, b.rmse)
