"""analyze on a ball-screw test stand's force trace names what the reference fit misses.

One seed of ``bench/truth_stand_analyze.py`` (issue 24, the test-stand class): the truth
stand (asymmetric Coulomb and viscous friction, a Stribeck excess, a constant offset force
acting at rest too; a 1 kHz force from a 5 ms-filtered controller output) is identified with
mass + symmetric Coulomb + viscous (the reference identification), and ``analyze`` runs on
its force trace against that machine. It must name every missing friction term and the
offset force (alone or as its alias group with ``gravity``), nothing else, with the noise
level of a smooth signal (the slow estimate), and the augmented machine must beat the
reference on runs no fit has seen (power RMSE <= 0.95 x, |net energy error| <= 2 %). A clean
stand (the reference fit's own class) must end clean. The figures over seeds and variants
are in docs/analyze.md.
"""
from __future__ import annotations

import math

import pytest

from bench_modules import load_bench

bench = load_bench('truth_stand_analyze')


def test_stand_friction_terms_and_offset_force_are_named(tmp_path):
    truth = bench.VARIANTS['full']
    cell = bench.run_cell('full', 1, tmp_path)
    assert not cell.missed, cell
    assert not cell.false, cell
    assert set(cell.expected) == {'coulomb', 'viscous_asymmetry', 'stribeck', 'offset_force'}
    # a smooth force: the sample-to-sample scatter would read far below the noise
    assert cell.noise.startswith('slow'), cell.noise
    # the figures of the truth, recovered (the catalog's Stribeck shape is Gaussian, the
    # truth's exponential: its size is not compared)
    p = cell.params
    half = 0.5 * (truth.f_pos_n - truth.f_neg_n)
    assert 0.5 * (p['coulomb']['f_pos_n'] - p['coulomb']['f_neg_n']) == pytest.approx(
        half, rel=0.15)
    assert p['viscous_asymmetry']['d_n_s_m'] == pytest.approx(
        0.5 * (truth.c_pos_n_s_m - truth.c_neg_n_s_m), rel=0.15)
    if 'offset_force' in p:
        offset = p['offset_force']['f0_n']
    else:
        # the alias: an incline of the same force on the one moved mass
        offset = p['gravity']['sin_theta'] * truth.mass_kg * 9.80665
    assert offset == pytest.approx(truth.offset_n, rel=0.1)
    assert p['stribeck']['f_s_n'] > 0.0
    # the class's targets on the held-out runs
    assert cell.after_rmse_w <= 0.95 * cell.ref_rmse_w
    assert abs(cell.after_energy_pct) <= 2.0
    assert cell.passed
    assert math.isfinite(cell.ratio)


def test_clean_stand_stays_clean(tmp_path):
    cell = bench.run_cell('clean', 2, tmp_path)
    assert cell.expected == ()
    assert cell.status == 'clean', cell
    assert not cell.false and not cell.params, cell
