"""Tests of the loss models: the paper's eq. (3) by hand, signs, units, registry, errors."""
import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.machine.losses import (CoulombViscousLoss, LOSS_MODELS, loss_from_dict,
                                             PowerRegressionLoss)


def test_paper_coefficients_by_hand():
    loss = PowerRegressionLoss()
    # x = 100 mm/s: y = 0.2505 * 100**0.3471 W/(mm/s); P = y * 100 W; F = P / 0.1 m/s
    y = 0.2505 * 100.0 ** 0.3471
    assert_allclose(loss.power_w(np.array([0.1])), [0.2505 * 100.0 ** 1.3471], rtol=1e-12)
    assert_allclose(loss.force_n(np.array([0.1])), [-y * 100.0 / 0.1], rtol=1e-12)
    # the range quoted for our unit reading: about 124 W at 100 mm/s, 1085 W at 500 mm/s
    p = loss.power_w(np.array([0.1, 0.5]))
    assert 120.0 < p[0] < 128.0
    assert 1070.0 < p[1] < 1100.0


def test_force_opposes_motion_and_vanishes_at_rest():
    loss = PowerRegressionLoss()
    v = np.array([-0.3, -1e-6, 0.0, 1e-6, 0.3])
    f = loss.force_n(v)
    assert f[2] == 0.0
    assert np.all(f[v > 0] < 0.0) and np.all(f[v < 0] > 0.0)
    assert_allclose(f[:2], -f[[4, 3]], rtol=1e-15)  # odd in v
    assert np.all(loss.power_w(v) >= 0.0)


@pytest.mark.parametrize('x_unit, scale', [('mm/s', 1000.0), ('m/s', 1.0),
                                           ('mm/min', 60000.0), ('m/min', 60.0)])
@pytest.mark.parametrize('y_unit', ['W/(mm/s)', 'W', 'N'])
def test_unit_readings(x_unit, scale, y_unit):
    a, b, v = 0.7, 0.5, 0.25
    loss = PowerRegressionLoss(a=a, b=b, x_unit=x_unit, y_unit=y_unit)
    y = a * (v * scale) ** b
    expected = {'W/(mm/s)': y * 1000.0 * v, 'W': y, 'N': y * v}[y_unit]
    assert_allclose(loss.power_w(np.array([v])), [expected], rtol=1e-12)


def test_power_reading_is_zero_at_rest_without_warnings():
    loss = PowerRegressionLoss(y_unit='W')
    with np.errstate(all='raise'):
        assert loss.force_n(np.zeros(3)).tolist() == [0.0, 0.0, 0.0]


def test_coulomb_viscous_by_hand():
    loss = CoulombViscousLoss(coulomb_n=20.0, viscous_n_s_m=100.0, mu=0.01)
    f = loss.force_n(np.array([0.2, -0.2, 0.0]), normal_force_n=500.0)
    assert_allclose(f, [-(20.0 + 5.0 + 20.0), 45.0, 0.0])


def test_registry_and_round_trip():
    assert LOSS_MODELS['power_regression'] is PowerRegressionLoss
    assert LOSS_MODELS['coulomb_viscous'] is CoulombViscousLoss
    for model in (PowerRegressionLoss(a=1.5, b=0.2, x_unit='m/min', y_unit='N'),
                  CoulombViscousLoss(coulomb_n=3.0, viscous_n_s_m=4.0, mu=0.1)):
        assert loss_from_dict(model.to_dict(), file='f', key='k') == model


@pytest.mark.parametrize('d, key', [
    ({'model': 'magic'}, 'axes.X.loss.model'),
    ({'a': 1.0, 'b': 0.3}, 'axes.X.loss.model'),
    ({'model': 'power_regression', 'b': 0.3}, 'axes.X.loss.a'),
    ({'model': 'power_regression', 'a': 1.0, 'b': -0.3}, 'axes.X.loss.b'),
    ({'model': 'power_regression', 'a': 'big', 'b': 0.3}, 'axes.X.loss.a'),
    ({'model': 'power_regression', 'a': 1.0, 'b': 0.3, 'x_unit': 'in/s'}, 'axes.X.loss.x_unit'),
    ({'model': 'power_regression', 'a': 1.0, 'b': 0.3, 'c': 2.0}, 'axes.X.loss.c'),
    ({'model': 'coulomb_viscous', 'coulomb': 2.0}, 'axes.X.loss.coulomb'),
    ([1, 2], 'axes.X.loss'),
])
def test_bad_loss_config_names_key(d, key):
    with pytest.raises(ConfigError) as info:
        loss_from_dict(d, file='m.yaml', key='axes.X.loss')
    assert info.value.key == key
    assert str(info.value).startswith(f'm.yaml: {key}: ')


@pytest.mark.parametrize('shape', [(0,), (3,), (40_000,), (5_000, 3)])
@pytest.mark.parametrize('pattern', ['cruise', 'random', 'zeros'])
def test_power_per_run_is_numpy_power_to_the_bit(shape, pattern) -> None:
    """The regression's power evaluated once per run of equal speeds (cruise phases) is
    np.power, bit for bit, whatever the runs (long, none, signed zeros) and the layout."""
    from feed_axis_energy.machine.losses import _power
    rng = np.random.default_rng(7)
    n = int(np.prod(shape))
    if pattern == 'cruise':
        x = np.repeat(rng.uniform(0.0, 500.0, max(n // 50, 1)), 50)[:n]
        x[:: 97] = rng.uniform(0.0, 500.0, x[:: 97].shape)     # ramps: single values
    elif pattern == 'random':
        x = rng.uniform(0.0, 500.0, n)
    else:
        x = np.zeros(n)
        x[1::2] = -0.0
    x = np.asfortranarray(x.reshape(shape))
    for b in (0.0, 0.3471, 1.0, 2.5):
        got = _power(x, b)
        assert got.shape == x.shape
        assert got.tobytes() == np.power(x, b).tobytes()
        if x.ndim == 2:
            col = x[:, 1]                                        # a strided view
            assert _power(col, b).tobytes() == np.power(col, b).tobytes()
