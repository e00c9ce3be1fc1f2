"""Streaming simulation: summary and per-block energy equal the whole-program result."""
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.record.bagio import read_block_energy, read_series, TOPIC_POWER
from feed_axis_energy.physics.energy import energy_by_line
from feed_axis_energy.gcode.load import load_gcode
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.record.recording import SimulationBagWriter
from feed_axis_energy.sim.stream import simulate_stream
from feed_axis_energy.sim.simulate import simulate_program, summarize

REPO = Path(__file__).resolve().parents[2]
CASES = [('demonstrator.yaml', 'demonstrator_f300.nc'),
         ('three_axis_mill.yaml', 'three_axis_contour.nc')]


def _close(a, b, *, scale):
    assert abs(a - b) <= 1e-12 * scale, (a, b)


def _compare(ref, got, blocks_ref, blocks_got):
    scale = max(abs(ref['energy_j']['total']), 1.0)
    for key in ('program', 'machine', 'load_kg', 'samples', 'braking'):
        assert got[key] == ref[key]
    for key in ('duration_s', 'rate_hz', 'regenerated_energy_j', 'loss_energy_j'):
        _close(ref[key], got[key], scale=max(abs(ref[key]), 1e-300))
    for group in ('energy_j', 'peak_power_w'):
        assert set(ref[group]) == set(got[group])
        for axis, value in ref[group].items():
            _close(value, got[group][axis], scale=max(abs(value), 1e-300))
    assert [b[0] for b in blocks_ref] == [b[0] for b in blocks_got]
    for (_, e0, d0), (_, e1, d1) in zip(blocks_ref, blocks_got):
        _close(e0, e1, scale=scale)
        _close(d0, d1, scale=ref['duration_s'])
    # ties between equal strokes may order differently; the energies listed may not
    top_ref = sorted(b['energy_j'] for b in ref['top_blocks'])
    top_got = sorted(b['energy_j'] for b in got['top_blocks'])
    np.testing.assert_allclose(top_got, top_ref, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize('braking', ['regenerative', 'dissipated'])
@pytest.mark.parametrize('config,program', CASES)
def test_stream_equals_whole_summary(config, program, braking):
    data = machine_to_dict(load_machine(REPO / 'config' / config))
    data['braking'] = braking
    machine = machine_from_dict(data)
    prog = load_gcode(REPO / 'config' / 'programs' / program, home=machine.home_point())
    whole = simulate_program(prog, machine, load_kg=12.5)
    ref = summarize(whole, top_blocks=5)
    chunks = []
    got, blocks = simulate_stream(prog.moves, machine, file=prog.file, load_kg=12.5,
                                  chunk_samples=999, on_chunk=chunks.append)
    assert len(chunks) > 5 and max(c.motion.n_samples for c in chunks) <= 999
    _compare(ref, got, energy_by_line(whole.power), blocks)
    # the chunks' cumulative energy continues across chunk boundaries
    e = np.concatenate([c.power.total_energy_j for c in chunks])
    np.testing.assert_allclose(e, whole.power.total_energy_j, rtol=0,
                               atol=1e-12 * max(abs(ref['energy_j']['total']), 1.0))


def test_bag_written_chunk_by_chunk(tmp_path):
    machine = load_machine(REPO / 'config' / 'three_axis_mill.yaml')
    prog = load_gcode(REPO / 'config' / 'programs' / 'three_axis_contour.nc',
                      home=machine.home_point())
    whole = simulate_program(prog, machine)
    out = tmp_path / 'bag'
    with SimulationBagWriter(out, batch=100) as writer:
        summary, blocks = simulate_stream(prog.moves, machine, file=prog.file,
                                          chunk_samples=1234, on_chunk=writer.write)
        writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
    power = read_series(out, TOPIC_POWER)
    assert power.t.shape == whole.power.t.shape
    np.testing.assert_allclose(power.velocities[:, -1], whole.power.total_w, rtol=1e-12,
                               atol=1e-9)
    assert [b[0] for b in read_block_energy(out)] == [b[0] for b in blocks]


def test_compressed_bag_reads_back_the_same(tmp_path):
    machine = load_machine(REPO / 'config' / 'demonstrator.yaml')
    prog = load_gcode(REPO / 'config' / 'programs' / 'demonstrator_f300.nc')
    series = {}
    sizes = {}
    for compression in ('none', 'zstd'):
        out = tmp_path / compression
        with SimulationBagWriter(out, compression=compression) as writer:
            summary, blocks = simulate_stream(prog.moves, machine, file=prog.file,
                                              on_chunk=writer.write)
            writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
        series[compression] = read_series(out, TOPIC_POWER)
        sizes[compression] = sum(f.stat().st_size for f in out.rglob('*.mcap'))
    np.testing.assert_array_equal(series['zstd'].t, series['none'].t)
    np.testing.assert_array_equal(series['zstd'].velocities, series['none'].velocities)
    assert sizes['zstd'] < sizes['none'] / 2


def test_lines_repeating_in_separate_runs():
    from feed_axis_energy.gcode.program import Move, MoveKind, Program
    machine = load_machine(REPO / 'config' / 'demonstrator.yaml')
    pts = [0.0, 0.1, 0.02, 0.15, 0.0, 0.05]
    moves = tuple(Move(MoveKind.LINEAR, 1 + i % 2, (a, 0.0, 0.0), (b, 0.0, 0.0),
                       feed_m_s=0.2) for i, (a, b) in enumerate(zip(pts[:-1], pts[1:])))
    prog = Program('rep.nc', moves)
    whole = simulate_program(prog, machine)
    got, blocks = simulate_stream(prog.moves, machine, file='rep.nc', chunk_samples=4096)
    ref = energy_by_line(whole.power)
    assert [b[0] for b in blocks] == [b[0] for b in ref] == [1, 2]
    for (_, e0, d0), (_, e1, d1) in zip(ref, blocks):
        assert e1 == pytest.approx(e0, rel=1e-12) and d1 == pytest.approx(d0, rel=1e-12)
