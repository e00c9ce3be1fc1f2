"""fit-loss uncertainties and calibrated range; warnings when a loss is extrapolated."""
import math

import numpy as np
import pytest
import yaml

from feed_axis_energy.machine.calibrated import (calibrated_from_value, CalibratedRange,
                                                 range_warnings, RangeUse)
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.identify.fit.lossfit import (fit_loss, fit_power_regression,
                                                   machine_with_losses)
from feed_axis_energy.identify.fit.steady import range_uses, SteadySegment
from feed_axis_energy.machine.file import load_machine, machine_to_dict

from test_lossfit import _synthetic, ROOT  # noqa: I100  (sibling test module)


def _segments(a, b, feeds, noise_rel, rng):
    out = []
    for f in feeds:
        y = a * f ** b * math.exp(rng.normal(0.0, noise_rel))
        out.append(SteadySegment(run='r', axis='X', t_start_s=0.0, t_end_s=1.0, samples=10,
                                 velocity_m_s=f / 1000.0, power_w=y * f, loss_power_w=y * f))
    return out


def test_standard_errors_match_the_scatter_of_repeated_fits():
    # 12 segments at 4 feeds, 5 % log-normal noise: the covariance-based standard error of b
    # must describe how much b scatters between independent data sets
    rng = np.random.default_rng(3)
    feeds = [6.0, 6.0, 6.0, 10.0, 10.0, 10.0, 15.0, 15.0, 15.0, 20.0, 20.0, 20.0]
    fits = [fit_power_regression(_segments(0.3, 0.35, feeds, 0.05, rng), axis='X')
            for _ in range(400)]
    b = np.array([f.b for f in fits])
    ln_a = np.log([f.a for f in fits])
    assert np.median([f.b_se for f in fits]) == pytest.approx(np.std(b), rel=0.15)
    assert np.median([f.a_se / f.a for f in fits]) == pytest.approx(np.std(ln_a), rel=0.15)
    # and the standard error by hand: sigma / sqrt(sum (lx - mean)^2)
    lx = np.log(feeds)
    assert np.median([f.b_se for f in fits]) == pytest.approx(
        0.05 / math.sqrt(np.sum((lx - lx.mean()) ** 2)), rel=0.15)


def test_exact_data_have_zero_uncertainty_and_the_range_of_the_feeds():
    fit = fit_power_regression(_segments(0.3, 0.35, [6.0, 10.0, 20.0], 0.0,
                                         np.random.default_rng(0)), axis='X', loads_kg=[0, 5])
    assert fit.ok
    assert fit.b_se == pytest.approx(0.0, abs=1e-9)
    assert fit.calibrated == CalibratedRange(feed_mm_s=(6.0, 20.0), load_kg=(0.0, 5.0))


def test_fitted_machine_carries_the_calibrated_range(tmp_path):
    run = _synthetic(0.25, 0.35, [10.0, 20.0, 40.0])
    machine = load_machine(ROOT / 'config' / 'demonstrator.yaml')
    fits = fit_loss([run], machine=machine)
    lo, hi = fits['X'].calibrated.feed_mm_s
    assert lo == pytest.approx(10.0, rel=0.02) and hi == pytest.approx(40.0, rel=0.02)
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(machine_to_dict(machine_with_losses(machine, fits))))
    loaded = load_machine(path)
    assert loaded.axis('X').loss_calibrated == fits['X'].calibrated
    # the same fit applied to a run with a 60 mm/s move: extrapolated, and said so
    fast = _synthetic(0.25, 0.35, [10.0, 60.0])
    text = range_warnings({'X': loaded.axis('X').loss_calibrated}, range_uses([fast]))
    assert len(text) == 1
    assert 'calibrated at 10-40 mm/s is used at 10-60 mm/s' in text[0]
    # inside the range: nothing
    assert range_warnings({'X': loaded.axis('X').loss_calibrated}, range_uses([run])) == []


def test_only_steady_samples_count_and_loads_are_checked():
    rng = CalibratedRange(feed_mm_s=(6.0, 20.0), load_kg=(0.0, 0.0))
    speed = np.array([0.001, 0.010, 0.045, 0.015])
    accel = np.array([2.0, 0.0, 3.0, 0.0])       # 1 and 45 mm/s only while accelerating
    quiet = RangeUse(run='a', load_kg=0.0, speed_m_s=speed, accel_m_s2=accel)
    assert range_warnings({'X': rng}, {'X': [quiet]}) == []
    loaded = RangeUse(run='b', load_kg=22.7, speed_m_s=speed, accel_m_s2=accel)
    text = range_warnings({'X': rng}, {'X': [quiet, loaded]})
    assert text == ['axis X: loss function calibrated at loads 0-0 kg is used at 22.7 kg: '
                    'extrapolated']


@pytest.mark.parametrize('value, key', [
    ([6, 20], 'loss_calibrated'), ({'load_kg': [0, 1]}, 'feed_mm_s'),
    ({'feed_mm_s': [20, 6]}, 'feed_mm_s'), ({'feed_mm_s': [6, 'x']}, 'feed_mm_s'),
    ({'feed_mm_s': [6, 20], 'speed': 1}, 'speed')])
def test_bad_calibrated_ranges_are_refused_naming_the_key(value, key):
    with pytest.raises(ConfigError, match=key):
        calibrated_from_value(value, file='m.yaml', key='axes.X.loss_calibrated')


def test_effect_used_beyond_the_positions_it_was_identified_on():
    rng = CalibratedRange(feed_mm_s=(100.0, 300.0), position_m=(0.0, 0.2))
    x = np.linspace(0.0, 0.4, 401)           # a quarter of the moving samples beyond 0.3 m
    use = RangeUse(run='a', load_kg=0.0, speed_m_s=np.full(401, 0.2), position_m=x)
    text = range_warnings({'X': rng}, {'X': [use]}, what='effect position_friction')
    assert text == ['axis X: effect position_friction calibrated at positions 0.0-200.0 mm '
                    'is used at 0.0-400.0 mm (49.9 % of the moving samples outside): '
                    'extrapolated']


def test_machine_effects_outside_their_physical_bounds_or_with_bad_ranges_are_refused(tmp_path):
    machine = load_machine(ROOT / 'config' / 'demonstrator.yaml')
    d = machine_to_dict(machine)
    d['effects'] = [{'id': 'copper', 'axis': 'X', 'params': {'k_w_nm2': -3.1}}]
    path = tmp_path / 'm.yaml'
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(ConfigError, match=r'effects\[0\]\.params.*must lie in \[0, inf\]'):
        load_machine(path)
    d['effects'] = [{'id': 'copper', 'axis': 'X', 'params': {'k_w_nm2': 3.1},
                     'calibrated': {'feed_mm_s': [100, 500], 'position_m': [0.3, 0.1]}}]
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(ConfigError, match=r'effects\[0\]\.calibrated\.position_m'):
        load_machine(path)
    d['effects'][0]['calibrated']['position_m'] = [-0.1, 0.3]
    path.write_text(yaml.safe_dump(d))
    loaded = load_machine(path)
    assert loaded.effects[0].calibrated.position_m == (-0.1, 0.3)
    assert machine_to_dict(loaded)['effects'][0]['calibrated'] == {
        'feed_mm_s': [100.0, 500.0], 'position_m': [-0.1, 0.3]}
