"""The analysis grid (identify/design/grid.py): fast data are analysed on exact bin means."""
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose, assert_array_equal
import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify.analyze import analyze_campaign
from feed_axis_energy.identify.design import bin_windows, bins_for
from feed_axis_energy.identify.results import AnalyzeOptions
from feed_axis_energy.identify.rig import Instrument, make_campaign, parse_effects, RigConfig
from feed_axis_energy.measured import (align_simulated, compare_one_run, load_run, MotionCache,
                                       stamp_shift)
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.machine import load_machine

ROOT = Path(__file__).resolve().parents[2]
MACHINE = ROOT / 'config' / 'demonstrator.yaml'


@pytest.mark.parametrize('step, period, size', [
    (0.001, 0.05, 50), (0.002, 0.05, 25), (0.01, 0.05, 5), (0.05, 0.05, 1), (0.04, 0.05, 1),
    (0.1, 0.05, 1), (0.001, 0.0105, 10), (0.003, 0.05, 16)])
def test_bin_size_is_the_whole_number_of_sample_periods_in_the_analysis_period(
        step, period, size) -> None:
    t = 7.0 + step * np.arange(1000)
    bins = bins_for(t, period)
    assert bins.size == size
    assert bins.count == 1000 // size
    assert bins.samples == 1000


def test_bin_means_are_exact_and_drop_only_the_trailing_partial_bin() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=(103, 2))
    bins = bins_for(np.arange(103) * 0.01, 0.05)
    means = bins.mean(x)
    assert means.shape == (20, 2)
    for b in range(20):
        assert_allclose(means[b], x[5 * b:5 * b + 5].mean(axis=0), rtol=1e-14)
    # the sums over whole bins are kept exactly: what a fit on the bins weighs
    assert_allclose(means.sum(axis=0) * 5, x[:100].sum(axis=0), rtol=1e-12)


def test_slow_data_are_used_as_they_are() -> None:
    x = np.arange(10.0)
    bins = bins_for(np.arange(10) * 0.05, 0.05)
    assert bins.mean(x) is x


def test_too_short_a_record_for_two_bins_is_not_binned() -> None:
    assert bins_for(np.arange(60) * 0.001, 0.05).size == 1


@pytest.mark.parametrize('bad', [0.0, -0.05, float('nan'), float('inf')])
def test_analysis_period_must_be_positive_and_finite(bad) -> None:
    with pytest.raises(ConfigError, match='analysis_period_s'):
        AnalyzeOptions(analysis_period_s=bad)


def _rig(tmp_path: Path, effects: str, *, period_s: float):
    inst = Instrument(window_s=period_s, period_s=period_s, noise_w=1.0, quantum_w=0.0)
    cfg = RigConfig(machine=MACHINE, loads_kg=(0.0, 22.711), feeds_mm_s=(150.0, 300.0, 450.0),
                    cycles=1, effects=parse_effects(effects), instrument=inst, seed=2)
    return load_campaign(make_campaign(tmp_path / 'rig', cfg))


def test_a_loaded_run_gives_the_comparison_of_the_file(tmp_path) -> None:
    campaign = _rig(tmp_path, 'none', period_s=0.01)
    spec = campaign.runs[0]
    machine = load_machine(MACHINE)
    kw = dict(max_lag_s=5.0, window_s=None, offset_s=None, min_correlation=0.5,
              floor_fraction=0.05)
    own = compare_one_run(spec, machine, MotionCache(machine), **kw)
    given = compare_one_run(spec, machine, MotionCache(machine), measured=load_run(spec), **kw)
    assert given.offset_used_s == own.offset_used_s
    assert_array_equal(given.power_sim_w, own.power_sim_w)
    assert given.metrics == own.metrics


def test_fast_data_are_analysed_on_bins_and_find_the_same_effect(tmp_path) -> None:
    """10 ms samples, analysed on 50 ms bins (5 samples) and sample by sample: the same
    effects, the same coefficient within 1 %, the series and noise on the bins."""
    campaign = _rig(tmp_path, 'viscous=c_n_s_m:150', period_s=0.01)
    binned = analyze_campaign(campaign)
    fine = analyze_campaign(campaign, options=AnalyzeOptions(analysis_period_s=0.01))
    assert set(binned.samples_per_bin.values()) == {5}
    assert set(fine.samples_per_bin.values()) == {1}
    # (at 10 ms the rig's strokes also show a small mass error, sample by sample as well)
    assert [e.id for e in binned.effects] == [e.id for e in fine.effects]
    assert binned.effects[0].id == 'viscous'
    c_bin = binned.effects[0].values()['c_n_s_m']
    c_fine = fine.effects[0].values()['c_n_s_m']
    assert c_bin == pytest.approx(150.0, rel=0.05)
    assert c_bin == pytest.approx(c_fine, rel=0.01)
    for run_b, run_f in zip(binned.runs, fine.runs):
        assert run_b.residual_before_w.shape[0] == run_f.residual_before_w.shape[0] // 5
        assert run_b.t.shape == run_b.meas_w.shape == run_b.after_w.shape
        # the Table-1 figures are the comparisons' own: not binned (the two analyses may
        # pin a run at common meter lags a few microseconds apart: pinning.repin)
        for name in ('avg_diff_error_w', 'max_diff_error_w', 'rmse_w', 'energy_error_j'):
            assert getattr(run_b.before, name) == pytest.approx(
                getattr(run_f.before, name), rel=1e-3, abs=1e-6), name
        assert run_b.before.n_samples == run_f.before.n_samples
    # white noise of 1 W per sample is 1/sqrt(5) W per bin of 5
    assert binned.noise['X'].white_w == pytest.approx(1.0 / np.sqrt(5.0), rel=0.15)
    assert fine.noise['X'].white_w == pytest.approx(1.0, rel=0.1)
    doc = binned.to_dict()
    assert doc['analysis_grid']['period_s'] == 0.05
    assert set(doc['analysis_grid']['samples_per_bin'].values()) == {5}


@pytest.mark.parametrize('stamp', ['end', 'centre', 'start'])
def test_abutting_windows_average_per_bin_as_the_mean_of_the_samples(stamp) -> None:
    """A 1 ms meter on 1 ms stamps: one 50 ms window per bin equals the mean of the 50
    window averages (to rounding); other meters are averaged sample by sample."""
    t_sim = np.arange(0.0, 12.0, 0.001)
    y_sim = np.column_stack([np.sin(3.0 * t_sim) + 0.3 * np.sign(np.sin(7.0 * t_sim)),
                             t_sim ** 2])
    t = 0.5 + 0.001 * np.arange(9000)
    bins = bins_for(t, 0.05)
    wide = bin_windows(t, bins, window_s=0.001, shift_s=stamp_shift(0.001, stamp))
    assert wide is not None
    ends, span = wide
    assert span == pytest.approx(0.05, rel=1e-9)
    fast = align_simulated(t_sim, y_sim, ends, offset_s=0.37, window_s=span)
    slow = bins.mean(align_simulated(t_sim, y_sim, t, offset_s=0.37, window_s=0.001,
                                     stamp=stamp))
    assert_allclose(fast, slow, rtol=1e-9, atol=1e-12)
    # point samples, a window longer than the period, irregular stamps: no wide window
    assert bin_windows(t, bins, window_s=0.0, shift_s=0.0) is None
    assert bin_windows(t, bins, window_s=0.002, shift_s=0.0) is None
    jitter = t + np.random.default_rng(1).uniform(0, 2e-5, t.size)
    assert bin_windows(jitter, bins_for(jitter, 0.05), window_s=0.001, shift_s=0.0) is None
    assert bin_windows(t, bins_for(t, 0.001), window_s=0.001, shift_s=0.0) is None
