"""The joint offset screen: a run's offset with a candidate effect in the model."""
import numpy as np
import pytest

from feed_axis_energy.identify.timing import joint_screen, ScreenCandidate, ScreenRun, screen_span
from feed_axis_energy.measured import align_simulated, estimate_offset

RATE = 1000.0


def _strokes(t):
    """Reciprocating strokes: 0.1 s ramps, 0.6 s cruise at 0.3 m/s, 0.2 s rests."""
    phase = np.mod(t, 2.0)
    half = np.mod(phase, 1.0)
    shape = np.clip(np.minimum(half / 0.1, (0.8 - half) / 0.1), 0.0, 1.0)
    v = 0.3 * shape * np.where(phase < 1.0, 1.0, -1.0)
    # a 21 ms moving average: finite jerk
    k = np.ones(21) / 21.0
    v = np.convolve(v, k, mode='same')
    a = np.gradient(v, t)
    return v, a


@pytest.fixture(scope='module')
def record():
    t_sim = np.arange(0.0, 20.0, 1.0 / RATE)
    v, a = _strokes(t_sim)
    declared = 40.0 + 300.0 * np.abs(v) + 50.0 * a * v        # friction, declared inertia
    inertia = (a * v)[:, None]                                # missing mass, per kg [W/kg]
    speed = np.abs(v)[:, None]
    true_offset = 0.3
    t = np.arange(-1.0, 19.0, 1.0 / RATE) + 1e-4
    truth = declared + 400.0 * inertia[:, 0]
    rng = np.random.default_rng(3)
    y = (align_simulated(t_sim, truth, t, offset_s=true_offset, window_s=1.0 / RATE)
         + rng.normal(0.0, 0.5, t.size))
    return t_sim, declared, {'inertia': inertia, 'speed': speed}, t, y, true_offset


def test_a_missing_inertia_pulls_the_power_lag_and_the_screen_undoes_it(record):
    t_sim, declared, bases, t, y, true_offset = record
    est = estimate_offset(t, y, t_sim, declared, max_lag_s=2.0, window_s=1.0 / RATE)
    # the declared model alone: the lag is pulled (the failure the screen exists for)
    assert abs(est.offset_s - true_offset) > 0.01, est.message
    run = ScreenRun('r', t, y, t_sim, declared, est.offset_s, 1.0 / RATE, 'end')
    cands = [ScreenCandidate(('speed', 'X'), {}), ScreenCandidate(('inertia', 'X'), {})]
    fits = joint_screen([(run, [bases['speed'], bases['inertia']])], cands)
    best = fits[0]
    assert best.key == ('inertia', 'X')
    assert abs(best.offsets_s[0] - true_offset) < 5e-4, best
    assert best.moves_s[0] == pytest.approx(best.offsets_s[0] - est.offset_s)
    assert best.gain > 0.9 and best.sse_joint < fits[1].sse_joint
    # the other candidate does not carry the run to the truth
    assert abs(fits[1].offsets_s[0] - true_offset) > 0.005


def test_a_run_at_its_offset_does_not_move_and_the_range_end_is_no_offset(record):
    t_sim, declared, bases, t, y, true_offset = record
    # the truth's own model at its offset: the candidate it has is fitted where the run is
    truth = declared + 400.0 * bases['inertia'][:, 0]
    run = ScreenRun('r', t, y, t_sim, truth, true_offset, 1.0 / RATE, 'end')
    (fit,) = joint_screen([(run, [bases['inertia']])],
                          [ScreenCandidate(('inertia', 'X'), {})])
    assert abs(fit.moves_s[0]) < 5e-4 and fit.gain < 0.01, fit
    # a run 0.5 s off, beyond the searched reach: its best lag is at the end of the range,
    # which is no offset found: it stays where it is
    far = ScreenRun('r', t, y, t_sim, declared, true_offset + 0.5, 1.0 / RATE, 'end')
    (fit,) = joint_screen([(far, [bases['inertia']])],
                          [ScreenCandidate(('inertia', 'X'), {})], reach_s=0.1)
    assert fit.moves_s[0] == 0.0 and fit.sse_joint == fit.sse_today


def test_screen_span_covers_the_lags_searched():
    t = np.arange(0.0, 600.0, 0.001)
    n, lo, hi = screen_span(t, 2.0, 0.001, reach_s=0.15)
    assert t[n - 1] <= 120.0 < t[min(n, t.size - 1)]
    assert lo <= t[0] - 2.0 - 0.15 and hi >= t[n - 1] - 2.0 + 0.15
