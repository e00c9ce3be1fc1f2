"""Standstill samples left out of the rows (dwells): results equal the sampled computation."""
import math
from pathlib import Path
import tracemalloc

import numpy as np
import pytest

from feed_axis_energy.effects.catalog import EFFECTS
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.units import GRAVITY_M_S2
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.plan.stream import concat_motion, iter_motion
from feed_axis_energy.sim.stream import compactable, simulate_stream
from feed_axis_energy.sim.simulate import simulate_program, summarize
from feed_axis_energy.physics.energy import energy_by_line
from feed_axis_energy.plan.standstill import (first_grid_indices, grid_interval_counts,
                                              standstill_runs)

REPO = Path(__file__).resolve().parents[2]

# dwells of several lengths, a dwell at the start and at the end, a stop, and a short move
# with a corner right after a dwell (its velocity step lands next to the dwell's end)
MILL_PROGRAM = """G21 G90 G94 G64
G4 P0.4
G1 X20 Y5 Z-2 F3000
G4 P0.6
G1 X20.2 F3000
G1 X25 Y9
G2 X30 Y4 I0 J-5
G4 P0.0734
G1 Z3 F1200
M0
G1 X0 Y0 Z0 F6000
G4 P1.25
"""
DEMO_PROGRAM = """G21 G90 G61
G1 X200 F18000
G4 P0.5
G1 X0
G4 P0.25
G1 X400 F30000
G4 P0.0321
G1 X0
"""


def _machine(name, *, effects=None, braking=None):
    data = machine_to_dict(load_machine(REPO / 'config' / name))
    if effects is not None:
        data['effects'] = effects
    if braking is not None:
        data['braking'] = braking
    return machine_from_dict(data)


def _close(a, b, scale):
    assert abs(a - b) <= 1e-12 * max(abs(scale), 1e-300), (a, b)


def _same_summary(ref, got, blocks_ref, blocks_got):
    scale = max(abs(ref['energy_j']['total']), 1.0)
    for key in ('samples', 'braking'):
        assert got[key] == ref[key]
    for key in ('duration_s', 'rate_hz', 'regenerated_energy_j', 'loss_energy_j'):
        _close(ref[key], got[key], max(abs(ref[key]), scale if 'energy' in key else 0.0))
    for group in ('energy_j', 'peak_power_w'):
        for axis, value in ref[group].items():
            _close(value, got[group][axis], max(abs(value), 1e-300))
    assert [b[0] for b in blocks_ref] == [b[0] for b in blocks_got]
    for (_, e0, d0), (_, e1, d1) in zip(blocks_ref, blocks_got):
        _close(e0, e1, scale)
        _close(d0, d1, ref['duration_s'])


@pytest.mark.parametrize('rate', [1000.0, 333.0, 1024.0, 977.3])
@pytest.mark.parametrize('i0,n', [(0, 5), (0, 3000), (998, 5), (1020, 70000),
                                  (2_047_000, 3000), (123_456, 1_000_000)])
def test_grid_interval_counts_equal_the_samples(rate, i0, n):
    t = np.arange(i0, i0 + n + 1, dtype=float) / rate
    values, counts = np.unique(np.diff(t), return_counts=True)
    assert grid_interval_counts(i0, i0 + n, rate) == dict(zip(values.tolist(),
                                                              counts.tolist()))


def test_first_grid_indices_is_the_first_sample_at_or_after():
    rate = 1000.0
    t = np.array([0.0, 1e-3, 0.0015, 2.0 / 3.0, 1024.0, 604800.0001])
    i = first_grid_indices(t, rate)
    assert np.all(i / rate >= t)
    assert np.all((i == 0) | ((i - 1) / rate < t))


@pytest.mark.parametrize('chunk', [97, 1000, 65536])
@pytest.mark.parametrize('config,text', [('three_axis_mill.yaml', MILL_PROGRAM),
                                         ('demonstrator.yaml', DEMO_PROGRAM)])
def test_compact_dwells_equal_sampled_and_whole(config, text, chunk):
    machine = _machine(config)
    prog = parse_gcode(text, file='dwell.nc', home=machine.home_point())
    whole = simulate_program(prog, machine, load_kg=7.5)
    ref = summarize(whole, top_blocks=5)
    chunks = []
    got, blocks = simulate_stream(prog.moves, machine, file='dwell.nc', load_kg=7.5,
                                  chunk_samples=chunk, on_chunk=chunks.append,
                                  chunk_gaps=True)
    assert sum(len(c.motion.gaps) for c in chunks) >= 2           # dwells were left out
    assert sum(c.motion.n_samples for c in chunks) < ref['samples']
    _same_summary(ref, got, energy_by_line(whole.power), blocks)
    sampled, blocks_sampled = simulate_stream(prog.moves, machine, file='dwell.nc',
                                              load_kg=7.5, chunk_samples=chunk,
                                              compact=False)
    _same_summary(sampled, got, blocks_sampled, blocks)


def test_gap_between_chunks():
    """A chunk that ends right before a gap: the gap is row 0 of the next chunk."""
    machine = _machine('demonstrator.yaml')
    prog = parse_gcode(DEMO_PROGRAM, file='d.nc')
    first = next(iter_motion(prog.moves, machine.limits(), compact_min_samples=64))
    row = first.gaps[0][0]
    chunks = list(iter_motion(prog.moves, machine.limits(), compact_min_samples=64,
                              chunk_samples=row))
    assert chunks[1].gaps[0][0] == 0
    got, blocks = simulate_stream(prog.moves, machine, file='d.nc', chunk_samples=row)
    whole = simulate_program(prog, machine)
    _same_summary(summarize(whole), got, energy_by_line(whole.power), blocks)


@pytest.mark.parametrize('chunk', [50, 4096])
def test_rows_are_the_plan_without_the_gaps(chunk):
    machine = _machine('three_axis_mill.yaml')
    prog = parse_gcode(MILL_PROGRAM, file='m.nc', home=machine.home_point())
    ref = simulate_program(prog, machine).motion
    got = concat_motion(iter_motion(prog.moves, machine.limits(),
                                    options=machine.planner.options(), chunk_samples=chunk,
                                    compact_min_samples=10))
    keep = np.ones(ref.n_samples, bool)
    for row, first, count in got.gaps:
        keep[first:first + count] = False
        # every omitted sample equals the row after the gap, except its time
        lo, hi = first - 1, first + count + 1
        np.testing.assert_array_equal(ref.pos[lo:hi], np.repeat(got.pos[row:row + 1],
                                                                hi - lo, axis=0))
        assert np.all(ref.vel[lo:hi] == 0.0) and np.all(ref.acc[lo:hi] == 0.0)
        assert np.all(ref.line[first:hi] == got.line[row])
    assert got.n_samples == int(keep.sum()) and got.omitted_samples == int((~keep).sum())
    np.testing.assert_array_equal(got.t, ref.t[keep])
    np.testing.assert_array_equal(got.line, ref.line[keep])
    for name in ('pos', 'vel', 'acc'):
        a, b = getattr(ref, name)[keep], getattr(got, name)
        assert float(np.max(np.abs(a - b))) <= 1e-12 * max(float(np.max(np.abs(a))), 1e-300)


def test_expanded_chunks_equal_sampled_chunks():
    machine = _machine('three_axis_mill.yaml', braking='regenerative')
    prog = parse_gcode(MILL_PROGRAM, file='m.nc', home=machine.home_point())
    full, sampled = [], []
    simulate_stream(prog.moves, machine, chunk_samples=300, on_chunk=full.append)
    simulate_stream(prog.moves, machine, chunk_samples=300, on_chunk=sampled.append,
                    compact=False)
    assert all(not c.motion.gaps and c.power.t.shape[0] <= 300 for c in full)
    for get in (lambda c: c.power.t, lambda c: c.motion.pos, lambda c: c.dynamics.torque_nm,
                lambda c: c.power.power_w, lambda c: c.power.energy_j,
                lambda c: c.power.total_energy_j, lambda c: c.motion.line):
        a = np.concatenate([get(c) for c in sampled])
        b = np.concatenate([get(c) for c in full])
        assert a.shape == b.shape
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * max(np.max(np.abs(a)), 1.0))


def _holding_machine():
    """The 3-axis mill with a standby power on every axis and copper losses on Z, which
    holds its weight at rest: the power at standstill is not zero."""
    return _machine('three_axis_mill.yaml', effects=[
        {'id': 'standby', 'params': {'p0_w': 15.0}},
        {'id': 'copper', 'axis': 'Z', 'params': {'k_w_nm2': 2.0}}])


def _holding_power_w(machine):
    """Power at rest by hand: 15 W per axis, plus k M^2 on Z with M = m g lead / (2 pi eta)
    (the vertical Z holds its own weight; the drive 'drives' it, F v = 0 >= 0)."""
    z = machine.axis('Z')
    torque = 150.0 * GRAVITY_M_S2 * z.screw.lead_m / (2.0 * math.pi * z.screw.efficiency)
    return 3 * 15.0 + 2.0 * torque ** 2


def test_dwell_power_by_hand():
    machine = _holding_machine()
    assert compactable(machine)
    prog = parse_gcode('G4 P10\n', file='rest.nc')
    got, blocks = simulate_stream(prog.moves, machine, file='rest.nc')
    p = _holding_power_w(machine)
    assert got['samples'] == 10001 and got['duration_s'] == pytest.approx(10.0, rel=1e-15)
    assert got['energy_j']['total'] == pytest.approx(10.0 * p, rel=1e-12)
    assert got['peak_power_w']['total'] == pytest.approx(p, rel=1e-12)
    assert [b[0] for b in blocks] == [1]


def test_week_long_dwell_costs_no_memory_per_sample():
    machine = _holding_machine()
    prog = parse_gcode('G4 P604800\n', file='week.nc')
    tracemalloc.start()
    try:
        got, _ = simulate_stream(prog.moves, machine, file='week.nc', chunk_samples=4096)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert got['samples'] == 604_800_001
    assert got['energy_j']['total'] == pytest.approx(604800.0 * _holding_power_w(machine),
                                                     rel=1e-12)
    assert got['rate_hz'] == pytest.approx(1000.0, rel=1e-6)
    assert peak < 8 << 20             # one chunk of 4096 rows, not 605 million samples


def test_effects_that_change_at_rest_keep_every_sample(monkeypatch):
    drift = _machine('three_axis_mill.yaml',
                     effects=[{'id': 'thermal_drift', 'params': {'rate_n_s': 0.1}}])
    assert compactable(drift)                  # grows with t, but is zero at rest
    monkeypatch.setattr(EFFECTS['thermal_drift'], 'constant_at_rest', False)
    assert not compactable(drift)
    prog = parse_gcode(DEMO_PROGRAM.replace('G61', 'G61 G17'), file='d.nc')
    chunks = []
    simulate_stream(prog.moves, _machine('three_axis_mill.yaml', effects=[
        {'id': 'thermal_drift', 'params': {'rate_n_s': 0.1}}]), on_chunk=chunks.append,
        chunk_gaps=True)
    assert not any(c.motion.gaps for c in chunks)


def test_runs_leave_the_ends_of_a_phase_sampled():
    # one rest phase from 0.1 s to 0.6 s at 100 Hz: samples 10 .. 59 are its own
    t0 = np.array([0.0, 0.1, 0.6])
    z = np.zeros(3)
    phases = (t0, np.array([0.1, 0.5, 0.2]), z, np.array([0.1, 0.0, 0.0]), z,
              np.array([1.0, 0.0, 2.0]), np.arange(3))
    assert standstill_runs(phases, rate_hz=100.0, lo=0, hi=80, min_samples=5) == [(12, 58, 1)]
    assert standstill_runs(phases, rate_hz=100.0, lo=0, hi=30, min_samples=5) == [(12, 30, 1)]
    assert standstill_runs(phases, rate_hz=100.0, lo=0, hi=80, min_samples=47) == []
