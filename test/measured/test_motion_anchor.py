"""Alignment on the measured motion (issue 24 §1): the time offset from the record's velocity
columns survives a large missing effect that pulls the power correlation, and ``analyze``
uses the motion-anchored runs at one common meter lag.

The records come from the independent truth (``bench/truth_model.py``: its own physics),
written as ``bench/truth_matrix.py`` writes its campaigns: the paper's 15 runs, offsets up
to two strokes, clock drift, a 50 ms power meter, position and velocity columns.
"""
import json
import math
from pathlib import Path

import numpy as np
from bench_modules import load_bench
import pytest
import yaml

from feed_axis_energy.identify.timing import at_common_lag, motion_lag_s
from feed_axis_energy.machine import load_machine
from feed_axis_energy.measured import compare_campaign, load_campaign, load_run
from feed_axis_energy.measured.run import MeasuredRun
from feed_axis_energy.measured.spatial import measured_velocity, motion_anchor

TOL_S = 0.0125      # a quarter of the 50 ms meter period (the matrix's "misaligned")


@pytest.fixture(scope='module')
def matrix():
    return load_bench('truth_matrix')


def _campaign(matrix, tmp: Path, case: str, share: float, seed: int = 3):
    tm, tt = matrix.tm, matrix.tt
    axis = tm.read_axis(tt.MACHINE)
    runs = tt.make_runs(axis)
    base, extra = matrix.unit_powers(runs, axis, case)
    offsets = matrix.write_campaign(tmp, case=case, amp=share * base / extra, runs=runs,
                                    axis=axis, seed=seed, cls='large')
    return tmp / 'manifest.yaml', offsets


@pytest.fixture(scope='module')
def heavy(matrix, tmp_path_factory):
    """A moved mass the machine file lacks, worth 15 % of the energy."""
    return _campaign(matrix, tmp_path_factory.mktemp('heavy'), 'mass_error', 0.15)


def test_the_motion_pins_what_the_power_pulls_away(heavy):
    manifest, truth = heavy
    result = compare_campaign(load_campaign(manifest))
    pulled = []
    for run in result.runs:
        o = run.offset
        assert o.anchor == 'motion' and o.status == 'ok', o.message
        assert abs(o.motion_s - truth[run.name]) < 1e-3, (run.name, o.motion_s)
        assert 'aligned on the measured motion' in o.message
        pulled.append(abs(o.offset_s - truth[run.name]))
    # the case is a real one: the power refinement alone is pulled off by the missing mass
    assert max(pulled) > TOL_S


def test_a_record_without_motion_columns_is_aligned_on_its_power(heavy, tmp_path):
    manifest, _ = heavy
    doc = yaml.safe_load(manifest.read_text(encoding='utf-8'))
    doc['defaults']['axes']['X'] = {'power': doc['defaults']['axes']['X']['power']}
    for run in doc['runs']:
        run['data'] = str(manifest.parent / run['data'])
    doc['machine'] = str(manifest.parent / doc['machine'])
    for run in doc['runs']:
        run['motion']['program'] = str(manifest.parent / run['motion']['program'])
    plain = tmp_path / 'manifest.yaml'
    plain.write_text(yaml.safe_dump(doc, sort_keys=False), encoding='utf-8')
    result = compare_campaign(load_campaign(plain), runs=[doc['runs'][0]['name']])
    o = result.runs[0].offset
    assert o.anchor == 'power' and math.isnan(o.motion_s)
    # JSON contract: the keys are there, NaN as null
    d = json.loads(json.dumps(result.to_dict(), allow_nan=False))
    assert d['runs'][0]['offset']['anchor'] == 'power'
    assert d['runs'][0]['offset']['motion_s'] is None


def test_analyze_starts_at_the_motion_and_one_common_lag(heavy):
    manifest, truth = heavy
    campaign = load_campaign(manifest)
    machine = load_machine(campaign.machine)
    runs = compare_campaign(campaign, machine=machine).runs
    # the power's own lags are pulled by the missing mass, all of them the same way
    lags = [r.offset.offset_s - r.offset.motion_s for r in runs]
    assert motion_lag_s(runs) == pytest.approx(float(np.median(lags)))
    assert motion_lag_s(runs) < -TOL_S
    # analyze's start: every run at its motion offset (lag 0), within 1 ms of the truth
    start = at_common_lag(campaign, machine, runs, lag_s=0.0)
    for before, after in zip(runs, start):
        assert after.name == before.name
        assert after.offset_used_s == pytest.approx(after.offset.motion_s, abs=1e-9)
        assert abs(after.offset_used_s - truth[after.name]) < 1e-3
        assert 'common meter lag' in after.offset.message
    # a given lag moves them all by it
    moved = at_common_lag(campaign, machine, runs[:2], lag_s=0.004)
    for after in moved:
        assert after.offset_used_s == pytest.approx(after.offset.motion_s + 0.004, abs=1e-9)


def test_motion_anchor_on_arrays():
    t_sim = np.arange(0.0, 12.0, 0.001)
    back = np.where((t_sim > 7) & (t_sim < 10), -0.2, 0.0)
    v_sim = np.where((t_sim > 2) & (t_sim < 5), 0.2, back)[:, None]
    t_meas = np.arange(0.0, 15.0, 0.01)
    v_meas = np.interp(t_meas - 1.234, t_sim, v_sim[:, 0])[:, None]
    found = motion_anchor(t_meas, v_meas, t_sim, v_sim, max_lag_s=5.0)
    assert found is not None and found.status == 'ok'
    assert found.offset_s == pytest.approx(1.234, abs=2e-3)
    # the signs tell the strokes apart: the down stroke 5 s later is no alternative
    assert not (abs(found.runner_up_s - 1.234 - 5.0) < 0.05 and
                found.runner_up_correlation > 0.9 * found.peak_correlation)
    # nothing moves: nothing to align on
    assert motion_anchor(t_meas, 0.0 * v_meas, t_sim, v_sim, max_lag_s=5.0) is None


def test_measured_velocity_falls_back_to_positions():
    t = np.arange(0.0, 1.0, 0.01)
    pos = np.column_stack([0.3 * t, -0.1 * t])
    run = MeasuredRun(name='r', file='f.csv', t=t, axes=('X', 'Y'), power_axes=('X',),
                      power_w=np.zeros((t.size, 1)), load_kg=0.0, position_m=pos)
    v = measured_velocity(run, ['Y'])
    assert v is not None and v.shape == (t.size, 1)
    np.testing.assert_allclose(v[:, 0], -0.1, atol=1e-12)
    assert measured_velocity(run, ['Z']) is None
    bare = MeasuredRun(name='r', file='f.csv', t=t, axes=('X',), power_axes=('X',),
                       power_w=np.zeros((t.size, 1)), load_kg=0.0)
    assert measured_velocity(bare, ['X']) is None


def test_the_motion_times_the_clock_and_compare_corrects_it(matrix, tmp_path, monkeypatch):
    # clocks up to 400 ppm off on the smooth class's 10 ms meter: the velocities of each
    # record's halves time its clock; a rate that moves the stamps at the record's ends by
    # more than a quarter period is corrected (the stamps put on the simulation's clock,
    # the offset the one at the record's middle), a smaller one reported only
    tm, tt = matrix.tm, matrix.tt
    monkeypatch.setattr(tt, 'DRIFT_PPM', 400.0)
    rates = []
    record = tm.record

    def spy(state, power, *, meter, **kw):
        rates.append(meter.drift_ppm)
        return record(state, power, meter=meter, **kw)
    monkeypatch.setattr(tm, 'record', spy)
    axis = tm.read_axis(tt.MACHINE)
    runs = tt.make_runs(axis)
    truth = matrix.write_campaign(tmp_path, case='clean', amp=1.0, runs=runs, axis=axis,
                                  seed=5, cls='smooth')
    manifest = tmp_path / 'manifest.yaml'
    result = compare_campaign(load_campaign(manifest))
    corrected = 0
    for run, rate in zip(result.runs, rates):
        assert run.offset.drift_ppm == pytest.approx(rate, rel=0.02, abs=2.0), \
            run.offset.drift_message
        raw = load_run(load_campaign(manifest).run(run.name)).t
        moved = 0.5e-6 * abs(rate) * (raw[-1] - raw[0])
        if moved > 1e-3 * 0.01 + 1e-6:
            corrected += 1
            assert run.clock_ppm == run.offset.drift_ppm, run.name
            assert 'corrected: the stamps' in run.offset.drift_message
            # the stamps are the file's, moved by the rate times their distance from the
            # middle, and the motion's offset is the truth's at the record's middle (the
            # truth's offset includes the meter's 5 ms lag, which the motion does not see)
            mid = 0.5 * (raw[0] + raw[-1])
            np.testing.assert_allclose(run.t, raw - 1e-6 * run.clock_ppm * (raw - mid),
                                       rtol=0.0, atol=1e-12)
            lag = matrix.SMOOTH.lag_s
            assert abs(run.offset.motion_s - (truth[run.name] - lag)) < 1e-5, run.name
        elif moved < 1e-3 * 0.01 - 1e-6:
            assert run.clock_ppm == 0.0 and 'not corrected' in run.offset.drift_message
            assert np.array_equal(run.t, raw)
    assert corrected >= 2, rates
    d = json.loads(json.dumps(result.to_dict(), allow_nan=False))
    assert [r['clock_ppm'] for r in d['runs']] == [r.clock_ppm for r in result.runs]
