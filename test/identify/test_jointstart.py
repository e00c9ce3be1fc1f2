"""What the joint start's screen reads of each run (identify/timing/jointstart.py): the
simulation up to the screened stretch, taken chunk by chunk, is the whole run's, cropped."""
from dataclasses import replace
import functools
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.effects import get_effect
from feed_axis_energy.identify.rig import Instrument, make_campaign, RigConfig
from feed_axis_energy.identify.timing import jointalign, jointstart, ScreenCandidate
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured import (compare_campaign, first_order_lag, load_campaign,
                                       load_run, MotionCache, predicted_signal,
                                       simulate_declared)
from feed_axis_energy.physics import state_from_simulation

ROOT = Path(__file__).resolve().parents[2]
CANDIDATES = [ScreenCandidate(('mass_error', 'X'), {}), ScreenCandidate(('coulomb', 'X'), {}),
              ScreenCandidate(('stribeck', 'X'), {'v_s_m_s': 0.01, 'delta': 2.0})]


@pytest.fixture(scope='module')
def rig(tmp_path_factory):
    cfg = RigConfig(machine=ROOT / 'config' / 'demonstrator.yaml', loads_kg=(0.0, 22.711),
                    feeds_mm_s=(150.0, 450.0), cycles=3, instrument=Instrument(noise_w=1.0),
                    seed=3)
    campaign = load_campaign(make_campaign(tmp_path_factory.mktemp('joint') / 'rig', cfg))
    machine = load_machine(campaign.machine)
    loaded = {spec.name: load_run(spec) for spec in campaign.runs}
    return campaign, machine, loaded, compare_campaign(campaign, machine=machine, loaded=loaded)


def _whole_run_items(campaign, machine, runs, loaded):
    """The screen's input the way it was computed before: the whole run simulated at once."""
    cache = MotionCache(machine)
    for r in runs:
        spec = campaign.run(r.name)
        sim, _ = simulate_declared(spec, loaded[r.name], machine, cache)
        total = predicted_signal(spec.instrument.measures, sim, machine, r.axes).sum(axis=1)
        state = state_from_simulation(sim)
        n, lo, hi = jointalign.screen_span(r.t, r.offset_used_s, r.window_s)
        a = max(int(np.searchsorted(state.t, lo, side='right')) - 1, 0)
        b = min(int(np.searchsorted(state.t, hi, side='left')) + 1, state.t.size)
        bases = []
        for c in CANDIDATES:
            basis = get_effect(c.key[0]).basis(state, dict(c.shape))[:, 0, :]
            bases.append((first_order_lag(state.t, basis, r.filter_s) if r.filter_s
                          else basis)[a:b])
        y = (first_order_lag(state.t, total, r.filter_s) if r.filter_s else total)[a:b]
        yield state.t[a:b], y, bases


@pytest.mark.parametrize('filter_s', [0.0, 0.02])
def test_the_screened_stretch_in_chunks_equals_the_whole_run_cropped(rig, monkeypatch,
                                                                     filter_s):
    campaign, machine, loaded, cmp = rig
    runs = [replace(r, filter_s=filter_s) for r in cmp.runs[:3]]
    # a short screened stretch and chunks of 400 samples: the later chunks are let go
    monkeypatch.setattr(jointalign, 'MAX_SCREEN_SPAN_S', 3.0)
    kept = []
    real = jointstart.simulate_declared_chunks

    def chunks(spec, run, machine, cache, on_chunk):
        def counted(sim):
            before = len(kept)
            on_chunk(sim)
            kept.append(before)
        return real(spec, run, machine, cache, counted, chunk_samples=400)

    monkeypatch.setattr(jointstart, 'simulate_declared_chunks', chunks)
    got = list(jointstart._screen_items(campaign, machine, runs, CANDIDATES, loaded))
    want = list(_whole_run_items(campaign, machine, runs, loaded))
    assert len(got) == len(want) == 3 and len(kept) > 30
    for (run, bases), (t_sim, y_sim, whole_bases) in zip(got, want):
        assert run.t_sim.size > 1000
        np.testing.assert_array_equal(run.t_sim, t_sim)
        np.testing.assert_array_equal(run.y_sim, y_sim)
        for x, y in zip(bases, whole_bases):
            np.testing.assert_array_equal(x, y)


def test_a_long_run_keeps_no_more_than_the_screen_sees(rig, monkeypatch):
    campaign, machine, loaded, cmp = rig
    monkeypatch.setattr(jointalign, 'MAX_SCREEN_SPAN_S', 3.0)
    seen = []
    real_state = jointstart.state_from_simulation
    monkeypatch.setattr(jointstart, 'state_from_simulation',
                        lambda sim: seen.append(sim.power.t[-1]) or real_state(sim))
    monkeypatch.setattr(jointstart, 'simulate_declared_chunks',
                        functools.partial(jointstart.simulate_declared_chunks,
                                          chunk_samples=400))
    r = cmp.runs[0]
    list(jointstart._screen_items(campaign, machine, [r], CANDIDATES, loaded))
    _, _, hi = jointalign.screen_span(r.t, r.offset_used_s, r.window_s)
    duration = float(r.sim_duration_s)
    assert duration > hi + 2.0
    # pieces kept up to the first one that passes what the screen can see, none after it
    assert seen[-1] > hi and seen[-2] <= hi
