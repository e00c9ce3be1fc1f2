"""compare_campaign on synthetic campaigns whose truth is known, and on the UMich data.

The synthetic "measured" data are made with the core's own simulation, then passed through an
instrument written out here independently of feed_axis_energy.measured.align: a known time
shift, the mean
over a 50 ms window ending at each stamp (exact trapezoid over the 1 kHz samples), a gain and
Gaussian noise, written as CSV in kW, mm and mm/min with a millisecond clock.

Other test modules load :func:`write_campaign` from this file.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import must_run
import numpy as np
import pytest
from scipy import signal

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.gcode.load import load_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.compare import compare_campaign, compare_run
from feed_axis_energy.sim.simulate import simulate_program

REPO = Path(__file__).resolve().parents[2]
RATE_HZ = 1000
WINDOW_MS = 50

MACHINE_YAML = """\
name: synthetic_xy
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
    loss: {model: power_regression, a: 0.2505, b: 0.3471, x_unit: mm/s, y_unit: W/(mm/s)}
  Y:
    table_mass_kg: 8.0
    rides_on: null
    inclination_deg: 0.0
    screw: {diameter_m: 0.016, lead_m: 0.005, length_m: 0.4, starts: 1, efficiency: 1.0}
    inertias: {motor_kg_m2: 6.0e-5, coupling_kg_m2: 1.0e-5}
    limits: {velocity_m_s: 0.3, acceleration_m_s2: 2.0, jerk_m_s3: 40.0}
    loss: {model: power_regression, a: 0.2505, b: 0.3471, x_unit: mm/s, y_unit: W/(mm/s)}
"""

# No two segments alike, so the cross-correlation has one clear peak.
PROGRAM = """\
( synthetic test program: X and Y moves of different lengths and feeds )
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

COLUMNS = ['Time_ms', 'X_Power_kW', 'Y_Power_kW', 'X_Pos_mm', 'Y_Pos_mm', 'X_Vel_mm_min',
           'Y_Vel_mm_min', 'Stage']


def _window_means(p: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Mean of the piecewise-linear 1 kHz signal ``p`` over samples start .. start+WINDOW_MS."""
    seg = 0.5 * (p[1:] + p[:-1])
    cum = np.concatenate([np.zeros((1, p.shape[1])), np.cumsum(seg, axis=0)])
    return (cum[start + WINDOW_MS] - cum[start]) / WINDOW_MS


def write_campaign(root: Path, runs: list[dict], *, seed: int = 7,
                   program_text: str = PROGRAM) -> Path:
    """Write machine, program, CSV data and manifest under ``root``; return the manifest.

    Each run dict has ``name``, ``load_kg`` and optionally ``offset_ms`` (int, how much later
    the measured record is), ``factor`` (gain on the measured power), ``noise_w`` (sigma),
    ``motion`` (``'program'`` or ``'actual'``), ``role`` and ``filter_ms`` (the meter smooths
    with a first-order lag of that time constant before it averages; simulated here with
    scipy's continuous-time ``lsim``, the input linear between the 1 kHz samples).
    """
    root.mkdir(parents=True, exist_ok=True)
    (root / 'machine.yaml').write_text(MACHINE_YAML)
    (root / 'part.nc').write_text(program_text)
    machine = load_machine(root / 'machine.yaml')
    program = load_gcode(root / 'part.nc')
    rng = np.random.default_rng(seed)
    manifest_runs = []
    for spec in runs:
        sim = simulate_program(program, machine, load_kg=spec['load_kg'])
        assert sim.power.axes == ('X', 'Y')
        off = int(spec.get('offset_ms', 0))
        pad = 2000 + abs(off)
        power = np.pad(sim.power.power_w, ((pad, pad), (0, 0)), mode='edge')
        if spec.get('filter_ms'):
            tt = 1e-3 * np.arange(power.shape[0])
            lag = signal.lti([1.0], [1e-3 * spec['filter_ms'], 1.0])
            # at rest on the first value before the record (the deviation starts at 0)
            power = np.column_stack([
                power[0, j] + signal.lsim(lag, power[:, j] - power[0, j], tt, interp=True)[1]
                for j in range(power.shape[1])])
        pos = np.pad(sim.motion.pos, ((pad, pad), (0, 0)), mode='edge')
        vel = np.pad(sim.motion.vel, ((pad, pad), (0, 0)), mode='edge')
        n_sim = sim.power.t.size
        # stamp k [ms] (0 = the record's first stamp, which load_run makes t = 0) sees
        # simulated time k - off
        stamps = np.arange(0, n_sim + off + 1000, WINDOW_MS)
        idx_end = stamps - off + pad          # padded index of the window's end
        mean = _window_means(power, idx_end - WINDOW_MS)
        p_meas = spec.get('factor', 1.0) * mean
        p_meas = p_meas + rng.normal(0.0, spec.get('noise_w', 0.0), p_meas.shape)
        path = root / f'{spec["name"]}.csv'
        with open(path, 'w', newline='') as fh:
            w = csv.writer(fh)
            w.writerow(COLUMNS)
            for k, i in enumerate(idx_end):
                w.writerow([f'{5000 + stamps[k]:d}', f'{p_meas[k, 0] / 1e3:.10g}',
                            f'{p_meas[k, 1] / 1e3:.10g}', f'{pos[i, 0] * 1e3:.9g}',
                            f'{pos[i, 1] * 1e3:.9g}', f'{vel[i, 0] * 6e4:.9g}',
                            f'{vel[i, 1] * 6e4:.9g}', 'cut'])
        motion = ({'program': 'part.nc'} if spec.get('motion', 'program') == 'program'
                  else {'from_data': spec['motion']})
        entry = {'name': spec['name'], 'load_kg': spec['load_kg'], 'data': path.name,
                 'motion': motion}
        if spec.get('role'):
            entry['role'] = spec['role']
        if spec.get('instrument'):
            entry['instrument'] = spec['instrument']
        manifest_runs.append(entry)
    axes = {a: {'power': {'column': f'{a}_Power_kW', 'unit': 'kW'},
                'position': {'column': f'{a}_Pos_mm', 'unit': 'mm'},
                'velocity': {'column': f'{a}_Vel_mm_min', 'unit': 'mm/min'}}
            for a in ('X', 'Y')}
    manifest = {'name': 'synthetic', 'machine': 'machine.yaml',
                'defaults': {'time': {'column': 'Time_ms', 'unit': 'ms'}, 'axes': axes},
                'runs': manifest_runs}
    out = root / 'campaign.yaml'
    out.write_text(json.dumps(manifest, indent=1))     # JSON is YAML
    return out


@pytest.fixture(scope='module')
def campaign(tmp_path_factory):
    root = tmp_path_factory.mktemp('synthetic')
    runs = [
        {'name': 'late', 'load_kg': 0.0, 'offset_ms': 437, 'noise_w': 0.2, 'role': 'validate'},
        {'name': 'early', 'load_kg': 0.0, 'offset_ms': -213, 'noise_w': 0.2},
        {'name': 'gain110', 'load_kg': 17.336, 'offset_ms': 120, 'factor': 1.1, 'noise_w': 0.2},
        {'name': 'gain080', 'load_kg': 17.336, 'offset_ms': 0, 'factor': 0.8, 'noise_w': 0.2},
        # this meter averages 50 ms ending at the stamp while positions are read at it:
        # declared, since motion from data defaults to point samples
        {'name': 'fromdata', 'load_kg': 5.0, 'offset_ms': 300, 'noise_w': 0.2,
         'motion': 'actual', 'instrument': {'window_s': 'period', 'stamp': 'end'}},
        {'name': 'noise', 'load_kg': 5.0, 'factor': 0.0, 'noise_w': 5.0},
    ]
    manifest = write_campaign(root, runs)
    c = load_campaign(manifest)
    return c, compare_campaign(c, max_lag_s=1.0)


@pytest.mark.parametrize('name, offset_s', [('late', 0.437), ('early', -0.213),
                                            ('gain110', 0.120), ('gain080', 0.0)])
def test_offset_is_recovered(campaign, name, offset_s):
    run = {r.name: r for r in campaign[1].runs}[name]
    assert run.offset.status == 'ok', run.offset.message
    assert run.offset.peak_correlation > 0.99
    assert run.offset_used_s == pytest.approx(offset_s, abs=0.002)
    assert run.window_s == pytest.approx(0.050)


def test_metrics_near_zero_when_the_model_is_the_truth(campaign):
    for name in ('late', 'early'):
        run = {r.name: r for r in campaign[1].runs}[name]
        peak = np.abs(run.total_meas_w).max()
        assert peak > 100.0                     # a real signal, hundreds of watts
        m = run.metrics
        # noise sigma 0.2 W: mean |noise| = 0.16 W; alignment error adds a little
        assert m.avg_diff_error_w < 0.5
        assert m.rmse_w < 1.0
        assert m.avg_pct_error_pct < 1.0
        assert abs(m.energy_error_pct) < 0.5
        for axis in ('X', 'Y'):
            assert run.axis_metrics[axis].avg_diff_error_w < 0.5


@pytest.mark.parametrize('name, factor', [('gain110', 1.1), ('gain080', 0.8)])
def test_gain_error_shows_in_percentual_and_energy_error(campaign, name, factor):
    run = {r.name: r for r in campaign[1].runs}[name]
    m = run.metrics
    # P_sim = P_meas / factor, so |dP| / |P_meas| = |1 - 1/factor| at every sample, and
    # E_sim / E_meas - 1 = 1/factor - 1
    expected_pct = 100.0 * abs(1.0 - 1.0 / factor)      # 9.0909 % and 25 %
    assert m.avg_pct_error_pct == pytest.approx(expected_pct, abs=0.25)
    assert m.energy_error_pct == pytest.approx(100.0 * (1.0 / factor - 1.0), abs=0.25)
    assert m.energy_error_j == pytest.approx(m.energy_sim_j - m.energy_meas_j)
    # the differential error is that fraction of the measured power, on average
    expected_w = abs(1.0 - 1.0 / factor) * np.abs(run.total_meas_w).mean()
    assert m.avg_diff_error_w == pytest.approx(expected_w, rel=0.05)
    assert m.avg_diff_error_w > 10.0 * campaign[1].runs[0].metrics.avg_diff_error_w


def test_simulated_power_is_interval_averaged_not_point_sampled(campaign):
    c, result = campaign
    run = {r.name: r for r in result.runs}['late']
    machine = load_machine(c.machine)
    sim = simulate_program(load_gcode(c.run('late').motion_program), machine, load_kg=0.0)
    point = np.interp(run.t - run.offset_used_s, sim.power.t, sim.power.total_w)
    # point samples miss the averaging: their error is many times the compared one
    point_err = np.abs(point - run.total_meas_w).mean()
    assert point_err > 5.0 * run.metrics.avg_diff_error_w


def test_motion_from_data_runs_and_agrees(campaign):
    run = {r.name: r for r in campaign[1].runs}['fromdata']
    assert run.motion_source == 'data:actual'
    # positions and power come through the same shifted clock: nothing left to align
    assert abs(run.offset_used_s) < 0.02
    # power from positions differentiated at 50 ms: close in energy, not sample by sample
    assert abs(run.metrics.energy_error_pct) < 5.0


def test_motion_from_data_defaults_to_point_samples(tmp_path):
    runs = [{'name': f'r{k}', 'load_kg': 5.0, 'noise_w': 0.2, 'motion': 'actual'}
            for k in range(2)]
    res = compare_campaign(load_campaign(write_campaign(tmp_path, runs)), max_lag_s=0.5)
    assert [(r.window_s, r.stamp, r.instrument) for r in res.runs] == [
        (0.0, 'end', 'point samples (default)')] * 2
    assert res.to_dict()['runs'][0]['instrument'] == 'point samples (default)'


def test_a_declared_instrument_that_does_not_fit_is_reported(tmp_path):
    # the data come through a 50 ms trailing window; declared as point samples, compare
    # finds that one period fits better and says so
    runs = [{'name': f'r{k}', 'load_kg': 5.0, 'offset_ms': 100 * k, 'noise_w': 0.2,
             'instrument': 'point'} for k in range(2)]
    res = compare_campaign(load_campaign(write_campaign(tmp_path, runs)), max_lag_s=0.5)
    assert all(r.window_s == 0.0 and r.instrument == 'point samples' for r in res.runs)
    assert [[f.label for f in r.meter_fits] for r in res.runs] == [['declared', 'period']] * 2
    for r in res.runs:
        declared, period = r.meter_fits
        assert period.rms_w < 0.8 * declared.rms_w
    warning = ' '.join(res.instrument_warnings)
    assert 'a 50 ms window fit better than point samples' in warning, warning
    assert res.to_dict()['warnings'] == res.offset_warnings + res.instrument_warnings
    # declared right (here the default for a program), nothing to report
    right = [{k: v for k, v in r.items() if k != 'instrument'} for r in runs]
    c = load_campaign(write_campaign(tmp_path / 'right', right))
    assert compare_campaign(c, max_lag_s=0.5).instrument_warnings == []


def test_a_wrong_stamp_position_is_reported_when_the_motion_comes_from_the_data(tmp_path):
    # the meter averages the 50 ms ending at each stamp, where the positions are read. With
    # the motion from the data the simulation runs on those stamps, so a window declared at
    # its start cannot hide behind a 50 ms offset: the check searches offsets near 0 only
    runs = [{'name': f'r{k}', 'load_kg': 5.0, 'offset_ms': 100 * k, 'noise_w': 0.2,
             'motion': 'actual', 'instrument': {'window_s': 'period', 'stamp': 'start'}}
            for k in range(2)]
    res = compare_campaign(load_campaign(write_campaign(tmp_path, runs)), max_lag_s=0.5)
    for r in res.runs:
        fits = {f.label: f for f in r.meter_fits}
        assert set(fits) == {'declared', 'point', 'period', 'period_centre'}
        assert all(f.same_clock and f.reach_s == pytest.approx(0.0125) for f in fits.values())
        assert all(abs(f.offset_s) <= 0.0125 + 1e-9 for f in fits.values())
        assert fits['period'].stamp == 'end' and fits['period_centre'].stamp == 'centre'
        # the right meter, the one the data were made with, is the best by far
        assert fits['period'].rms_w < 0.5 * fits['declared'].rms_w
        assert fits['period'].rms_w < min(fits['point'].rms_w, fits['period_centre'].rms_w)
        # compare itself shifts the declared window by a period to fit (the record reads
        # 50 ms "late"): nothing else would tell
        assert r.offset_used_s == pytest.approx(0.05, abs=0.01)
    warning = ' '.join(res.instrument_warnings)
    assert ('a 50 ms window stamped at its end fit better than 50 ms window stamped at its '
            'start') in warning, warning
    assert "within 12.5 ms of the data's own stamps" in warning
    assert res.to_dict()['runs'][0]['instrument_check'][0]['same_clock'] is True
    # declared as the data were made: nothing to report
    right = [dict(r, instrument={'window_s': 'period', 'stamp': 'end'}) for r in runs]
    c = load_campaign(write_campaign(tmp_path / 'right', right))
    assert compare_campaign(c, max_lag_s=0.5).instrument_warnings == []


def test_a_weak_alignment_is_a_result_compared_at_offset_zero(campaign):
    run = {r.name: r for r in campaign[1].runs}['noise']
    assert run.offset.status == 'weak'
    # its record maps the motion: compared at the motion's offset (0 here), and says so
    assert run.offset.anchor == 'motion'
    assert run.offset_used_s == pytest.approx(run.offset.motion_s)
    assert run.offset_used_s == pytest.approx(0.0, abs=0.002)
    assert "compared at the motion's offset" in run.offset.message
    assert math.isfinite(run.metrics.avg_diff_error_w)
    assert any(w.startswith('noise: offset weak') for w in campaign[1].offset_warnings)


def test_groups_pool_runs_by_load(campaign):
    c, result = campaign
    groups = {g.load_kg: g for g in result.groups}
    assert list(groups) == [0.0, 5.0, 17.336]
    assert groups[17.336].runs == ('gain110', 'gain080')
    runs = {r.name: r for r in result.runs}
    g = groups[17.336].metrics
    assert g.n_samples == runs['gain110'].metrics.n_samples + runs['gain080'].metrics.n_samples
    assert g.energy_meas_j == pytest.approx(runs['gain110'].metrics.energy_meas_j
                                            + runs['gain080'].metrics.energy_meas_j)
    assert set(groups[0.0].axis_metrics) == {'X', 'Y'}


def test_to_dict_is_strict_json_with_units_in_keys(campaign):
    d = campaign[1].to_dict()
    text = json.dumps(d, allow_nan=False)
    back = json.loads(text)
    run = back['runs'][0]
    assert run['name'] == 'late' and run['role'] == 'validate'
    assert set(run['offset']) == {'found_s', 'used_s', 'correlation', 'rms_w', 'status',
                                  'message', 'runner_up', 'drift_ppm', 'drift_message',
                                  'anchor', 'motion_s'}
    assert set(run['metrics']) == {'total', 'X', 'Y'}
    assert {'avg_diff_error_w', 'avg_pct_error_pct', 'max_diff_error_w', 'max_pct_error_pct',
            'energy_error_j', 'energy_error_pct', 'rmse_w'} <= set(run['metrics']['total'])
    assert back['groups'][0]['metrics']['total']['pct_floor_w'] is None   # NaN -> null


def test_selected_runs_and_compare_run(campaign):
    c, full = campaign
    part = compare_campaign(c, runs=['gain080', 'late'], max_lag_s=1.0)
    assert [r.name for r in part.runs] == ['gain080', 'late']
    one = compare_run(c.run('late'), load_machine(c.machine), offset_s=0.437)
    assert one.offset.status == 'fixed' and one.offset_used_s == 0.437
    ref = {r.name: r for r in full.runs}['late'].metrics
    assert one.metrics.avg_diff_error_w == pytest.approx(ref.avg_diff_error_w, abs=0.05)


def test_unknown_run_is_named(campaign):
    with pytest.raises(ConfigError, match="no run named 'nope'; runs are late, early"):
        compare_campaign(campaign[0], runs=['nope'])


def test_measured_axis_missing_from_the_machine(tmp_path):
    manifest = write_campaign(tmp_path, [{'name': 'r', 'load_kg': 0.0}])
    machine_yaml = (tmp_path / 'machine.yaml').read_text()
    (tmp_path / 'machine.yaml').write_text(machine_yaml.split('  Y:')[0])
    (tmp_path / 'part.nc').write_text('G21 G90 G61\nG1 X100 F6000\nG4 P0.5\nG1 X0\nM30\n')
    with pytest.raises(ConfigError, match=r"runs\[0\]\.axes\.Y.*not an axis of machine"):
        compare_campaign(load_campaign(manifest))


UMICH = REPO / 'config' / 'campaigns' / 'umich_mill.yaml'
UMICH_DATA = (REPO.parent / 'shared' / 'data' / 'umich-cnc-mill').resolve()


@must_run.skipif('shared', not (UMICH_DATA / 'experiment_03.csv').exists(),
                 f'UMich CNC mill data not found at {UMICH_DATA}')
def test_umich_validate_runs_compare():
    c = load_campaign(UMICH)
    names = [r.name for r in c.runs_with_role('validate')]
    result = compare_campaign(c, runs=names)
    assert [r.name for r in result.runs] == ['exp03', 'exp06']
    for run in result.runs:
        assert run.axes == ('X', 'Y')              # Z has no power column
        assert run.motion_source == 'data:actual'
        # motion from the data: point samples unless the manifest declares a meter
        assert run.window_s == 0.0 and run.instrument == 'point samples (default)'
        # The motion uses the measured actual velocities and accelerations (not positions
        # rounded to ~1 mm and glitching to the home position), so the records align clearly
        # and the simulated power follows the measured one to about a watt.
        assert run.offset.status == 'ok'
        assert run.metrics.avg_diff_error_w < 2.0
        assert run.metrics.n_samples == run.t.size
        assert math.isfinite(run.metrics.rmse_w) and run.metrics.energy_meas_j > 0.0
    assert [g.load_kg for g in result.groups] == [0.0]
    # the default meter fits these data better than a window of one period stamped at its
    # end, centre or start: no instrument warning
    assert result.instrument_warnings == []
    json.dumps(result.to_dict(), allow_nan=False)


@pytest.fixture(scope='module')
def smoothing(tmp_path_factory):
    # a meter that smooths with a 20 ms first-order lag before its 50 ms window, the record
    # 120 ms later than the simulation: declared, and the same data read as if it did not
    root = tmp_path_factory.mktemp('smoothing')
    runs = [{'name': 'declared', 'load_kg': 0.0, 'offset_ms': 120, 'noise_w': 0.05,
             'filter_ms': 20, 'instrument': {'filter_s': 0.02}},
            {'name': 'undeclared', 'load_kg': 0.0, 'offset_ms': 120, 'noise_w': 0.05,
             'filter_ms': 20}]
    c = load_campaign(write_campaign(root, runs))
    return {r.name: r for r in compare_campaign(c, max_lag_s=1.0).runs}


def test_a_declared_filter_is_the_instrument(smoothing):
    good, plain = smoothing['declared'], smoothing['undeclared']
    assert (good.filter_s, plain.filter_s) == (0.02, 0.0)
    assert good.to_dict()['filter_s'] == 0.02
    assert 'after a 20 ms first-order filter' in good.instrument
    # read through its filter the record is found where it is; read as a plain window the
    # filter's delay goes into the offset and its rounded edges stay in the residual
    assert good.offset_used_s == pytest.approx(0.120, abs=0.001)
    assert plain.offset_used_s > 0.130
    assert good.metrics.rmse_w < 0.1
    assert plain.metrics.rmse_w > 3.0 * good.metrics.rmse_w
