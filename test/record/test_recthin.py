"""What a recording holds during a standstill: first, last and one sample per second.

Checked against the full-rate recording of the same simulation: the thinned bag is a subset
of its samples with equal values, every left-out sample lies inside a standstill and is
recovered by linear interpolation, the result does not depend on the chunking, a dwell by
hand keeps exactly the samples the rule names, and chunks whose dwell interiors were left
out by the simulation (``Motion.gaps``) give the same bag as the full-rate chunks.
"""
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from feed_axis_energy.record import bagio
from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.plan.stream import iter_motion
from feed_axis_energy.record.recording import SimulationBagWriter
from feed_axis_energy.record.thinning import StandstillThinner
from feed_axis_energy.sim.stream import iter_simulation

REPO = Path(__file__).resolve().parents[2]
RATE = 1000.0
TOPICS = (bagio.TOPIC_SETPOINTS, bagio.TOPIC_AXIS_STATE, bagio.TOPIC_POWER)
PROGRAM = 'G21 G90 G61\nG4 P0.3\nG1 X50 F3000\nG4 P2.5\nG1 X0\nG4 P1\nG1 X20\nG4 P0.0005\nX0\nM2\n'


def _chunks(text: str = PROGRAM, chunk_samples: int = 65536):
    machine = load_machine(REPO / 'config' / 'demonstrator.yaml')
    prog = parse_gcode(text, file='dwell.nc')
    motions = iter_motion(prog.moves, machine.limits(), options=machine.planner.options(),
                          file='dwell.nc', chunk_samples=chunk_samples)
    return list(iter_simulation(motions, machine))


def _bag(path: Path, chunks, **kwargs) -> dict:
    with SimulationBagWriter(path, rate_hz=RATE, **kwargs) as writer:
        for chunk in chunks:
            writer.write(chunk)
        writer.finish([], summary={}, stamp_s=float(chunks[-1].power.t[-1]))
    return {topic: bagio.read_series(path, topic) for topic in TOPICS}


def _fields(series):
    return [f for f in ('positions', 'velocities', 'accelerations', 'effort')
            if getattr(series, f) is not None]


def test_thinned_bag_is_the_full_one_at_fewer_samples(tmp_path):
    full = _bag(tmp_path / 'full', _chunks(), standstill_period_s=None)
    thin = _bag(tmp_path / 'thin', _chunks(chunk_samples=777))
    t_full, t_thin = full[bagio.TOPIC_POWER].t, thin[bagio.TOPIC_POWER].t
    assert t_thin.shape[0] < 0.6 * t_full.shape[0]          # 4.3 s of 6.8 s are dwells
    at = np.searchsorted(t_full, t_thin)
    np.testing.assert_array_equal(t_full[at], t_thin)       # a subset of the samples
    for topic in TOPICS:
        for field in _fields(full[topic]):
            a, b = getattr(full[topic], field), getattr(thin[topic], field)
            np.testing.assert_array_equal(a[at], b)         # with the same values
            # linear interpolation between kept samples gives every left-out one
            for col in range(a.shape[1]):
                back = np.interp(t_full, t_thin, b[:, col])
                np.testing.assert_allclose(back, a[:, col], rtol=1e-9,
                                           atol=1e-9 * max(1.0, np.abs(a[:, col]).max()))
    # a sample is left out only if it equals its neighbours (energy aside)
    dropped = np.setdiff1d(np.arange(t_full.shape[0]), at)
    vel = full[bagio.TOPIC_SETPOINTS].velocities
    assert np.all(vel[dropped] == 0.0)
    # the kept samples of a standstill are at most one second (plus one sample) apart
    assert np.diff(t_thin).max() <= 1.0 + 1.5 / RATE


@pytest.mark.parametrize('chunk_samples', [2, 99, 1000, 2500])
def test_independent_of_the_chunking(tmp_path, chunk_samples):
    ref = _bag(tmp_path / 'ref', _chunks())
    got = _bag(tmp_path / 'got', _chunks(chunk_samples=chunk_samples))
    for topic in TOPICS:
        np.testing.assert_array_equal(got[topic].t, ref[topic].t)
        for field in _fields(ref[topic]):
            np.testing.assert_array_equal(getattr(got[topic], field),
                                          getattr(ref[topic], field))


def test_a_dwell_by_hand(tmp_path):
    # G4 P2.5 between two moves that end and start at rest: the run is the dwell's 2 501
    # samples at X50 (first: the move's last sample, at rest). Kept: the first, those 1 s and
    # 2 s later, and the last: 4 samples, then the next move at the full rate.
    thin = _bag(tmp_path / 'b', _chunks('G21 G90 G61\nG1 X50 F3000\nG4 P2.5\nG1 X0\nM2\n'))
    s = thin[bagio.TOPIC_SETPOINTS]
    at_rest = np.flatnonzero((s.positions[:, 0] == 0.05) & (s.velocities[:, 0] == 0.0))
    times = s.t[at_rest]
    assert times.shape[0] == 4
    np.testing.assert_allclose(np.diff(times)[:2], [1.0, 1.0], atol=1.5e-9)
    assert abs(times[-1] - times[0] - 2.5) <= 1.5 / RATE       # the dwell, to a sample
    # the samples around the run are at the full rate
    i = at_rest[-1]
    np.testing.assert_allclose(np.diff(s.t[i - 10:i - 3]), 1.0 / RATE, atol=1e-9)
    np.testing.assert_allclose(np.diff(s.t[i:i + 10]), 1.0 / RATE, atol=1e-9)


def _with_gaps(chunks, *, keep_ends: int = 2, min_run: int = 64, pieces: int = 3):
    """The simulation's compact form: interiors of standstill runs left out as gaps."""
    cat = {}
    first = chunks[0]
    for name in ('motion', 'dynamics', 'power'):
        obj = getattr(first, name)
        per_sample = [f for f, v in vars(obj).items()
                      if isinstance(v, np.ndarray) and v.shape[:1] == obj.t.shape]
        cat[name] = {f: np.concatenate([getattr(getattr(c, name), f) for c in chunks])
                     for f in per_sample}
    vel = cat['motion']['vel'][:, 0]
    pos = cat['motion']['pos'][:, 0]
    n = vel.shape[0]
    rest = (vel == 0.0) & np.concatenate(([False], pos[1:] == pos[:-1]))
    keep = np.ones(n, bool)
    gaps_at = {}
    i = 0
    while i < n:
        if not rest[i]:
            i += 1
            continue
        j = i
        while j < n and rest[j]:
            j += 1
        if j - i >= min_run:
            lo, hi = i + keep_ends, j - keep_ends
            keep[lo:hi] = False
            gaps_at[hi] = (int(round(cat['motion']['t'][lo] * RATE)), hi - lo)
        i = j
    rows = np.flatnonzero(keep)
    new_row = {int(r): k for k, r in enumerate(rows)}
    gaps = [(new_row[r], f, c) for r, (f, c) in gaps_at.items()]
    bounds = np.linspace(0, rows.shape[0], pieces + 1).astype(int)
    out = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        sel = rows[a:b]
        parts = {name: {f: v[sel] for f, v in cat[name].items()} for name in cat}
        motion = SimpleNamespace(**parts['motion'], axes=first.motion.axes,
                                 gaps=tuple((r - a, f, c) for r, f, c in gaps if a <= r < b))
        out.append(replace(first, motion=motion,
                           dynamics=replace(first.dynamics, **parts['dynamics']),
                           power=replace(first.power, **parts['power'])))
    assert sum(len(c.motion.gaps) for c in out) >= 3
    return out


def test_chunks_with_left_out_samples_give_the_same_bag(tmp_path):
    chunks = _chunks()
    ref = _bag(tmp_path / 'ref', chunks)
    got = _bag(tmp_path / 'got', _with_gaps(chunks))
    for topic in TOPICS:
        np.testing.assert_allclose(got[topic].t, ref[topic].t, rtol=0, atol=1e-9)
        for field in _fields(ref[topic]):
            a, b = getattr(ref[topic], field), getattr(got[topic], field)
            np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())


def test_selection_rules_directly():
    th = StandstillThinner(period_s=1.0, rate_hz=10.0)
    t = np.arange(40) / 10.0
    still = np.zeros(40, bool)
    still[6:31] = True          # rows 5..30 at rest: run starts at row 5 (t = 0.5 s)
    sel = th.select(t, still)
    kept = sel.src.tolist()
    assert kept == list(range(6)) + [15, 25, 30] + list(range(31, 40))
    assert not sel.hold_last and not sel.filled.any()
    # a run reaching the chunk's end: the last row waits for the next chunk
    th = StandstillThinner(period_s=1.0, rate_hz=10.0)
    still = np.zeros(20, bool)
    still[12:] = True
    sel = th.select(t[:20], still)
    assert sel.hold_last and sel.src.tolist() == list(range(12))
    sel = th.select(t[20:25], np.array([False, False, False, False, False]))
    assert sel.src.tolist() == [-1, 0, 1, 2, 3, 4]      # the run ended: its last row kept
    with pytest.raises(ValueError, match='differs'):
        StandstillThinner(rate_hz=10.0).select(t[:5], np.zeros(5, bool), gaps=((2, 0, 3),))


def test_the_simulations_own_gaps_give_the_full_rate_bag(tmp_path):
    """simulate_stream(chunk_gaps=True) hands the writer chunks whose dwell interiors were
    never computed (Motion.gaps, what simulate --out does): the bag equals the one written
    from full-rate chunks."""
    from feed_axis_energy.sim.stream import simulate_stream
    machine = load_machine(REPO / 'config' / 'demonstrator.yaml')
    bags = {}
    for gaps in (False, True):
        path = tmp_path / f'gaps_{gaps}'
        seen = []
        with SimulationBagWriter(path, rate_hz=RATE) as writer:
            def write(chunk, seen=seen, writer=writer):
                seen.append(len(getattr(chunk.motion, 'gaps', ())))
                writer.write(chunk)
            summary, blocks = simulate_stream(parse_gcode(PROGRAM, file='dwell.nc').moves,
                                              machine, file='dwell.nc', on_chunk=write,
                                              chunk_gaps=gaps, chunk_samples=1000)
            writer.finish(blocks, summary=summary, stamp_s=summary['duration_s'])
        assert (sum(seen) > 0) == gaps
        bags[gaps] = {topic: bagio.read_series(path, topic) for topic in TOPICS}
    for topic in TOPICS:
        ref, got = bags[False][topic], bags[True][topic]
        np.testing.assert_allclose(got.t, ref.t, rtol=0, atol=1e-9)
        for field in _fields(ref):
            a, b = getattr(ref, field), getattr(got, field)
            np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())
