"""Pieces of analyze: declared effects in the machine model, selection, diagnostics."""
import copy
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import ConfigError
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.identify.diagnostics import binned_structure, noise_sigma, spectrum_structure
from feed_axis_energy.identify.selection import Design, forward_select, loro_folds
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.sim.simulate import simulate_program

ROOT = Path(__file__).resolve().parents[2]
PROGRAM = 'G21 G90 G94 G61\nG0 X0\nG4 P0.5\nG1 X200 F18000\nG4 P0.5\nX0\nM30\n'


def _demo_dict(effects):
    d = copy.deepcopy(machine_to_dict(load_machine(ROOT / 'config' / 'demonstrator.yaml')))
    d['effects'] = effects
    return d


def test_declared_standby_adds_its_power_and_energy() -> None:
    plain = machine_from_dict(_demo_dict([]))
    with_p0 = machine_from_dict(_demo_dict([{'id': 'standby', 'axis': 'X',
                                             'params': {'p0_w': 12.5}}]))
    program = parse_gcode(PROGRAM)
    a = simulate_program(program, plain)
    b = simulate_program(program, with_p0)
    assert_allclose(b.power.power_w - a.power.power_w, 12.5)
    duration = a.power.t[-1] - a.power.t[0]
    assert_allclose(b.power.total_energy_j[-1] - a.power.total_energy_j[-1], 12.5 * duration)
    assert_allclose(b.power.mechanical_w, a.power.mechanical_w)


def test_declared_load_friction_by_hand() -> None:
    mu = 0.05
    m = machine_from_dict(_demo_dict([{'id': 'load_friction', 'params': {'mu': mu}}]))
    plain = machine_from_dict(_demo_dict([]))
    program = parse_gcode(PROGRAM)
    a = simulate_program(program, plain, load_kg=10.0)
    b = simulate_program(program, m, load_kg=10.0)
    v = a.motion.vel[:, 0]
    assert_allclose(b.power.power_w[:, 0] - a.power.power_w[:, 0],
                    mu * (12.0 + 10.0) * 9.80665 * np.abs(v), atol=1e-9)


def test_machine_effects_round_trip() -> None:
    d = _demo_dict([{'id': 'coulomb', 'axis': 'X', 'params': {'f_pos_n': 3.0}},
                    {'id': 'stribeck', 'axis': None,
                     'params': {'f_s_n': 40.0, 'v_s_m_s': 0.02}}])
    m = machine_from_dict(d)
    assert m.effects[0].values == {'f_pos_n': 3.0}
    assert m.effects[1].axis is None
    assert machine_from_dict(machine_to_dict(m)) == m
    # without effects the YAML form has no 'effects' key (the paper's plain model)
    assert 'effects' not in machine_to_dict(machine_from_dict(_demo_dict([])))


@pytest.mark.parametrize('effects, key', [
    ([{'id': 'warp_drive'}], 'effects[0].id'),
    ([{'id': 'coulomb', 'params': {'f_up_n': 1.0}}], 'effects[0].params.f_up_n'),
    ([{'id': 'coulomb', 'axis': 'Q'}], 'effects[0].axis'),
    ([{'id': 'standby', 'params': {'p0_w': 'lots'}}], 'effects[0].params.p0_w'),
    ([{'id': 'standby', 'colour': 'red'}], 'effects[0].colour'),
    ({'id': 'standby'}, 'effects'),
])
def test_machine_effects_are_validated(effects, key) -> None:
    with pytest.raises(ConfigError, match=key.replace('[', r'\[').replace(']', r'\]')):
        machine_from_dict(_demo_dict(effects), file='m.yaml')


def test_forward_select_picks_the_true_column_only() -> None:
    rng = np.random.default_rng(0)
    xs, ys = [], []
    for _ in range(5):
        x1 = rng.normal(size=400)
        ys.append(3.0 * x1 + rng.normal(scale=0.5, size=400))
        xs.append(x1)
    design = Design(ys)
    design.add_block(('true', 'X'), {}, ('a',), [x[:, None] for x in xs])
    design.add_block(('noise', 'X'), {}, ('b',), [rng.normal(size=(400, 1)) for _ in xs])
    sel = forward_select(design, loro_folds(5))
    assert [b.key for b in sel.blocks] == [('true', 'X')]
    assert sel.steps[-1].accepted is False
    assert_allclose(design.fit(sel.cols, range(5)), [3.0], rtol=0.02)


def test_forward_select_needs_two_heldout_runs() -> None:
    x = np.linspace(0, 1, 50)
    design = Design([2 * x, 2 * x])
    design.add_block(('e', 'X'), {}, ('a',), [x[:, None], x[:, None]])
    sel = forward_select(design, [([0], [1])])
    assert sel.blocks == ()
    assert 'fewer than 2' in sel.steps[0].reason


def test_diagnostics_find_a_step_and_a_sine_not_noise() -> None:
    rng = np.random.default_rng(1)
    x = rng.uniform(0.0, 0.4, size=4000)
    noise = rng.normal(scale=1.0, size=4000)
    sigma = noise_sigma([noise])
    assert sigma == pytest.approx(1.0, rel=0.1)
    assert not binned_structure(noise, x, sigma=sigma, name='position', axis='X').structured
    step = noise + 3.0 * (x > 0.25)
    d = binned_structure(step, x, sigma=sigma, name='position', axis='X')
    assert d.structured and d.p_value < 1e-10
    t = np.arange(1200) * 0.05
    runs = [rng.normal(size=1200) for _ in range(3)]
    flat = spectrum_structure(runs, period_s=0.05, sigma=1.0, axis='X')
    assert not flat.structured
    wavy = spectrum_structure([r + 5.0 * np.sin(2 * np.pi * 3.7 * t) for r in runs],
                              period_s=0.05, sigma=1.0, axis='X')
    assert wavy.structured
    assert wavy.peak_hz == pytest.approx(3.7, abs=0.1)
    assert wavy.rms_w == pytest.approx(5.0, rel=0.3)


def test_a_mass_error_on_a_circle_shows_only_against_kinetic_power() -> None:
    # X of a circle at constant speed: v = -R w sin(wt), a = -R w² cos(wt). A wrong moved
    # mass leaves dm·a·v = dm R² w³ sin cos, whose mean is zero at every velocity, position
    # and acceleration (each bin holds sin and cos of both signs), not at every a·v.
    rng = np.random.default_rng(3)
    r_m, w, dm_kg, sigma = 0.02, 2.0, 400.0, 0.2
    t = np.arange(0.0, 60.0, 0.1)
    x = r_m * np.cos(w * t)
    v = -r_m * w * np.sin(w * t)
    a = -r_m * w ** 2 * np.cos(w * t)
    residual = dm_kg * a * v + rng.normal(scale=sigma, size=t.size)
    for name, state in (('velocity', v), ('position', x), ('acceleration', a)):
        assert not binned_structure(residual, state, sigma=sigma, name=name,
                                    axis='X').structured, name
    found = binned_structure(residual, a * v, sigma=sigma, name='kinetic_power', axis='X')
    assert found.structured and found.p_value < 1e-10
    # the bin means follow dm·a·v: their RMS is that of a sine of amplitude dm R² w³ / 2
    assert found.rms_w == pytest.approx(dm_kg * r_m ** 2 * w ** 3 / 2 / np.sqrt(2), rel=0.15)
