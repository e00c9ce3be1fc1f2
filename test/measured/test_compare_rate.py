"""What makes ``compare`` linear in the data (issue 24, section 7) keeps its results.

The streamed simulation a comparison keeps equals the whole-record one; CSV runs read in
blocks equal the whole-file read, errors included; the lag grid computed with FFT blocks and
around a centre equals the direct correlation; records with irregular stamps coarsen their
grid and still align; state labels computed in chunks equal those of one pass. Speed and
memory are measured by bench/bench_compare_rate.py, not here.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy import csvtable
from feed_axis_energy.errors import DataError
from feed_axis_energy.machine import DeclaredEffect
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured import align
from feed_axis_energy.measured import compare as cmp
from feed_axis_energy.measured import states
from feed_axis_energy.physics import state_from_simulation
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.manifest import load_campaign

from test_compare import MACHINE_YAML, write_campaign

COVARIANCE = """\
    loss_covariance:
      params: [a, b]
      units: ['W/(mm/s)/(mm/s)^b', '1']
      matrix: [[4.0e-4, -1.0e-4], [-1.0e-4, 2.0e-4]]
"""


@pytest.fixture(scope='module')
def small(tmp_path_factory):
    root = tmp_path_factory.mktemp('rate')
    manifest = write_campaign(root, [{'name': 'a', 'load_kg': 5.0, 'offset_ms': 250,
                                      'noise_w': 0.3}])
    # both axes with a loss covariance, so the energy uncertainty is a number on both paths
    text = MACHINE_YAML.replace('y_unit: W/(mm/s)}\n', 'y_unit: W/(mm/s)}\n' + COVARIANCE)
    assert text.count('loss_covariance') == 2
    (root / 'machine.yaml').write_text(text)
    return load_campaign(manifest)


def test_streamed_simulation_equals_the_whole_record(small):
    spec = small.run('a')
    machine = load_machine(small.machine)
    run = load_run(spec)
    whole = cmp._whole_trace(spec, run, machine, cmp.MotionCache(machine))
    streamed = cmp.simulate_trace(spec, run, machine, cmp.MotionCache(machine))
    assert streamed.t.shape == whole.t.shape and streamed.t.size > 1000
    assert_allclose(streamed.t, whole.t, rtol=0.0, atol=1e-12)
    assert_allclose(streamed.signal, whole.signal, rtol=1e-12, atol=1e-9)
    assert_allclose(streamed.vel, whole.vel, rtol=1e-12, atol=1e-12)
    assert np.isfinite(whole.energy_sd_pct) and whole.energy_sd_pct > 0.0
    assert streamed.energy_sd_pct == pytest.approx(whole.energy_sd_pct, rel=1e-9)


def _joined(states):
    return {name: np.concatenate([getattr(s, name) for s in states])
            for name in ('t', 'position_m', 'velocity_m_s', 'acceleration_m_s2', 'angle_rad',
                         'omega_rad_s', 'force_n', 'torque_nm', 'mechanical_w', 'power_w')}


def test_the_declared_simulation_in_chunks_equals_the_whole_run(small):
    # what analyze keeps of each run (its EffectState) from chunks of 1000 samples
    spec = small.run('a')
    machine = load_machine(small.machine)
    run = load_run(spec)
    sim, source = cmp.simulate_declared(spec, run, machine, cmp.MotionCache(machine))
    whole = state_from_simulation(sim)
    pieces = []
    got = cmp.simulate_declared_chunks(spec, run, machine, cmp.MotionCache(machine),
                                       lambda c: pieces.append(state_from_simulation(c)),
                                       chunk_samples=1000)
    assert got == source and len(pieces) > 3
    for name, value in _joined(pieces).items():
        assert_allclose(value, getattr(whole, name), rtol=1e-12, atol=1e-12, err_msg=name)
    assert all(np.array_equal(p.mass_kg, whole.mass_kg) for p in pieces)
    # a record no longer than one chunk: the whole run, in one piece
    pieces.clear()
    cmp.simulate_declared_chunks(spec, run, machine, cmp.MotionCache(machine),
                                 lambda c: pieces.append(c), chunk_samples=10 ** 7)
    assert len(pieces) == 1 and pieces[0].power.t.shape == whole.t.shape
    # a declared effect that needs neighbouring samples: the whole run, in one piece
    drift = replace(machine, effects=(DeclaredEffect('time_offset', 'X',
                                                     (('delta_s', 0.002),)),))
    pieces.clear()
    cmp.simulate_declared_chunks(spec, run, drift, cmp.MotionCache(drift),
                                 lambda c: pieces.append(c), chunk_samples=1000)
    assert len(pieces) == 1 and pieces[0].power.t.shape == whole.t.shape


def test_trace_buffers_grow_beyond_the_expected_length(small):
    # sized for a record far shorter than the program: the buffers double, the values stay
    spec = small.run('a')
    machine = load_machine(small.machine)
    run = load_run(spec)
    whole = cmp._whole_trace(spec, run, machine, cmp.MotionCache(machine))
    grown = cmp._streamed_trace(spec, spec.motion_program, machine, expected_s=-59.99)
    assert_allclose(grown.t, whole.t, rtol=0.0, atol=1e-12)
    assert_allclose(grown.signal, whole.signal, rtol=1e-12, atol=1e-9)
    assert_allclose(grown.vel, whole.vel, rtol=1e-12, atol=1e-12)


def test_runs_read_in_blocks_equal_the_whole_file(small, monkeypatch):
    spec = small.run('a')
    whole = load_run(spec)
    monkeypatch.setattr(csvtable, 'BLOCK_ROWS', 7)
    blocks = list(csvtable.iter_csv_blocks(spec.data))
    assert len(blocks) > 10 and all(len(b[1]) <= 7 for b in blocks)
    parts = load_run(spec)
    assert_allclose(parts.t, whole.t, rtol=0.0, atol=0.0)
    assert_allclose(parts.power_w, whole.power_w, rtol=0.0, atol=0.0)
    assert_allclose(parts.position_m, whole.position_m, rtol=0.0, atol=0.0)
    assert np.array_equal(parts.extra['rows'], whole.extra['rows'])


def test_errors_of_a_run_read_in_blocks_keep_the_whole_file_order(small, monkeypatch, tmp_path):
    # a bad power cell early and a time going back later: the time is checked first, as on
    # a file read whole, although its block comes after the power cell's
    lines = small.run('a').data.read_text().splitlines()
    row = lines[3].split(',')
    row[1] = 'oops'
    lines[3] = ','.join(row)
    late = lines[40].split(',')
    late[0] = '1'
    lines[40] = ','.join(late)
    bad = tmp_path / 'bad.csv'
    bad.write_text('\n'.join(lines) + '\n')
    from dataclasses import replace
    spec = replace(small.run('a'), data=bad)
    with pytest.raises(DataError) as whole:
        load_run(spec)
    monkeypatch.setattr(csvtable, 'BLOCK_ROWS', 5)
    with pytest.raises(DataError) as parts:
        load_run(spec)
    assert str(parts.value) == str(whole.value)
    assert parts.value.column == 'Time_ms' and parts.value.row == 40


def _profile(t):
    return (np.sin(2.3 * t) ** 2 * 40.0 + 15.0 * np.exp(-0.5 * ((t % 7.0 - 3.0) / 0.2) ** 2)
            + 5.0 * (t % 3.1 > 2.0))


@pytest.mark.parametrize('q, centre, window', [(1, 0.0, 0.01), (4, 0.0, 0.0), (3, 0.37, 0.01)])
def test_lag_grid_by_fft_blocks_equals_the_direct_correlation(q, centre, window):
    rng = np.random.default_rng(2)
    # an irregular simulated time base (as at the planner's phase ends)
    t_sim = np.cumsum(rng.choice([0.001, 0.00099], p=[0.95, 0.05], size=40_000))
    y_sim = _profile(t_sim) + rng.normal(scale=0.2, size=t_sim.size)
    period = 0.01
    t = 0.5 + np.arange(3000) * period
    y = np.interp(t - 0.123, t_sim, y_sim) + rng.normal(size=t.size)
    sig = align._Signals(t, y, t_sim, y_sim, window, align.stamp_shift(window, 'end'))
    steps = 700                      # > _DIRECT_SHIFTS lags per residue: the FFT path
    lags = centre + np.arange(-steps, steps + 1) * period / q
    fast = sig.uniform_correlation(period / q, steps, centre=centre)
    assert fast is not None
    assert_allclose(fast, sig.correlation(lags), atol=1e-10)


def test_irregular_stamps_coarsen_the_grid_and_still_align(monkeypatch):
    # a cost cap as on a long irregular record: the grid is coarsened, the refinement finds
    # the offset within a fraction of the period all the same
    monkeypatch.setattr(align, '_DIRECT_PRODUCTS_MAX', 200_000)
    rng = np.random.default_rng(4)
    t_sim = np.arange(0.0, 60.0, 0.001)
    y_sim = _profile(t_sim)
    t = np.sort(rng.uniform(0.0, 60.0, size=1200))
    y = align.align_simulated(t_sim, y_sim, t, offset_s=0.8137, window_s=0.0)
    y = y + rng.normal(scale=0.5, size=t.size)
    assert align._grid_step(t.size, 0.01, 6.0, False) > 0.01
    res = align.estimate_offset(t, y, t_sim, y_sim, max_lag_s=3.0, window_s=0.0)
    assert res.status in ('ok', 'ambiguous'), res.message
    assert abs(res.offset_s - 0.8137) < 0.005, res.message


def test_range_maxima_equal_a_direct_pass():
    rng = np.random.default_rng(0)
    for _ in range(200):
        m = int(rng.integers(2, 300))
        v = rng.normal(size=m)
        lo = np.sort(rng.integers(0, m - 1, size=int(rng.integers(1, 100))))
        hi = np.maximum.accumulate(np.minimum(lo + rng.integers(1, 20, size=lo.size), m))
        direct = np.array([v[a:b].max() for a, b in zip(lo, hi)])
        assert np.array_equal(states._range_max(v, lo, hi), direct)


def test_state_labels_in_chunks_equal_one_pass(monkeypatch):
    t_sim = np.arange(0.0, 20.0, 0.001)
    vel = np.column_stack([np.clip(np.sin(t_sim), 0.0, None) * 0.2,
                           np.where(t_sim % 5.0 < 2.0, 0.1, 0.0)])
    tau = np.arange(-0.5, 20.5, 0.01)
    one = states.state_labels(t_sim, vel, tau, period_s=0.01)
    monkeypatch.setattr(states, '_CHUNK', 37)
    assert np.array_equal(states.state_labels(t_sim, vel, tau, period_s=0.01), one)
    assert set(np.unique(one)) == {0, 1, 2}
    # an offset applied a chunk at a time equals the shifted stamps
    assert np.array_equal(states.state_labels(t_sim, vel, tau + 0.3, period_s=0.01,
                                              offset_s=0.3),
                          states.state_labels(t_sim, vel, (tau + 0.3) - 0.3, period_s=0.01))
