"""Drive traces (current, torque, force) as measured quantities: compare, errors, JSON contract.

The "measured" traces are made here from the core's simulation of a program and written out
by an instrument independent of feed_axis_energy.measured: the motor torque of every axis is
divided by a known torque constant (current), left as it is (torque) or turned into the
actuator force ``M·2·pi/lead``; the trace is read at the data's own rate (50 Hz to 2 kHz) a
known time later than the simulation, as point samples by linear interpolation, with
Gaussian noise, and written as CSV (in mA or A, N·m, kN) with or without a time column.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.cli import main
from feed_axis_energy.errors import ConfigError, DataError
from feed_axis_energy.gcode.load import load_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.manifest import campaign_from_dict, load_campaign
from feed_axis_energy.measured.metrics import CHUNK
from feed_axis_energy.measured.quantity import measured_signal, quantity_of, signal_metrics
from feed_axis_energy.measured.run import MeasuredRun
from feed_axis_energy.sim.simulate import simulate_program

MACHINE_YAML = """\
name: drive_xy
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
    loss: {model: coulomb_viscous, coulomb_n: 40.0, viscous_n_s_m: 200.0}
  Y:
    table_mass_kg: 8.0
    rides_on: null
    inclination_deg: INCL
    screw: {diameter_m: 0.016, lead_m: 0.005, length_m: 0.4, starts: 1, efficiency: 1.0}
    inertias: {motor_kg_m2: 6.0e-5, coupling_kg_m2: 1.0e-5}
    limits: {velocity_m_s: 0.3, acceleration_m_s2: 2.0, jerk_m_s3: 40.0}
    loss: {model: coulomb_viscous, coulomb_n: 25.0, viscous_n_s_m: 150.0}
"""

# No two segments alike, so the cross-correlation has one clear peak.
PROGRAM = """\
( drive-trace test program: X and Y moves of different lengths and feeds )
G21 G90 G94 G61
G0 X0 Y0
G4 P0.5
G1 X200 F9000
G4 P0.7
G1 Y120 F4200
G4 P0.3
G1 X60 Y40 F12000
G4 P1.1
G1 X300 F21000
G4 P0.4
G1 X0 Y0 F7000
G4 P0.5
M30
"""

KT = {'X': 0.12, 'Y': 0.08}
UNITS = {'current': ('mA', 1e3), 'torque': ('N*m', 1.0), 'force': ('kN', 1e-3)}


def _truth(tmp_path: Path, *, incl: float = 0.0):
    machine_file = tmp_path / 'machine.yaml'
    machine_file.write_text(MACHINE_YAML.replace('INCL', f'{incl:g}'), encoding='utf-8')
    program = tmp_path / 'program.nc'
    program.write_text(PROGRAM, encoding='ascii')
    machine = load_machine(machine_file)
    sim = simulate_program(load_gcode(program), machine)
    return machine_file, program, machine, sim


def write_drive_campaign(tmp_path: Path, *, measures: str = 'current', rate_hz: float = 1000.0,
                         offset_s: float = 0.6, noise: float = 0.02, time_column: bool = True,
                         flip: tuple[str, ...] = (), kt_in_manifest: bool = True,
                         incl: float = 0.0, seed: int = 1, instrument: dict | None = None):
    """A one-run campaign of a drive trace of X and Y; returns (manifest, truth values)."""
    machine_file, program, machine, sim = _truth(tmp_path, incl=incl)
    dyn = sim.dynamics
    rng = np.random.default_rng(seed)
    duration = float(sim.power.t[-1]) + offset_s + 0.5
    t = np.arange(0.0, duration, 1.0 / rate_hz)
    unit, factor = UNITS[measures]
    cols = {}
    for j, axis in enumerate(dyn.axes):
        torque = dyn.torque_nm[:, j]
        gain = {'current': KT[axis], 'torque': 1.0,
                'force': machine.axis(axis).screw.lead_m / (2.0 * math.pi)}[measures]
        q = torque / gain
        # the record starts offset_s before the program: the machine is at rest (its first
        # and last values held), read at the data's stamps
        value = np.interp(t - offset_s, sim.power.t, q, left=q[0], right=q[-1])
        value = value + rng.normal(0.0, noise, t.size)
        if axis in flip:
            value = -value
        cols[axis] = value * factor
    header = (['time_s'] if time_column else []) + [f'{a}_{measures}' for a in dyn.axes]
    lines = [','.join(header)]
    for i in range(t.size):
        row = ([f'{t[i]:.6f}'] if time_column else []) + [f'{cols[a][i]:.6g}' for a in dyn.axes]
        lines.append(','.join(row))
    data = tmp_path / 'trace.csv'
    data.write_text('\n'.join(lines) + '\n', encoding='ascii')
    meter: dict = {'measures': measures}
    if measures == 'current' and kt_in_manifest:
        meter['kt_nm_a'] = dict(KT)
    meter.update(instrument or {})
    run = {'name': 'trace', 'load_kg': 0.0, 'motion': {'program': str(program)},
           'data': str(data), 'instrument': meter,
           'axes': {a: {measures: {'column': f'{a}_{measures}', 'unit': unit}}
                    for a in dyn.axes}}
    if time_column:
        run['time'] = {'column': 'time_s', 'unit': 's'}
    else:
        run['period_s'] = 1.0 / rate_hz
    doc = {'name': 'drive', 'machine': str(machine_file), 'runs': [run]}
    manifest = tmp_path / 'campaign.yaml'
    import yaml
    manifest.write_text(yaml.safe_dump(doc, sort_keys=False), encoding='utf-8')
    return manifest, {'machine': machine, 'sim': sim, 'offset_s': offset_s}


@pytest.mark.parametrize('rate_hz, time_column', [(50.0, False), (1000.0, True),
                                                  (2000.0, False)])
def test_current_trace_compares_in_amperes_and_watts(tmp_path, rate_hz, time_column):
    manifest, truth = write_drive_campaign(tmp_path, rate_hz=rate_hz, time_column=time_column,
                                           noise=0.02)
    result = compare_campaign(load_campaign(manifest))
    run = result.runs[0]
    assert run.measures == 'current' and run.axes == ('X', 'Y')
    # the offset is found to a fraction of a sample
    assert run.offset_used_s == pytest.approx(truth['offset_s'], abs=0.25 / rate_hz + 1e-3)
    for axis in ('X', 'Y'):
        m = run.signal_metrics[axis]
        assert m.unit == 'A'
        # the residual is the noise written in (0.02 A) and nothing else
        assert m.rmse == pytest.approx(0.02, rel=0.25)
        assert abs(m.bias) < 0.01
        assert m.r2 > 0.95 and m.correlation > 0.97
    assert run.torque_per_unit == KT
    assert not run.sign_warnings
    # the Table-1 figures are in W via I·kt·omega: the energies agree within the noise
    assert abs(run.metrics.energy_error_pct) < 2.0
    assert run.metrics.rmse_w > 0.0


@pytest.mark.parametrize('measures', ['torque', 'force'])
def test_torque_and_force_traces(tmp_path, measures):
    noise = {'torque': 0.01, 'force': 5.0}[measures]
    manifest, truth = write_drive_campaign(tmp_path, measures=measures, noise=noise)
    run = compare_campaign(load_campaign(manifest)).runs[0]
    unit = {'torque': 'N·m', 'force': 'N'}[measures]
    for axis in ('X', 'Y'):
        m = run.signal_metrics[axis]
        assert m.unit == unit
        assert m.rmse == pytest.approx(noise, rel=0.25)
    if measures == 'force':
        lead = truth['machine'].axis('X').screw.lead_m
        assert run.torque_per_unit['X'] == pytest.approx(lead / (2.0 * math.pi))


def test_holding_current_of_a_vertical_axis_is_predicted(tmp_path):
    # Y vertical: at rest its motor holds m·g·lead/(2·pi)/kt, which the trace shows
    manifest, truth = write_drive_campaign(tmp_path, incl=90.0, noise=0.01)
    run = compare_campaign(load_campaign(manifest)).runs[0]
    j = run.axes.index('Y')
    machine = truth['machine']
    mass = 8.0
    hold = mass * 9.80665 * machine.axis('Y').screw.lead_m / (2.0 * math.pi) / KT['Y']
    first = run.signal_sim[:20, j]     # the record starts with the machine at rest
    np.testing.assert_allclose(first, hold, rtol=1e-6)
    assert run.signal_metrics['Y'].rmse == pytest.approx(0.01, rel=0.25)


def test_a_declared_constant_force_is_predicted_at_rest_too(tmp_path):
    # offset_force (a cable carrier) and gravity (an incline analyze found) pull at rest as in
    # motion: a force trace shows F0 at every stop; a friction effect adds nothing at rest
    from dataclasses import replace

    from feed_axis_energy.machine import DeclaredEffect, moved_mass_kg
    manifest, truth = write_drive_campaign(tmp_path, measures='force', noise=0.5)
    machine = truth['machine']
    plain = compare_campaign(load_campaign(manifest), machine=machine).runs[0]
    j = plain.axes.index('X')
    effects = (DeclaredEffect(id='offset_force', axis='X', params=(('f0_n', 12.0),)),
               DeclaredEffect(id='gravity', axis='X', params=(('sin_theta', 0.1),)),
               DeclaredEffect(id='viscous', axis='X', params=(('c_n_s_m', 50.0),)))
    added = compare_campaign(load_campaign(manifest),
                             machine=replace(machine, effects=effects)).runs[0]
    # the record starts at rest: 12 N + 0.1·m·g more, the viscous force nothing
    rest = added.signal_sim[:20, j] - plain.signal_sim[:20, j]
    want = 12.0 + 0.1 * moved_mass_kg(machine, 'X', 0.0) * 9.80665
    np.testing.assert_allclose(rest, want, rtol=1e-6)
    assert 'Y' in added.axes
    np.testing.assert_allclose(added.signal_sim[:20, added.axes.index('Y')],
                               plain.signal_sim[:20, added.axes.index('Y')])


def test_current_without_torque_constant_names_the_key(tmp_path):
    manifest, _ = write_drive_campaign(tmp_path, kt_in_manifest=False)
    with pytest.raises(ConfigError) as info:
        compare_campaign(load_campaign(manifest))
    text = str(info.value)
    assert 'axes.X.drive.kt_nm_a' in text and 'instrument.kt_nm_a.X' in text
    assert str(manifest) in text


def test_wrong_sign_is_detected_and_invert_fixes_it(tmp_path):
    manifest, _ = write_drive_campaign(tmp_path, flip=('Y',))
    result = compare_campaign(load_campaign(manifest))
    run = result.runs[0]
    assert run.signal_metrics['Y'].correlation < -0.9
    assert [w for w in result.warnings if 'Y: the measured current is anti-correlated' in w]
    assert 'instrument.invert: [Y]' in result.warnings[-1]
    assert not [w for w in result.warnings if 'X: the measured' in w]
    # declared, the trace is negated on loading and agrees
    other = tmp_path / 'fixed'
    other.mkdir()
    fixed, _ = write_drive_campaign(other, flip=('Y',), instrument={'invert': ['Y']})
    run = compare_campaign(load_campaign(fixed)).runs[0]
    assert not run.sign_warnings
    assert run.signal_metrics['Y'].correlation > 0.97


@pytest.mark.parametrize('instrument, key, text', [
    ({'measures': 'current', 'kt_nm_a': {'X': -1.0}}, 'kt_nm_a.X', 'positive'),
    ({'measures': 'current', 'kt_nm_a': {'X': 5.0e3}}, 'kt_nm_a.X', '[1e-4, 1e3]'),
    ({'measures': 'current', 'kt_nm_a': [1.0]}, 'kt_nm_a', 'mapping axis'),
    ({'measures': 'torque', 'kt_nm_a': {'X': 1.0}}, 'kt_nm_a', 'convert a current'),
    ({'measures': 'shaft', 'invert': ['X']}, 'invert', 'sign convention'),
    ({'measures': 'current', 'invert': 'X'}, 'invert', 'list of axis names'),
    ({'measures': 'current', 'invert': ['Z']}, 'invert', "'Z' has no current column"),
    ({'measures': 'current', 'kt_nm_a': {'Z': 1.0}}, 'kt_nm_a.Z', "no axis 'Z'"),
    ({'measures': 'volts'}, 'measures', 'expected one of shaft, motor, supply, current'),
    ({'measures': 'force'}, 'axes', 'no axis has a force column'),
    ({'measures': 'current', 'noise': -0.1}, 'noise', 'positive'),
    ({'measures': 'current', 'noise': 'low'}, 'noise', ''),
])
def test_manifest_errors_name_the_key(tmp_path, instrument, key, text):
    doc = {'machine': 'm.yaml', 'runs': [{
        'name': 'r', 'load_kg': 0.0, 'motion': {'program': 'p.nc'}, 'data': 'd.csv',
        'period_s': 0.001, 'instrument': instrument,
        'axes': {'X': {'current': {'column': 'IX', 'unit': 'A'}}}}]}
    with pytest.raises(ConfigError) as info:
        campaign_from_dict(doc, file=tmp_path / 'c.yaml', check_files=False)
    assert info.value.key == (f'runs[0].instrument.{key}' if key != 'axes' else 'runs[0].axes')
    assert text in str(info.value)


def test_a_declared_noise_level_is_read_and_used_by_analyze_when_every_run_has_one(tmp_path):
    from types import SimpleNamespace
    from feed_axis_energy.identify.analyze import declared_noise
    run = {'load_kg': 0.0, 'motion': {'program': 'p.nc'}, 'period_s': 0.001,
           'axes': {'X': {'current': {'column': 'IX', 'unit': 'A'}}}}
    doc = {'machine': 'm.yaml', 'runs': [
        {**run, 'name': 'a', 'data': 'a.csv',
         'instrument': {'measures': 'current', 'noise': 0.05}},
        {**run, 'name': 'b', 'data': 'b.csv',
         'instrument': {'measures': 'current', 'noise': 0.08, 'window_s': 0.0}},
        {**run, 'name': 'c', 'data': 'c.csv', 'instrument': {'measures': 'current'}}]}
    campaign = campaign_from_dict(doc, file=tmp_path / 'c.yaml', check_files=False)
    a = campaign.run('a').instrument
    assert a.noise == 0.05 and not a.declared      # the noise declares no window
    assert campaign.run('b').instrument.noise == 0.08 and campaign.run('b').instrument.declared
    named = [SimpleNamespace(name=n) for n in ('a', 'b')]
    assert declared_noise(campaign, named) == 0.08     # the larger where runs differ
    assert declared_noise(campaign, named + [SimpleNamespace(name='c')]) is None


def test_power_runs_keep_their_metrics_and_get_the_quantity_block(tmp_path):
    # a power trace: quantity metrics in W beside the Table-1 ones, same numbers for RMSE
    manifest, _ = write_drive_campaign(tmp_path, measures='torque', noise=0.01)
    run = compare_campaign(load_campaign(manifest)).runs[0]
    d = run.to_dict()
    assert d['quantity']['measures'] == 'torque' and d['quantity']['unit'] == 'N·m'


def test_compare_json_contract_for_current(tmp_path, capsys):
    manifest, _ = write_drive_campaign(tmp_path, rate_hz=500.0, noise=0.02)
    assert main(['compare', str(manifest), '--json', '--quiet']) == 0
    out = json.loads(capsys.readouterr().out)
    run = out['runs'][0]
    q = run['quantity']
    assert set(q) == {'measures', 'unit', 'column', 'metrics', 'sign_check', 'torque_per_unit',
                      'power_equivalent', 'abs_energy_j'}
    assert q['measures'] == 'current' and q['unit'] == 'A' and q['column'] == 'current'
    assert q['power_equivalent'] == 'I*g*omega'
    assert q['torque_per_unit'] == KT
    for axis in ('X', 'Y'):
        m = q['metrics'][axis]
        assert set(m) == {'unit', 'n_samples', 'rmse_a', 'mae_a', 'max_abs_error_a', 'bias_a',
                          'r2', 'correlation', 'rms_meas_a'}
        assert m['rmse_a'] == pytest.approx(0.02, rel=0.3)
        assert set(q['abs_energy_j'][axis]) == {'meas', 'sim'}
        assert q['abs_energy_j'][axis]['sim'] > 0.0
    # the Table-1 block stays in W (the power equivalent) with its documented keys
    assert 'rmse_w' in run['metrics']['total'] and 'energy_error_pct' in run['metrics']['X']
    group = out['groups'][0]
    assert set(group['quantity_metrics']) == {'X', 'Y'}
    assert 'rmse_a' in group['quantity_metrics']['X']
    assert q['sign_check'] == []


def test_compare_table_shows_the_quantity_with_units(tmp_path, capsys):
    manifest, _ = write_drive_campaign(tmp_path, rate_hz=200.0, noise=0.02, flip=('X',))
    assert main(['compare', str(manifest), '--quiet']) == 0
    text = capsys.readouterr().out
    assert 'current per axis' in text and 'RMSE [A]' in text and 'bias [A]' in text
    assert 'kt [N·m/A]' in text
    assert 'anti-correlated' in text and 'instrument.invert: [X]' in text


def test_compare_report_shows_the_trace_in_its_unit(tmp_path, capsys):
    manifest, _ = write_drive_campaign(tmp_path, rate_hz=100.0, noise=0.02, flip=('Y',))
    report = tmp_path / 'rep'
    assert main(['compare', str(manifest), '--quiet', '--report', str(report)]) == 0
    html = (report / 'index.html').read_text(encoding='utf-8')
    # the trace plot comes before the three power plots, and the table is in A
    assert html.count('<img src="data:image/png;base64,') == 4
    assert 'torque-producing motor current [A]' in html and 'N·m/A' in html
    assert 'Time-shift and sign warnings' in html and 'instrument.invert: [Y]' in html


@pytest.mark.parametrize('measures', ['current', 'force'])
def test_import_refuses_a_drive_trace_naming_the_run(tmp_path, capsys, measures):
    manifest, _ = write_drive_campaign(tmp_path, measures=measures, rate_hz=100.0)
    out = tmp_path / 'bags'
    assert main(['import', str(manifest), '--out', str(out), '--quiet']) == 1
    err = capsys.readouterr().err
    assert 'runs[0].axes' in err and 'compare such a run from its CSV file' in err
    assert 'Traceback' not in err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize('lead_m', [0.005, 0.04])
def test_force_of_a_linear_stand_is_the_axis_force_whatever_the_lead(tmp_path, lead_m):
    # a stand without rotating parts (inertias 0, efficiency 1): M·2·pi/lead is the force
    # m·a + m·g·sin(incl) + F_loss of the dynamics, and the lead cancels
    from feed_axis_energy.machine.file import machine_from_dict, machine_to_dict
    from feed_axis_energy.measured.quantity import predicted_signal, torque_per_unit
    _, _, machine, _ = _truth(tmp_path, incl=30.0)
    d = machine_to_dict(machine)
    for axis in d['axes'].values():
        axis['screw']['lead_m'] = lead_m
        axis['inertias'] = {'motor_kg_m2': 0.0, 'coupling_kg_m2': 0.0, 'screw_kg_m2': 0.0}
    stand = machine_from_dict(d, file='<stand>')
    sim = simulate_program(load_gcode(tmp_path / 'program.nc'), stand)
    gains = torque_per_unit('force', stand, ('X', 'Y'))
    force = predicted_signal('force', sim, stand, ('X', 'Y'), gains=gains)
    np.testing.assert_allclose(force, sim.dynamics.force_n, rtol=1e-9, atol=1e-9)
    assert np.abs(force[:, 1]).max() > 8.0 * 9.80665 * 0.5 * 0.99     # gravity on Y at 30°


def test_signal_metrics_over_several_chunks_equal_whole_array_formulas():
    rng = np.random.default_rng(5)
    n = 2 * CHUNK + 1001
    meas = 3.0 + np.sin(np.linspace(0.0, 40.0, n)) + rng.normal(0.0, 0.1, n)
    sim = 0.9 * meas + rng.normal(0.2, 0.05, n)
    m = signal_metrics(meas, sim, quantity=quantity_of('current'))
    err = sim - meas
    assert m.n_samples == n and m.unit == 'A'
    assert m.rmse == pytest.approx(np.sqrt(np.mean(err ** 2)), rel=1e-12)
    assert m.bias == pytest.approx(err.mean(), rel=1e-10)
    assert m.mae == pytest.approx(np.abs(err).mean(), rel=1e-12)
    assert m.max_abs_error == np.abs(err).max()
    assert m.r2 == pytest.approx(1.0 - np.sum(err ** 2) / np.sum((meas - meas.mean()) ** 2),
                                 rel=1e-12)
    assert m.correlation == pytest.approx(np.corrcoef(meas, sim)[0, 1], rel=1e-12)
    assert m.rms_meas == pytest.approx(np.sqrt(np.mean(meas ** 2)), rel=1e-12)
    sim[n - 5] = np.nan
    with pytest.raises(DataError, match='not finite'):
        signal_metrics(meas, sim, quantity=quantity_of('current'))


def test_measured_power_is_a_read_only_view_unless_it_must_change():
    t = np.arange(5) * 1e-3
    power = np.arange(15.0).reshape(5, 3)
    run = MeasuredRun(name='r', file='r.csv', t=t, axes=('X', 'Y', 'Z'),
                      power_axes=('X', 'Y', 'Z'), power_w=power, load_kg=0.0)
    view = measured_signal(run, measures='shaft', axes=('Y', 'Z'))
    assert np.shares_memory(view, power) and not view.flags.writeable
    np.testing.assert_array_equal(view, power[:, 1:])
    # out of order or inverted: a new array, the run untouched
    swapped = measured_signal(run, measures='shaft', axes=('Z', 'X'))
    assert not np.shares_memory(swapped, power)
    np.testing.assert_array_equal(swapped, power[:, [2, 0]])
    inverted = measured_signal(run, measures='shaft', axes=('X',), invert=('X',))
    np.testing.assert_array_equal(inverted[:, 0], -power[:, 0])
    assert power[1, 0] == 3.0
