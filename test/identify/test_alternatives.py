"""Alternatives outside the catalog (identify/alternatives.py), by construction:
a meter gain, a meter lag and a reversal pulse are named; real friction is not taken for
them."""
from types import SimpleNamespace

import numpy as np
import pytest

from feed_axis_energy.identify.alternatives import (check_alternatives, meter_columns,
                                                    reversal_columns)
from feed_axis_energy.identify.selection import Design
from feed_axis_energy.measured.align import interval_average


def _runs(n_runs=6):
    """1 kHz declared power of a speed-dependent loss (v^1.35) plus acceleration peaks, on
    reciprocating moves, and the instrument: 50 ms averages stamped at the window's end."""
    out = []
    for r in range(n_runs):
        t = np.arange(0.0, 8.0, 1e-3)
        v = (0.1 + 0.08 * r) * np.clip(np.sin(np.pi * t / 4.0) * 3.0, -1.0, 1.0)
        x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * 1e-3)])
        p = 250.0 * np.abs(v) ** 1.35 + 40.0 * np.gradient(v, t) * v
        stamps = np.arange(0.1, 7.9, 0.05)

        def aligned(cols, t=t, stamps=stamps):
            return interval_average(t, cols, stamps, window_s=0.05)

        state = SimpleNamespace(t=t, power_w=p[:, None], position_m=x[:, None],
                                velocity_m_s=v[:, None])
        out.append((state, [0], aligned))
    return out


def _avg(run, values):
    return run[2](values[:, None])[:, 0]


def _design(residuals, runs):
    design = Design([res.reshape(-1) for res in residuals])
    # viscous-like v^2 and flat Coulomb-like |v| columns: together they imitate a scale
    # of the loss power
    design.add_block(('viscous', 'X'), {}, ['c_n_s_m'],
                     [r[2](r[0].velocity_m_s ** 2) for r in runs])
    design.add_block(('coulomb', 'X'), {}, ['f_pos_n'],
                     [r[2](np.abs(r[0].velocity_m_s)) for r in runs])
    return design


def test_meter_columns_are_the_averaged_power_and_its_derivatives():
    state, idx, aligned = _runs(1)[0]
    t, p = state.t, state.power_w[:, 0]
    cols = meter_columns(t, state.power_w, idx, aligned)
    stamps = np.arange(0.1, 7.9, 0.05)
    assert cols.shape == (stamps.size, 3)
    np.testing.assert_allclose(cols[:, 0], interval_average(t, p, stamps, window_s=0.05))
    # the average of -P' over a window is minus the change of P across it, over the window
    change = -(np.interp(stamps, t, p) - np.interp(stamps - 0.05, t, p)) / 0.05
    np.testing.assert_allclose(cols[:, 1], change, atol=0.02 * np.abs(change).max())
    # an axis that is not simulated has zero columns
    two = meter_columns(t, state.power_w, [0, None], aligned)
    assert two.shape == (2 * stamps.size, 6)
    assert np.all(two[1::2] == 0.0) and np.all(two[0::2, 3:] == 0.0)


def test_reversal_pulse_starts_with_each_new_direction():
    t = np.arange(0.0, 6.0, 1e-3)
    # forward 1 s, stop, forward again, then back: pulses at the first and third start only
    v = np.where(t < 1.0, 0.1, 0.0) + np.where((t >= 2.0) & (t < 3.0), 0.1, 0.0) \
        - np.where((t >= 4.0) & (t < 5.0), 0.1, 0.0)
    x = np.concatenate([[0.0], np.cumsum(v[:-1] * 1e-3)])
    cols = reversal_columns(t, np.zeros((t.size, 1)), x[:, None], v[:, None], [0],
                            lambda c: c, decay_m=0.005)
    pulse = cols[:, 0]
    assert pulse[0] == pytest.approx(0.1)                 # first move: a new direction
    assert pulse[2000] == pytest.approx(0.1 * np.exp(-0.1 / 0.005))   # same direction
    assert pulse[4000] == pytest.approx(0.1)              # reversal
    assert pulse[4050] == pytest.approx(0.1 * np.exp(-0.005 / 0.005), rel=1e-3)
    assert np.all(pulse[v == 0.0] == 0.0)


def test_a_gain_of_the_declared_power_is_named_with_its_size():
    rng = np.random.default_rng(3)
    runs = _runs()
    # 0.3 W noise: the acceleration peaks' share of the gain (about 0.7 W) stands out
    residuals = [0.03 * _avg(r, r[0].power_w[:, 0]) + rng.normal(0.0, 0.3, 156) for r in runs]
    design = _design(residuals, runs)
    entry = check_alternatives(design, design.blocks, runs, axes=('X',))
    assert entry is not None and entry['diagnostic'] == 'instrument'
    assert entry['statistic'] == pytest.approx(0.03, abs=0.002)
    assert 'viscous on X, coulomb on X' in entry['message']


def test_a_meter_lag_is_named_with_its_delay():
    rng = np.random.default_rng(4)
    runs = _runs()
    residuals = []
    for r in runs:
        p = r[0].power_w[:, 0]
        # a first-order lag of 20 ms on the power before the 50 ms average
        lag = np.empty_like(p)
        acc = p[0]
        alpha = 1.0 - np.exp(-1e-3 / 0.02)
        for i, value in enumerate(p):
            acc += alpha * (value - acc)
            lag[i] = acc
        residuals.append(_avg(r, lag) - _avg(r, p) + rng.normal(0.0, 1.0, 156))
    design = _design(residuals, runs)
    entry = check_alternatives(design, design.blocks, runs, axes=('X',))
    assert entry is not None and entry['diagnostic'] == 'instrument'
    # the delay of a first-order lag is its time constant
    assert 'delay +2' in entry['message'] or 'delay +1' in entry['message']


def test_a_reversal_pulse_is_named_with_its_force():
    rng = np.random.default_rng(6)
    runs = _runs()
    residuals = []
    for r in runs:
        truth = reversal_columns(r[0].t, r[0].power_w, r[0].position_m, r[0].velocity_m_s,
                                 [0], lambda c: c, decay_m=0.005)[:, 0]
        residuals.append(_avg(r, 300.0 * truth) + rng.normal(0.0, 1.0, 156))
    design = _design(residuals, runs)
    entry = check_alternatives(design, design.blocks, runs, axes=('X',))
    assert entry is not None and entry['diagnostic'] == 'reversal'
    assert entry['statistic'] == pytest.approx(300.0, rel=0.05)


def test_real_friction_is_not_taken_for_an_alternative():
    rng = np.random.default_rng(5)
    runs = _runs()
    # the truth is 20 N of Coulomb friction: power 20 |v|
    residuals = [_avg(r, 20.0 * np.abs(r[0].velocity_m_s[:, 0])) + rng.normal(0.0, 1.0, 156)
                 for r in runs]
    design = _design(residuals, runs)
    coulomb = [b for b in design.blocks if b.key[0] == 'coulomb']
    assert check_alternatives(design, coulomb, runs, axes=('X',)) is None


def test_nothing_selected_nothing_to_compare():
    runs = _runs()
    design = _design([0.03 * _avg(r, r[0].power_w[:, 0]) for r in runs], runs)
    assert check_alternatives(design, [], runs, axes=('X',)) is None
