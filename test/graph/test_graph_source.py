"""graph/source: the node graph's setpoints streamed from the planner equal the whole plan."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.gcode.load import iter_moves, load_gcode
from feed_axis_energy.graph.flow import batch_bounds, block_starts, seconds_to_ns
from feed_axis_energy.graph.source import SetpointSource
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.plan.stream import iter_motion
from feed_axis_energy.plan.trajectory import plan

ROOT = Path(__file__).resolve().parents[2]
MILL = ROOT / 'config' / 'three_axis_mill.yaml'
CONTOUR = ROOT / 'config' / 'programs' / 'three_axis_contour.nc'


def _source(path: Path, *, batch: int, chunk_samples: int) -> tuple:
    machine = load_machine(MILL)
    options, limits, kw = machine.planner.options(), machine.limits(), machine.gcode_keywords()
    opened = []

    def open_motion():
        opened.append(1)
        return iter_motion(iter_moves(path, **kw), limits, options=options, file=str(path),
                           chunk_samples=chunk_samples)
    whole = plan(load_gcode(path, **kw), limits, options=options)
    return SetpointSource(open_motion, batch=batch), whole, opened


@pytest.mark.parametrize('batch, chunk', [(100, 4096), (7, 37), (1000, 2)])
def test_batches_are_the_whole_plan_cut_at_multiples_of_batch(batch, chunk):
    source, whole, opened = _source(CONTOUR, batch=batch, chunk_samples=chunk)
    t_ns = seconds_to_ns(whole.t)
    bounds = batch_bounds(whole.n_samples, batch)
    got = list(source.batches())
    assert len(got) == len(bounds)
    for b, (i0, i1) in zip(got, bounds):
        np.testing.assert_array_equal(b.t_ns, t_ns[i0:i1])
        np.testing.assert_allclose(b.pos, whole.pos[i0:i1], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(b.vel, whole.vel[i0:i1], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(b.acc, whole.acc[i0:i1], rtol=1e-9, atol=1e-9)
    assert [b.index for b in got] == list(range(len(bounds)))
    assert opened == [1]


@pytest.mark.parametrize('batch, chunk', [(100, 4096), (7, 37)])
def test_survey_knows_what_streaming_needs_first(batch, chunk):
    source, whole, _ = _source(CONTOUR, batch=batch, chunk_samples=chunk)
    sv = source.survey()
    t_ns = seconds_to_ns(whole.t)
    bounds = batch_bounds(whole.n_samples, batch)
    assert sv.axes == tuple(whole.axes)
    assert (sv.n_samples, sv.n_batches) == (whole.n_samples, len(bounds))
    assert sv.duration_s == pytest.approx(whole.duration_s, rel=1e-12)
    assert sv.first_ns == t_ns[0] and sv.last_batch_ns == t_ns[bounds[-1][0]]
    starts, lines = block_starts(t_ns, whole.line)
    # Chunk boundaries inside a block do not split its run.
    np.testing.assert_array_equal(sv.starts_ns, starts)
    np.testing.assert_array_equal(sv.lines, lines)
    assert len(sv.lines) < sv.n_samples / 10     # one entry per block, not per sample


def test_a_program_without_motion_has_no_batches(tmp_path):
    path = tmp_path / 'idle.nc'
    path.write_text('G21\n(nothing)\nM2\n')
    source, _, _ = _source(path, batch=10, chunk_samples=64)
    sv = source.survey()
    assert sv.n_samples <= 1 and sv.n_batches == sv.n_samples
    assert len(list(source.batches())) == sv.n_batches


def test_batch_must_be_positive():
    with pytest.raises(ValueError, match='batch must be >= 1'):
        SetpointSource(lambda: iter(()), batch=0)
