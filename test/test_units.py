"""Unit conversion: factors checked against definitions, spellings, and errors."""
import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.units import (axis_units, known_units, quantity_of, rate_from_interval,
                                    si_unit_of, to_si)


@pytest.mark.parametrize('value, unit, expected, si', [
    (1500.0, 'mm', 1.5, 'm'),
    (2.0, 'cm', 0.02, 'm'),
    (10.0, 'in', 0.254, 'm'),
    (250.0, 'um', 250e-6, 'm'),
    (6000.0, 'mm/min', 0.1, 'm/s'),      # 6 m per minute = 0.1 m/s
    (3.0, 'm/min', 0.05, 'm/s'),
    (60.0, 'in/min', 0.0254, 'm/s'),     # one inch per second
    (20.0, 'mm/s', 0.02, 'm/s'),
    (500.0, 'mm/s^2', 0.5, 'm/s^2'),
    (500.0, 'mm/s/s', 0.5, 'm/s^2'),
    (500.0, 'mm/s2', 0.5, 'm/s^2'),
    (500.0, 'mm/s\u00b2', 0.5, 'm/s^2'),
    (0.0175, 'kW', 17.5, 'W'),
    (250.0, 'mW', 0.25, 'W'),
    (1.0, 'Wh', 3600.0, 'J'),
    (0.5, 'kWh', 1.8e6, 'J'),
    (2.0, 'kJ', 2000.0, 'J'),
    (300.0, 'mA', 0.3, 'A'),
    (0.4, 'kV', 400.0, 'V'),
    (100.0, 'ms', 0.1, 's'),
    (5e8, 'ns', 0.5, 's'),
    (2.0, 'min', 120.0, 's'),
    (1500.0, 'g', 1.5, 'kg'),
    (1.2, 'kN', 1200.0, 'N'),
    (3.0, 'Nm', 3.0, 'N*m'),
    (3.0, 'N*m', 3.0, 'N*m'),
    (3.0, 'N\u00b7m', 3.0, 'N*m'),
])
def test_to_si_factors(value, unit, expected, si):
    assert_allclose(to_si(value, unit), expected, rtol=1e-12)
    assert si_unit_of(unit) == si


def test_to_si_keeps_shape_and_does_not_alias():
    raw = np.array([[1.0, 2.0], [3.0, 4.0]])
    out = to_si(raw, 'm')
    assert out.shape == (2, 2) and out.dtype == np.float64
    out[0, 0] = 99.0
    assert raw[0, 0] == 1.0


def test_quantity_of_and_known_units():
    assert quantity_of('mm/min') == 'velocity'
    assert 'kW' in known_units('power')
    assert set(known_units('power')) <= set(known_units())


def test_unknown_unit_lists_the_quantitys_units():
    with pytest.raises(ConfigError, match=r"unknown power unit 'hp'.*W, kW, mW"):
        to_si(1.0, 'hp', quantity='power')


def test_unit_of_wrong_quantity_is_rejected():
    with pytest.raises(ConfigError, match='unknown power unit'):
        si_unit_of('mm', quantity='power')


def test_unknown_unit_without_quantity_lists_all():
    with pytest.raises(ConfigError, match='length: m, cm'):
        to_si(1.0, 'furlong')
    with pytest.raises(ConfigError, match='unknown quantity'):
        to_si(1.0, 'm', quantity='colour')


@pytest.mark.parametrize('interval, rate', [
    (0.001, 1000.0), (1.0 / 3.0, 3.0), (0.1, 10.0), (0.05, 20.0), (2.5e-4, 4000.0),
    (0.0, 0.0), (-0.001, 0.0), (float('nan'), 0.0), (float('inf'), 0.0)])
def test_rate_from_interval_is_exact_for_float_noise_and_zero_without_a_rate(interval, rate):
    assert rate_from_interval(interval) == rate


def test_rate_from_interval_keeps_a_rate_that_is_not_round():
    # a measured 99.99 Hz meter must not be rounded to 100 Hz
    assert rate_from_interval(1.0 / 99.99) == 99.99
    # float noise of a difference of stamps near 8 h (about 1e-12 s) is removed
    t1, t0 = 28800.001, 28800.0
    assert rate_from_interval(t1 - t0) == pytest.approx(1000.0, rel=1e-8)
    assert rate_from_interval(0.001 + 1e-16) == 1000.0


def test_axis_units_rotary_axes_in_rad():
    assert axis_units('X') == ('m', 'm/s', 'm/s^2')
    assert axis_units('C') == ('rad', 'rad/s', 'rad/s^2')
