"""The energy's uncertainty from the loss parameters' covariance: config, gradient, propagation.

Checked by hand calculation (constant feed, ``P = a·x**(1+b)``), by finite differences of
the simulated energy, and by propagating a covariance through symmetric sigma points (for a
loss linear in its parameters the spread of the simulated energies is exactly ``g'Cg``).
"""
import copy
import math
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.gcode.load import load_gcode
from feed_axis_energy.machine.covariance import LossCovariance
from feed_axis_energy.machine.losses import CoulombViscousLoss, PowerRegressionLoss
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.plan.fromsamples import motion_from_samples
from feed_axis_energy.sim.stream import simulate_stream
from feed_axis_energy.sim.simulate import simulate_motion, simulate_program, summarize
from feed_axis_energy.physics.uncertainty import UNCERTAINTY_KEY

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / 'config'
PR_UNITS = ['W/(mm/s)/(mm/s)^b', '1']


def _demo(**axis_x) -> dict:
    data = machine_to_dict(load_machine(CONFIG / 'demonstrator.yaml'))
    data['axes']['X'].update(axis_x)
    return data


# ---- the loss models' parameter gradients ----------------------------------------------------

@pytest.mark.parametrize('y_unit', ['W/(mm/s)', 'W', 'N'])
@pytest.mark.parametrize('x_unit', ['mm/s', 'm/min'])
def test_power_regression_gradient_by_hand_and_by_difference(x_unit, y_unit):
    a, b = 0.2, 0.35
    loss = PowerRegressionLoss(a=a, b=b, x_unit=x_unit, y_unit=y_unit)
    v = np.array([-0.3, -0.01, 0.0, 0.002, 0.1, 0.5])
    g = loss.power_gradient_w(v)
    # by hand for x in mm/s and y in W/(mm/s): P = a·x**(1+b) with x = 1000·|v|
    if (x_unit, y_unit) == ('mm/s', 'W/(mm/s)'):
        x = 1000.0 * np.abs(v)
        assert_allclose(g['a'], x ** (1 + b), rtol=1e-12)
        with np.errstate(divide='ignore', invalid='ignore'):
            expect_b = np.where(x > 0, a * x ** (1 + b) * np.log(np.where(x > 0, x, 1)), 0.0)
        assert_allclose(g['b'], expect_b, rtol=1e-12)
    for name, h in (('a', 1e-6), ('b', 1e-6)):
        up = PowerRegressionLoss(**{'a': a, 'b': b, name: {'a': a, 'b': b}[name] + h},
                                 x_unit=x_unit, y_unit=y_unit).power_w(v)
        down = PowerRegressionLoss(**{'a': a, 'b': b, name: {'a': a, 'b': b}[name] - h},
                                   x_unit=x_unit, y_unit=y_unit).power_w(v)
        assert_allclose(g[name], (up - down) / (2 * h), rtol=1e-6, atol=1e-9)
    assert g['a'][2] == 0.0 and g['b'][2] == 0.0


def test_coulomb_viscous_gradient_by_hand():
    loss = CoulombViscousLoss(coulomb_n=20.0, viscous_n_s_m=100.0, mu=0.01)
    v = np.array([0.2, -0.1, 0.0])
    g = loss.power_gradient_w(v, normal_force_n=500.0)
    assert_allclose(g['coulomb_n'], [0.2, 0.1, 0.0])
    assert_allclose(g['viscous_n_s_m'], [0.04, 0.01, 0.0])
    assert_allclose(g['mu'], [100.0, 50.0, 0.0])
    # linear: the power is the gradient dotted with the parameters
    p = 20.0 * g['coulomb_n'] + 100.0 * g['viscous_n_s_m'] + 0.01 * g['mu']
    assert_allclose(loss.power_w(v, normal_force_n=500.0), p, rtol=1e-14)


# ---- loss_covariance in the machine config ---------------------------------------------------

def test_covariance_round_trips_and_is_optional():
    cov = {'params': ['a', 'b'], 'units': PR_UNITS, 'matrix': [[4e-4, -1e-4], [-1e-4, 2e-4]]}
    machine = machine_from_dict(_demo(loss_covariance=cov))
    got = machine.axis('X').loss_covariance
    assert got.params == ('a', 'b') and got.units == tuple(PR_UNITS)
    assert_allclose(got.array(), cov['matrix'])
    assert machine_to_dict(machine)['axes']['X']['loss_covariance'] == cov
    assert machine_from_dict(machine_to_dict(machine)) == machine
    assert load_machine(CONFIG / 'demonstrator.yaml').axis('X').loss_covariance is None


@pytest.mark.parametrize('change, key, words', [
    ({'params': ['a', 'c']}, 'loss_covariance.params[1]', 'not a parameter'),
    ({'params': ['a', 'a']}, 'loss_covariance.params[1]', 'twice'),
    ({'params': 'a'}, 'loss_covariance.params', 'list of parameter names'),
    ({'units': ['W/(mm/s)', '1']}, 'loss_covariance.units[0]', 'units of the loss model'),
    ({'units': ['1']}, 'loss_covariance.units', '2 units'),
    ({'matrix': [[1e-4, 0.0]]}, 'loss_covariance.matrix', '2 rows'),
    ({'matrix': [[1e-4, 0.0], [0.0]]}, 'loss_covariance.matrix[1]', 'row of 2'),
    ({'matrix': [[1e-4, float('nan')], [0.0, 1e-4]]}, 'loss_covariance.matrix[0][1]',
     'finite'),
    ({'matrix': [[1e-4, '0'], [0.0, 1e-4]]}, 'loss_covariance.matrix[0][1]', 'finite'),
    ({'matrix': [[1e-4, 1e20], [1e20, 1e-4]]}, 'loss_covariance.matrix[0][1]', '<= 1e+12'),
    ({'matrix': [[1e-4, 1e-5], [2e-5, 1e-4]]}, 'loss_covariance.matrix[0][1]',
     'not symmetric'),
    ({'matrix': [[-1e-4, 0.0], [0.0, 1e-4]]}, 'loss_covariance.matrix[0][0]', '>= 0'),
    ({'matrix': [[1e-4, 2e-4], [2e-4, 1e-4]]}, 'loss_covariance.matrix', 'semi-definite'),
    ({'extra': 1}, 'loss_covariance.extra', 'unknown key'),
])
def test_invalid_covariance_names_the_key(change, key, words):
    cov = {'params': ['a', 'b'], 'units': PR_UNITS, 'matrix': [[4e-4, 0.0], [0.0, 2e-4]]}
    cov.update(change)
    with pytest.raises(ConfigError) as info:
        machine_from_dict(_demo(loss_covariance=cov), file='m.yaml')
    assert info.value.key == f'axes.X.{key}', str(info.value)
    assert words in str(info.value)
    assert 'm.yaml' in str(info.value) and len(str(info.value)) < 400


def test_missing_part_and_wrong_model_units():
    with pytest.raises(ConfigError, match='axes.X.loss_covariance.matrix: missing'):
        machine_from_dict(_demo(loss_covariance={'params': ['a'], 'units': [PR_UNITS[0]]}))
    # the same covariance is refused once the loss is read in other units
    loss = {'model': 'power_regression', 'a': 0.2, 'b': 0.3, 'x_unit': 'm/s'}
    with pytest.raises(ConfigError, match=r'units\[0\]'):
        machine_from_dict(_demo(loss=loss, loss_covariance={
            'params': ['a'], 'units': [PR_UNITS[0]], 'matrix': [[1e-4]]}))


def test_semi_definite_rank_one_is_accepted():
    # perfectly correlated a and b: singular, still a covariance
    s = np.array([0.02, 0.01])
    cov = {'params': ['a', 'b'], 'units': PR_UNITS, 'matrix': np.outer(s, s).tolist()}
    assert machine_from_dict(_demo(loss_covariance=cov)).axis('X').loss_covariance is not None


# ---- propagation: hand calculation at constant feed -----------------------------------------

def _constant_feed(machine, *, v, duration, n=2001):
    t = np.linspace(0.0, duration, n)
    pos = v * t
    motion = motion_from_samples(t, pos[:, None], axes=('X',), vel=np.full((n, 1), v),
                                 acc=np.zeros((n, 1)))
    return summarize(simulate_motion(motion, machine), top_blocks=0)


@pytest.mark.parametrize('v', [0.05, -0.2])
def test_constant_feed_by_hand(v):
    a, b, T = 0.1339, 0.2179, 3.0
    c = np.array([[0.0045 ** 2, -3e-5], [-3e-5, 0.015 ** 2]])
    data = _demo(loss={'model': 'power_regression', 'a': a, 'b': b},
                 loss_covariance={'params': ['a', 'b'], 'units': PR_UNITS,
                                  'matrix': c.tolist()})
    summary = _constant_feed(machine_from_dict(data), v=v, duration=T)
    u = summary[UNCERTAINTY_KEY]
    x = 1000.0 * abs(v)                     # mm/s
    e = a * x ** (1 + b) * T                # steady loss power a·x^(1+b) [W] for T seconds
    assert_allclose(summary['energy_j']['total'], e, rtol=1e-9)   # no inertia, eta = 1
    d_a, d_b = x ** (1 + b) * T, a * x ** (1 + b) * math.log(x) * T
    assert_allclose([u['gradient']['X']['a'], u['gradient']['X']['b']], [d_a, d_b], rtol=1e-9)
    g = np.array([d_a, d_b])
    sd = math.sqrt(g @ c @ g)
    assert_allclose(u['energy_sd_j']['X'], sd, rtol=1e-9)
    assert_allclose(u['energy_sd_j']['total'], sd, rtol=1e-9)
    assert_allclose(u['relative_pct'], 100.0 * sd / e, rtol=1e-9)
    assert u['axes'] == ['X'] and u['axes_without'] == []
    assert u['units']['X'] == {'a': PR_UNITS[0], 'b': '1'}


def test_nothing_when_no_covariance():
    summary = _constant_feed(load_machine(CONFIG / 'demonstrator.yaml'), v=0.1, duration=1.0)
    assert UNCERTAINTY_KEY not in summary


# ---- propagation on a planned program: finite differences, streaming, sigma points --------

def _mill(braking, *, loss_x=None, cov_x=None, cov_z=None, eta=None):
    data = machine_to_dict(load_machine(CONFIG / 'three_axis_mill.yaml'))
    data['braking'] = braking
    if loss_x is not None:
        data['axes']['X']['loss'] = loss_x
    if eta is not None:
        for axis in data['axes'].values():
            axis['screw']['efficiency'] = eta
    if cov_x is not None:
        data['axes']['X']['loss_covariance'] = cov_x
    if cov_z is not None:
        data['axes']['Z']['loss_covariance'] = cov_z
    return data


def _energy(data, program):
    machine = machine_from_dict(data)
    summary, _ = simulate_stream(program.moves, machine, file=program.file, load_kg=5.0,
                                 chunk_samples=777)
    return summary


@pytest.fixture(scope='module')
def contour():
    machine = load_machine(CONFIG / 'three_axis_mill.yaml')
    return load_gcode(CONFIG / 'programs' / 'three_axis_contour.nc', home=machine.home_point())


CV_UNITS = ['N', 'N*s/m', '1']
CV_COV = {'params': ['coulomb_n', 'viscous_n_s_m', 'mu'], 'units': CV_UNITS,
          'matrix': [[25.0, -40.0, 0.0], [-40.0, 400.0, 0.0], [0.0, 0.0, 1e-6]]}


@pytest.mark.parametrize('braking, eta', [('regenerative', 1.0), ('dissipated', 0.9)])
def test_gradient_matches_finite_differences(contour, braking, eta):
    pr = {'model': 'power_regression', 'a': 0.15, 'b': 0.3}
    cov_pr = {'params': ['a', 'b'], 'units': PR_UNITS, 'matrix': [[1e-4, 0.0], [0.0, 1e-4]]}
    base = _mill(braking, eta=eta, loss_x=pr, cov_x=cov_pr, cov_z=CV_COV)
    ref = _energy(base, contour)
    grad = ref[UNCERTAINTY_KEY]['gradient']
    exact = braking == 'regenerative' and eta == 1.0
    for axis, param, value in (('X', 'a', 0.15), ('X', 'b', 0.3), ('Z', 'coulomb_n', 180.0),
                               ('Z', 'viscous_n_s_m', 400.0)):
        h = 1e-3 * value
        energies = []
        for sign in (1, -1):
            data = copy.deepcopy(base)
            data['axes'][axis]['loss'][param] = value + sign * h
            energies.append(_energy(data, contour)['energy_j']['total'])
        fd = (energies[0] - energies[1]) / (2 * h)
        # linear parameters with a fixed weight: the difference is the gradient to rounding
        tol = 1e-7 if exact and param != 'b' else 2e-3
        assert_allclose(grad[axis][param], fd, rtol=tol)
        assert fd != 0.0


def test_stream_equals_whole(contour):
    data = _mill('dissipated', cov_x=CV_COV, cov_z=CV_COV)
    machine = machine_from_dict(data)
    whole = summarize(simulate_program(contour, machine, load_kg=5.0))[UNCERTAINTY_KEY]
    got = _energy(data, contour)[UNCERTAINTY_KEY]
    for axis in ('X', 'Z', 'total'):
        assert_allclose(got['energy_sd_j'][axis], whole['energy_sd_j'][axis], rtol=1e-12)
    assert got['axes'] == ['X', 'Z'] and got['axes_without'] == ['Y']
    # the axes are independent: the total adds their variances
    assert_allclose(got['energy_sd_j']['total'],
                    math.hypot(got['energy_sd_j']['X'], got['energy_sd_j']['Z']), rtol=1e-12)


def test_covariance_propagates_through_sigma_points(contour):
    # coulomb_viscous is linear in its parameters; with eta = 1 and regenerative braking the
    # energy is linear in them, so the energies at the 2p symmetric sigma points
    # theta ± sqrt(p)·L[:, i] (C = L L') have exactly the variance g'Cg
    theta = np.array([150.0, 400.0, 0.005])
    c = np.array(CV_COV['matrix'])
    base = _mill('regenerative', eta=1.0, cov_x=CV_COV)
    reported = _energy(base, contour)[UNCERTAINTY_KEY]['energy_sd_j']['X']
    chol = np.linalg.cholesky(c)
    p = theta.size
    energies = []
    for i in range(p):
        for sign in (1.0, -1.0):
            data = copy.deepcopy(base)
            point = theta + sign * math.sqrt(p) * chol[:, i]
            data['axes']['X']['loss'].update(zip(CV_COV['params'], point.tolist()))
            energies.append(_energy(data, contour)['energy_j']['X'])
    e = np.array(energies)
    variance = float(np.sum((e - e.mean()) ** 2) / (2 * p))
    assert_allclose(reported, math.sqrt(variance), rtol=1e-6)


def test_fit_covariance_in_model_units():
    from feed_axis_energy.identify.fit.lossfit import LossFit
    fit = LossFit(axis='X', status='ok', message='', a=0.2, b=0.3,
                  cov_ln_a_b=((0.01, -0.002), (-0.002, 0.0004)))
    cov = fit.covariance()
    assert isinstance(cov, LossCovariance)
    assert cov.params == ('a', 'b') and list(cov.units) == PR_UNITS
    assert_allclose(cov.array(), [[0.04 * 0.01, 0.2 * -0.002], [0.2 * -0.002, 0.0004]])
    assert LossFit(axis='X', status='ok', message='', a=0.2, b=0.3).covariance() is None


@pytest.mark.parametrize('value, text', [(213.0, '210'), (4.123, '4.1'), (0.0123, '0.012'),
                                         (1.5, '1.5'), (0.999, '1.0'), (99.7, '100'),
                                         (0.0, '0'), (12345.0, '12000')])
def test_two_significant_digits(value, text):
    from feed_axis_energy.physics.uncertainty import two_digits
    assert two_digits(value) == text


def test_relative_uncertainty_of_a_whole_simulation(contour):
    from feed_axis_energy.physics.uncertainty import relative_sd_pct
    data = _mill('regenerative', cov_x=CV_COV, cov_z=CV_COV)
    machine = machine_from_dict(data)
    whole = simulate_program(contour, machine, load_kg=5.0)
    u = summarize(whole)[UNCERTAINTY_KEY]['energy_sd_j']
    e = summarize(whole)['energy_j']
    assert_allclose(relative_sd_pct(whole, ('X', 'Z')),
                    100.0 * math.hypot(u['X'], u['Z']) / (e['X'] + e['Z']), rtol=1e-12)
    assert_allclose(relative_sd_pct(whole, ('X',)), 100.0 * u['X'] / e['X'], rtol=1e-12)
    # Y has no covariance: a figure for X, Y would be too small, so there is none
    assert math.isnan(relative_sd_pct(whole, ('X', 'Y')))


def test_compare_answer_names_the_uncertainty_where_known():
    from types import SimpleNamespace
    from feed_axis_energy.report.html import compare_answer

    def run(err, sd):
        return SimpleNamespace(name='r', energy_sd_pct=sd, metrics=SimpleNamespace(
            energy_error_pct=err, avg_pct_error_pct=5.0))
    known = compare_answer(SimpleNamespace(runs=[run(2.0, 1.2), run(-3.0, 1.4)]))
    assert '±1.3 % of the simulated energy from the loss-function uncertainty' in known
    unknown = compare_answer(SimpleNamespace(runs=[run(2.0, math.nan)]))
    assert 'uncertainty' not in unknown
