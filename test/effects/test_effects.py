"""Effect catalog: powers by hand on a small state, bases, registry and documentation."""
import math
from pathlib import Path
import re

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.effects.catalog import (EFFECTS, Effect, effects_power_w, EffectState,
                                              get_effect, Param, register_effect)
from feed_axis_energy.physics.effectstate import state_from_simulation
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.units import GRAVITY_M_S2
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.sim.simulate import simulate_program

ROOT = Path(__file__).resolve().parents[2]
LEAD = 0.01

# 4 samples, 2 axes: positive, negative and zero speeds, accelerating and braking.
T = [0.0, 1.0, 2.0, 3.0]
V = [[0.1, -0.2], [-0.3, 0.0], [0.5, 0.2], [0.0, -0.1]]
A = [[1.0, 0.5], [-2.0, 0.0], [0.0, -1.0], [3.0, 2.0]]
X = [[0.0, 0.1], [0.2, 0.4], [0.3, 0.05], [0.4, 0.0]]
M = [[0.5, -1.0], [-2.0, 0.0], [1.5, 0.25], [0.0, 0.3]]
P = [[40.0, -30.0], [-80.0, 0.0], [120.0, 10.0], [0.0, -5.0]]
MASS = [20.0, 8.0]
NORMAL = [20.0 * GRAVITY_M_S2, 0.5 * 8.0 * GRAVITY_M_S2]   # axis 2 inclined by 60 deg
LOAD_NORMAL = [5.0 * GRAVITY_M_S2, 0.0]   # the 5 kg load rides on axis 1 only


def _state() -> EffectState:
    v = np.array(V)
    x = np.array(X)
    return EffectState(
        t=np.array(T), axes=('X', 'Y'), position_m=x, velocity_m_s=v,
        acceleration_m_s2=np.array(A), angle_rad=2 * math.pi * x / LEAD,
        omega_rad_s=2 * math.pi * v / LEAD, force_n=np.zeros((4, 2)), torque_nm=np.array(M),
        mass_kg=np.array(MASS), load_kg=5.0, normal_force_n=np.array(NORMAL),
        lead_m=np.array([LEAD, LEAD]), mechanical_w=np.array(P), power_w=np.array(P),
        load_normal_force_n=np.array(LOAD_NORMAL))


def _w(v: float) -> float:
    return 2 * math.pi * v / LEAD


def _phi(x: float) -> float:
    return 2 * math.pi * x / LEAD


# id -> (params, hand formula of one sample: (i, j) -> W)
HAND = {
    'standby': ({'p0_w': 12.0}, lambda i, j: 12.0),
    'coulomb': ({'f_pos_n': 20.0, 'f_neg_n': 25.0},
                lambda i, j: 20.0 * V[i][j] if V[i][j] > 0 else -25.0 * V[i][j]),
    'viscous': ({'c_n_s_m': 100.0}, lambda i, j: 100.0 * V[i][j] ** 2),
    # +30 N*s/m more moving in +, 30 less moving in -
    'viscous_asymmetry': ({'d_n_s_m': 30.0}, lambda i, j: 30.0 * V[i][j] * abs(V[i][j])),
    # 15 N pulling towards -: moving in + costs 15 N * v, moving in - returns it
    'offset_force': ({'f0_n': 15.0}, lambda i, j: 15.0 * V[i][j]),
    'load_friction': ({'mu': 0.05}, lambda i, j: 0.05 * NORMAL[j] * abs(V[i][j])),
    'clamped_load_friction': ({'mu_l': 0.05},
                              lambda i, j: 0.05 * LOAD_NORMAL[j] * abs(V[i][j])),
    'stribeck': ({'f_s_n': 40.0, 'v_s_m_s': 0.2},
                 lambda i, j: 40.0 * math.exp(-(V[i][j] / 0.2) ** 2) * abs(V[i][j])),
    'copper': ({'k_w_nm2': 3.0}, lambda i, j: 3.0 * M[i][j] ** 2),
    'iron': ({'k_h_w_s_rad': 0.05, 'k_e_w_s2_rad2': 1e-4},
             lambda i, j: 0.05 * abs(_w(V[i][j])) + 1e-4 * _w(V[i][j]) ** 2),
    'mass_error': ({'dm_kg': 3.0}, lambda i, j: 3.0 * A[i][j] * V[i][j]),
    # sin(theta) = 0.1: the weight of each axis's own moved mass (20 kg, 8 kg)
    'gravity': ({'sin_theta': 0.1}, lambda i, j: 0.1 * MASS[j] * GRAVITY_M_S2 * V[i][j]),
    # bumps 1 and 3 at x = 0.1 and 0.3 m, standard deviation 0.6 * 0.1 m
    'position_friction': (
        {'c1_n': 10.0, 'c3_n': -4.0, 'x0_m': 0.1, 'spacing_m': 0.1},
        lambda i, j: abs(V[i][j]) * (10.0 * math.exp(-0.5 * ((X[i][j] - 0.1) / 0.06) ** 2)
                                     - 4.0 * math.exp(-0.5 * ((X[i][j] - 0.3) / 0.06) ** 2))),
    'torque_ripple': (
        {'a1_nm': 0.1, 'b1_nm': -0.05, 'a2_nm': 0.02, 'b2_nm': 0.03},
        lambda i, j: _w(V[i][j]) * (0.1 * math.sin(_phi(X[i][j]))
                                    - 0.05 * math.cos(_phi(X[i][j]))
                                    + 0.02 * math.sin(2 * _phi(X[i][j]))
                                    + 0.03 * math.cos(2 * _phi(X[i][j])))),
    # tau = 2 s: the force after t seconds is 0.5 * 2 * (1 - exp(-t/2))
    'thermal_drift': ({'rate_n_s': 0.5, 'tau_s': 2.0},
                      lambda i, j: 1.0 * (1.0 - math.exp(-T[i] / 2.0)) * abs(V[i][j])),
    # one-sample shift: the value of the previous sample, held at the start
    'time_offset': ({'delta_s': 1.0}, lambda i, j: P[max(i - 1, 0)][j] - P[i][j]),
    'braking_loss': ({'fraction': 0.25}, lambda i, j: 0.25 * max(-P[i][j], 0.0)),
}


def test_every_registered_effect_has_a_hand_calculation() -> None:
    assert set(HAND) == set(EFFECTS)


@pytest.mark.parametrize('effect_id', sorted(HAND))
def test_power_against_hand_calculation(effect_id: str) -> None:
    params, formula = HAND[effect_id]
    got = get_effect(effect_id).power_w(_state(), params)
    want = np.array([[formula(i, j) for j in range(2)] for i in range(4)])
    assert got.shape == (4, 2)
    assert_allclose(got, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize('effect_id', sorted(HAND))
def test_absent_effect_adds_nothing(effect_id: str) -> None:
    # defaults mean "effect absent"
    assert_allclose(get_effect(effect_id).power_w(_state()), 0.0, atol=1e-15)


def test_time_offset_half_sample_interpolates() -> None:
    got = get_effect('time_offset').power_w(_state(), {'delta_s': 0.5})
    p = np.array(P)
    want = np.vstack([p[:1], 0.5 * (p[1:] + p[:-1])]) - p
    assert_allclose(got, want, rtol=1e-12)


@pytest.mark.parametrize('effect_id', sorted(i for i, c in EFFECTS.items() if c.exact_basis))
def test_basis_reproduces_power(effect_id: str) -> None:
    effect = get_effect(effect_id)
    rng = np.random.default_rng(7)
    state = _state()
    params = dict(HAND[effect_id][0])
    # one value per axis for every linear parameter, within its physical bounds
    for name, lo, hi in zip(effect.linear_params(), *effect.linear_bounds()):
        params[name] = rng.uniform(max(lo, -2.0), min(hi, 2.0), size=2)
    basis = effect.basis(state, params)
    assert basis.shape == (4, 2, len(effect.linear_params()))
    combined = sum(basis[..., i] * params[name]
                   for i, name in enumerate(effect.linear_params()))
    assert_allclose(effect.power_w(state, params), combined, rtol=1e-12, atol=1e-12)


def test_time_offset_basis_is_first_order_on_a_smooth_signal() -> None:
    t = np.linspace(0.0, 2.0, 2001)
    p = 100.0 * np.sin(2 * np.pi * 0.5 * t)[:, None]
    zeros = np.zeros_like(p)
    state = EffectState(t=t, axes=('X',), position_m=zeros, velocity_m_s=zeros,
                        acceleration_m_s2=zeros, angle_rad=zeros, omega_rad_s=zeros,
                        force_n=zeros, torque_nm=zeros, mass_kg=np.ones(1), load_kg=0.0,
                        normal_force_n=np.ones(1), lead_m=np.ones(1), mechanical_w=p,
                        power_w=p)
    effect = get_effect('time_offset')
    delta = 0.004
    exact = effect.power_w(state, {'delta_s': delta})[100:-100]
    linear = effect.basis(state)[100:-100, :, 0] * delta
    # dP/dt peaks at 100*pi W/s: the shift is about 1.26 W, the error O(delta²) far below
    assert np.max(np.abs(exact)) > 1.2
    assert_allclose(exact, linear, atol=0.01)


def test_stribeck_shape_parameter_changes_basis() -> None:
    effect = get_effect('stribeck')
    narrow = effect.basis(_state(), {'v_s_m_s': 0.05})
    wide = effect.basis(_state(), {'v_s_m_s': 0.5})
    assert effect.shape_params() == ('v_s_m_s', 'delta')
    assert effect.linear_params() == ('f_s_n',)
    assert np.all(wide[..., 0] >= narrow[..., 0])
    assert wide[2, 0, 0] > narrow[2, 0, 0]


def test_stribeck_exponential_decays_from_static_to_coulomb_level() -> None:
    # delta = 1: the excess force at |v| = vs is Fs/e, at 3 vs Fs/e^3 (hand values)
    effect = get_effect('stribeck')
    state = _state()
    p = effect.power_w(state, {'f_s_n': 40.0, 'v_s_m_s': 0.1, 'delta': 1.0})
    assert_allclose(p[0, 0], 40.0 * math.exp(-1.0) * 0.1)
    assert_allclose(p[1, 0], 40.0 * math.exp(-3.0) * 0.3)
    assert np.all(p >= 0.0)
    with pytest.raises(ConfigError, match="'delta' of effect 'stribeck' must lie in"):
        effect.resolve({'delta': 0.0})


def test_asymmetric_coulomb_is_symmetric_friction_plus_offset_force() -> None:
    from feed_axis_energy.effects import aliases_of, join_coulomb, split_coulomb
    state = _state()
    fc, f0 = split_coulomb(30.0, 10.0)
    assert (fc, f0) == (20.0, 10.0)
    assert join_coulomb(fc, f0) == (30.0, 10.0)
    asym = get_effect('coulomb').power_w(state, {'f_pos_n': 30.0, 'f_neg_n': 10.0})
    parts = (get_effect('coulomb').power_w(state, {'f_pos_n': fc, 'f_neg_n': fc})
             + get_effect('offset_force').power_w(state, {'f0_n': f0}))
    assert_allclose(asym, parts, atol=1e-12)
    exact = [a for a in aliases_of('offset_force') if 'coulomb' in a.members]
    assert len(exact) == 1 and exact[0].separates_when == ''


def test_offset_force_is_gravity_unless_the_moved_mass_varies() -> None:
    from feed_axis_energy.effects import masses_vary
    state = _state()
    offset = get_effect('offset_force')
    gravity = get_effect('gravity')
    # one mass (axis X, 20 kg): F0 = m g sin(theta) gives the same power
    same = gravity.power_w(state, {'sin_theta': 15.0 / (20.0 * GRAVITY_M_S2)})
    assert_allclose(offset.power_w(state, {'f0_n': 15.0})[:, 0], same[:, 0])
    assert not masses_vary(np.array([20.0, 20.0, 20.0]))
    # another run with 5 kg more: gravity's force follows the mass, the offset does not
    heavier = EffectState(**{**state.__dict__, 'mass_kg': np.array([25.0, 8.0])})
    other = gravity.power_w(heavier, {'sin_theta': 15.0 / (20.0 * GRAVITY_M_S2)})
    assert not np.allclose(other[:, 0], offset.power_w(heavier, {'f0_n': 15.0})[:, 0])
    assert masses_vary(np.array([20.0, 25.0]))


def test_unknown_parameter_and_effect_are_named() -> None:
    with pytest.raises(ConfigError, match="'coulomb' has no parameter 'f_n'"):
        get_effect('coulomb').power_w(_state(), {'f_n': 1.0})
    with pytest.raises(ConfigError, match="unknown effect 'sticktion'"):
        get_effect('sticktion')
    with pytest.raises(ConfigError, match='finite'):
        get_effect('viscous').resolve({'c_n_s_m': float('nan')})


@pytest.mark.parametrize('effect_id, name, value', [
    ('copper', 'k_w_nm2', -3.1), ('iron', 'k_e_w_s2_rad2', -1e-5), ('standby', 'p0_w', -1.0),
    ('stribeck', 'f_s_n', -5.0), ('load_friction', 'mu', -0.01), ('gravity', 'sin_theta', 1.5),
    ('braking_loss', 'fraction', 1.2), ('thermal_drift', 'tau_s', 0.0),
    ('offset_force', 'f0_n', 2.0e6), ('stribeck', 'delta', 20.0)])
def test_values_outside_the_physical_bounds_are_refused(effect_id, name, value) -> None:
    with pytest.raises(ConfigError, match=f"'{name}' of effect '{effect_id}' must lie in"):
        get_effect(effect_id).resolve({name: value})


def test_every_loss_coefficient_is_bounded_below_by_zero() -> None:
    # what the catalog documents as never negative: losses, friction coefficients, shares
    for effect_id, name in [('copper', 'k_w_nm2'), ('iron', 'k_h_w_s_rad'),
                            ('iron', 'k_e_w_s2_rad2'), ('standby', 'p0_w'),
                            ('stribeck', 'f_s_n'), ('load_friction', 'mu'),
                            ('clamped_load_friction', 'mu_l'), ('braking_loss', 'fraction')]:
        param = next(p for p in EFFECTS[effect_id].params if p.name == name)
        assert param.bounds[0] == 0.0, (effect_id, name)


def test_gravity_force_follows_the_moved_mass_of_each_run() -> None:
    # one angle, m·g·sin(theta) per load: the force at 25 kg is 25/20 of that at 20 kg
    state = _state()
    heavier = EffectState(**{**state.__dict__, 'mass_kg': np.array([25.0, 8.0])})
    effect = get_effect('gravity')
    theta = math.radians(3.0)
    a = effect.power_w(state, {'sin_theta': math.sin(theta)})
    b = effect.power_w(heavier, {'sin_theta': math.sin(theta)})
    assert_allclose(b[:, 0], 25.0 / 20.0 * a[:, 0])
    assert_allclose(a[2, 0], 20.0 * GRAVITY_M_S2 * math.sin(theta) * 0.5)


def test_thermal_drift_is_linear_in_the_limit_and_saturates() -> None:
    effect = get_effect('thermal_drift')
    state = _state()
    linear = effect.power_w(state, {'rate_n_s': 0.5})     # default tau: the linear limit
    want = 0.5 * np.array(T)[:, None] * np.abs(np.array(V))
    assert_allclose(linear, want, rtol=1e-8)
    # after many time constants the force change is rate * tau
    t = np.array([1000.0])
    far = EffectState(**{**state.__dict__, 't': np.repeat(t, 4)})
    sat = effect.power_w(far, {'rate_n_s': 0.5, 'tau_s': 10.0})
    assert_allclose(sat, 0.5 * 10.0 * np.abs(np.array(V)), rtol=1e-12)


def test_position_friction_localises_a_rough_spot() -> None:
    # one bump of 30 N at x = 0.15 m with a 30 mm spacing: sigma 18 mm, half height at
    # 1.1774 sigma either side
    x = np.linspace(0.0, 0.4, 4001)[:, None]
    ones = np.ones_like(x)
    state = EffectState(t=x[:, 0], axes=('X',), position_m=x, velocity_m_s=ones,
                        acceleration_m_s2=0 * x, angle_rad=0 * x, omega_rad_s=0 * x,
                        force_n=0 * x, torque_nm=0 * x, mass_kg=np.ones(1), load_kg=0.0,
                        normal_force_n=np.ones(1), lead_m=np.ones(1), mechanical_w=0 * x,
                        power_w=0 * x)
    p = get_effect('position_friction').power_w(state, {'c6_n': 30.0, 'spacing_m': 0.03})
    above = x[p[:, 0] > 15.0, 0]
    assert above.min() == pytest.approx(0.15 - 1.1774 * 0.018, abs=2e-4)
    assert above.max() == pytest.approx(0.15 + 1.1774 * 0.018, abs=2e-4)
    assert np.max(p[np.abs(x[:, 0] - 0.15) > 0.06]) < 0.01 * 30.0
    # the bumps together are flat within 0.5 % inside the covered range
    flat = get_effect('position_friction').power_w(
        state, {f'c{i}_n': 1.0 for i in range(1, 17)} | {'spacing_m': 0.025})
    inner = (x[:, 0] > 0.05) & (x[:, 0] < 0.32)
    assert np.ptp(flat[inner, 0]) < 0.005 * np.mean(flat[inner, 0])


def test_effects_power_sums_effects() -> None:
    state = _state()
    both = effects_power_w(state, [('standby', {'p0_w': 5.0}), ('viscous', {'c_n_s_m': 10.0})])
    assert_allclose(both, 5.0 + 10.0 * np.array(V) ** 2)


def test_adding_an_effect_is_one_class() -> None:
    @register_effect
    class Cubic(Effect):
        id = 'test_cubic'
        description = 'test only'
        params = (Param('k', 'W*s^3/m^3', 0.0, 0.0, 1.0, 1.0, 'coefficient'),)

        def _basis(self, state, values):
            return [np.abs(state.velocity_m_s) ** 3]

    try:
        assert_allclose(get_effect('test_cubic').power_w(_state(), {'k': 2.0}),
                        2.0 * np.abs(np.array(V)) ** 3)
        with pytest.raises(ValueError, match='registered twice'):
            register_effect(Cubic)
    finally:
        del EFFECTS['test_cubic']


def test_state_from_simulation_uses_moved_mass_and_declared_power() -> None:
    machine = load_machine(ROOT / 'config' / 'demonstrator.yaml')
    program = parse_gcode('G21 G90 G94 G61\nG1 X100 F12000\nG4 P0.2\nX0\nM30\n')
    result = simulate_program(program, machine, load_kg=17.336)
    state = state_from_simulation(result)
    mass = machine.axis('X').table_mass_kg + 17.336
    assert_allclose(state.mass_kg, [mass])
    assert_allclose(state.normal_force_n, [mass * GRAVITY_M_S2])
    assert_allclose(state.power_w, result.power.power_w)
    assert_allclose(state.omega_rad_s, 2 * np.pi * state.velocity_m_s / 0.01)
    # load friction on this state: mu·m·g·|v| sample by sample
    extra = get_effect('load_friction').power_w(state, {'mu': 0.1})
    assert_allclose(extra, 0.1 * mass * GRAVITY_M_S2 * np.abs(result.motion.vel))


@pytest.mark.parametrize('effect_id', sorted(i for i, c in EFFECTS.items() if c.sample_local))
def test_a_sample_local_basis_on_rows_is_those_rows_of_the_basis(effect_id: str) -> None:
    # what analyze relies on when it computes a long run's candidate columns in slices
    machine = load_machine(ROOT / 'config' / 'demonstrator.yaml')
    program = parse_gcode('G21 G90 G94 G61\nG1 X100 F12000\nG4 P0.2\nX0 F3000\nM30\n')
    state = state_from_simulation(simulate_program(program, machine, load_kg=17.336))
    effect = get_effect(effect_id)
    params = {name: value for name, value in HAND[effect_id][0].items()
              if name not in effect.linear_params()}
    whole = effect.basis(state, params)
    n = state.t.shape[0]
    cuts = [0, 1, n // 3, n // 3, n - 7, n]
    parts = [effect.basis(state.rows(a, b), params) for a, b in zip(cuts[:-1], cuts[1:])]
    assert_allclose(np.concatenate(parts), whole, rtol=0.0, atol=0.0)
    back = EffectState.joined([state.rows(a, b) for a, b in zip(cuts[:-1], cuts[1:])])
    for name in EffectState.SAMPLE_FIELDS:
        assert_allclose(getattr(back, name), getattr(state, name), rtol=0.0, atol=0.0)
    assert EffectState.joined([state]) is state
    with pytest.raises(ValueError, match='at least one piece'):
        EffectState.joined([])
    view = state.rows(5, 9)
    assert view.t.shape == (4,) and np.shares_memory(view.power_w, state.power_w)
    assert view.mass_kg is state.mass_kg


def _doc_rows() -> dict[str, str]:
    text = (ROOT / 'docs' / 'effects.md').read_text(encoding='utf-8')
    rows = {}
    for line in text.splitlines():
        match = re.match(r'\|\s*`([a-z_0-9]+)`\s*\|', line)
        if match:
            rows[match.group(1)] = line
    return rows


def test_every_effect_is_documented_with_its_parameters() -> None:
    rows = _doc_rows()
    assert set(rows) == set(EFFECTS), 'docs/effects.md table and EFFECTS differ'
    for effect_id, cls in EFFECTS.items():
        for p in cls.params:
            assert f'`{p.name}`' in rows[effect_id], f'{effect_id}.{p.name} undocumented'
            assert p.unit in rows[effect_id], f'{effect_id}.{p.name} unit undocumented'


def test_load_share_of_the_normal_force_follows_the_stacking():
    # three_axis_mill: the load sits on the Y table, Y rides on X, Z carries neither.
    from pathlib import Path

    from feed_axis_energy.physics.effectstate import state_from_simulation
    from feed_axis_energy.gcode.load import parse_gcode
    from feed_axis_energy.machine.file import load_machine
    from feed_axis_energy.sim.simulate import simulate_program

    machine = load_machine(Path(__file__).resolve().parents[2] / 'config' / 'three_axis_mill.yaml')
    program = parse_gcode('G21 G90 G1 X10 Y10 Z10 F600\n', file='p.nc')
    state = state_from_simulation(simulate_program(program, machine, load_kg=50.0))
    assert state.axes == ('X', 'Y', 'Z')
    assert_allclose(state.load_normal_force_n, [50.0 * GRAVITY_M_S2, 50.0 * GRAVITY_M_S2, 0.0])


def test_clamped_load_friction_without_a_load_share_uses_the_whole_load():
    state = _state()
    fallback = EffectState(**{**state.__dict__, 'load_normal_force_n': None})
    got = get_effect('clamped_load_friction').power_w(fallback, {'mu_l': 0.1})
    assert_allclose(got, 0.1 * 5.0 * GRAVITY_M_S2 * np.abs(np.array(V)), rtol=1e-12)
