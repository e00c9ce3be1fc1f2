"""The instrument alternative of ``analyze`` (core/identify/meteralt.py), by construction."""
import numpy as np
import pytest

from feed_axis_energy.core.identify.meteralt import meter_alternative, meter_columns
from feed_axis_energy.core.identify.selection import Design
from feed_axis_energy.core.measured.align import interval_average


def _runs(n_runs=6):
    """1 kHz declared power of a speed-dependent loss (v^1.35) plus acceleration peaks,
    and the instrument: 50 ms averages stamped at the window's end."""
    out = []
    for r in range(n_runs):
        t = np.arange(0.0, 8.0, 1e-3)
        v = (0.1 + 0.08 * r) * np.clip(np.sin(np.pi * t / 4.0) * 3.0, -1.0, 1.0)
        p = 250.0 * np.abs(v) ** 1.35 + 40.0 * np.gradient(v, t) * v
        stamps = np.arange(0.1, 7.9, 0.05)

        def aligned(cols, t=t, stamps=stamps):
            return interval_average(t, cols, stamps, window_s=0.05)

        out.append((t, p, v, stamps, aligned))
    return out


def _design(residuals, runs):
    design = Design([res.reshape(-1) for res in residuals])
    # viscous-like v^2 and flat Coulomb-like |v| columns: together they imitate a scale
    # of the loss power
    design.add_block(('viscous', 'X'), {}, ['c_n_s_m'],
                     [a(v[:, None] ** 2) for _, _, v, _, a in runs])
    design.add_block(('coulomb', 'X'), {}, ['f_pos_n'],
                     [a(np.abs(v)[:, None]) for _, _, v, _, a in runs])
    return design


def _columns(runs):
    return [meter_columns(t, p[:, None], [0], a) for t, p, _, _, a in runs]


def test_columns_are_the_averaged_power_and_its_derivatives():
    t, p, _, stamps, aligned = _runs(1)[0]
    cols = meter_columns(t, p[:, None], [0], aligned)
    assert cols.shape == (stamps.size, 3)
    np.testing.assert_allclose(cols[:, 0], interval_average(t, p, stamps, window_s=0.05))
    # the average of -P' over a window is minus the change of P across it, over the window
    change = -(np.interp(stamps, t, p) - np.interp(stamps - 0.05, t, p)) / 0.05
    np.testing.assert_allclose(cols[:, 1], change, atol=0.02 * np.abs(change).max())
    # an axis that is not simulated has zero columns
    two = meter_columns(t, p[:, None], [0, None], aligned)
    assert two.shape == (2 * stamps.size, 6)
    assert np.all(two[1::2, :3] == 0.0) and np.all(two[0::2, 3:] == 0.0)
    assert np.all(two[1::2, 3:] == 0.0)


def test_a_gain_of_the_declared_power_is_found_and_its_size_named():
    rng = np.random.default_rng(3)
    runs = _runs()
    # 0.3 W noise: the acceleration peaks' share of the gain (about 0.7 W) stands out
    residuals = [0.03 * a(p[:, None])[:, 0] + rng.normal(0.0, 0.3, s.size)
                 for _, p, _, s, a in runs]
    design = _design(residuals, runs)
    entry = meter_alternative(design, design.blocks, _columns(runs), axes=('X',))
    assert entry is not None and entry['diagnostic'] == 'instrument'
    assert entry['statistic'] == pytest.approx(0.03, abs=0.002)
    assert 'viscous on X, coulomb on X' in entry['message']


def test_a_meter_lag_is_found():
    rng = np.random.default_rng(4)
    runs = _runs()
    residuals = []
    for t, p, _, s, a in runs:
        # a first-order lag of 20 ms on the power before the 50 ms average
        lag = np.empty_like(p)
        acc = p[0]
        alpha = 1.0 - np.exp(-1e-3 / 0.02)
        for i, value in enumerate(p):
            acc += alpha * (value - acc)
            lag[i] = acc
        residuals.append((a(lag[:, None]) - a(p[:, None]))[:, 0] + rng.normal(0.0, 1.0, s.size))
    design = _design(residuals, runs)
    entry = meter_alternative(design, design.blocks, _columns(runs), axes=('X',))
    assert entry is not None
    # the delay of a first-order lag is its time constant
    assert 'delay +2' in entry['message'] or 'delay +1' in entry['message']


def test_a_real_friction_effect_is_not_taken_for_a_meter():
    rng = np.random.default_rng(5)
    runs = _runs()
    # the truth is 20 N of Coulomb friction: power 20 |v|, not a scale of the loss power
    residuals = [a(20.0 * np.abs(v)[:, None])[:, 0] + rng.normal(0.0, 1.0, s.size)
                 for _, _, v, s, a in runs]
    design = _design(residuals, runs)
    coulomb = [b for b in design.blocks if b.key[0] == 'coulomb']
    assert meter_alternative(design, coulomb, _columns(runs), axes=('X',)) is None


def test_nothing_selected_nothing_to_compare():
    runs = _runs()
    design = _design([0.03 * a(p[:, None])[:, 0] for _, p, _, _, a in runs], runs)
    assert meter_alternative(design, [], _columns(runs), axes=('X',)) is None
