"""Lag estimates off the delivering thread: rows are taken while an estimate runs, same result."""
import threading

import numpy as np
import pytest

from feed_axis_energy.measured import interval_average
from feed_axis_energy.measured.live import (estimate_lag, InlineLag, LagOutcome, LagRequest,
                                            LiveComparison, LiveSettings, ThreadedLag)

from test_live_compare import pulses, run


class Gate:
    """An estimator that waits for ``release`` before each estimate (counts its calls)."""

    def __init__(self):
        self.started = threading.Event()
        self.release = threading.Event()
        self.seqs = []
        self.threads = set()

    def __call__(self, request: LagRequest) -> LagOutcome:
        self.seqs.append(request.seq)
        self.threads.add(threading.get_ident())
        self.started.set()
        assert self.release.wait(timeout=30.0), 'the test never released the estimator'
        return estimate_lag(request)


def streams(lag_s=0.42, seconds=60.0, seed=11):
    t_pred = np.arange(0.0, seconds, 0.001)
    y_pred = pulses(t_pred, seed=seed)
    t_meas = np.arange(1.0, seconds - 1.0, 0.1)
    y_meas = 1.05 * interval_average(t_pred, y_pred, t_meas - lag_s, window_s=0.0)
    return t_pred, y_pred, t_meas, y_meas


def test_rows_are_delivered_while_an_estimate_blocks():
    t_pred, y_pred, t_meas, y_meas = streams()
    gate = Gate()
    runner = ThreadedLag(gate)
    core = LiveComparison(('X', 'Y'), LiveSettings(max_lag_s=2.0), lag_runner=runner)
    core.add_prediction(t_pred, y_pred)     # the whole prediction ahead of the rows
    i = 0
    while not runner.submitted:
        core.add_measured(float(t_meas[i]), y_meas[i])
        i += 1
    assert gate.started.wait(timeout=30.0)
    # the first estimate is running and cannot finish: rows still go in, one per call
    first_blocked = i
    for j in range(i, i + 200):
        core.add_measured(float(t_meas[j]), y_meas[j])
    i += 200
    assert core.meas.size == i
    assert core.lag.estimates == 0 and core.lag.status == 'none'
    assert runner.busy
    assert runner.superseded >= 2       # 20 s of rows: more requests came, the newest waits
    assert gate.seqs == [1]             # one estimate at a time
    assert threading.get_ident() not in gate.threads
    gate.release.set()
    assert runner.wait_idle(timeout=60.0)
    core.add_measured(float(t_meas[i]), y_meas[i])
    # the blocked one and the newest waiting one ran; nothing in between
    assert gate.seqs[0] == 1 and len(gate.seqs) == 2 and gate.seqs[1] > 2
    assert core.lag.estimates == 1      # the newest finished outcome is used, once
    assert core.lag.status == 'ok' and abs(core.lag.lag_s - 0.42) < 1e-3
    assert first_blocked < i
    core.close()


@pytest.mark.parametrize('freeze_count', [0, 2])
def test_a_threaded_comparison_ends_as_the_inline_one(freeze_count):
    """A run within ``ring_s``: every row is evaluated at the final lag either way."""
    t_pred, y_pred, t_meas, y_meas = streams(lag_s=-0.31, seed=4)
    settings = LiveSettings(max_lag_s=2.0, freeze_count=freeze_count, freeze_tol_s=1e-3)
    inline = run(LiveComparison(('X', 'Y'), settings), t_pred, y_pred, t_meas, y_meas)
    runner = ThreadedLag()
    threaded = run(LiveComparison(('X', 'Y'), settings, lag_runner=runner),
                   t_pred, y_pred, t_meas, y_meas)
    assert runner.submitted >= 1
    if freeze_count == 0:
        # the last estimate is made at the end on the same rings: the same figures exactly
        assert threaded['lag']['lag_s'] == inline['lag']['lag_s']
        for key in ('measured_energy_j', 'predicted_energy_j', 'energy_error_pct'):
            assert threaded[key] == inline[key]
    else:
        # frozen by estimates that agree within freeze_tol_s; which ones depends on when the
        # worker finished them (some requests are superseded): the lag within the tolerance
        assert threaded['lag']['frozen'] and inline['lag']['frozen']
        assert abs(threaded['lag']['lag_s'] - inline['lag']['lag_s']) <= 2e-3
        assert abs(threaded['energy_error_pct']['total']
                   - inline['energy_error_pct']['total']) < 0.05
    assert threaded['rows'] == inline['rows']
    # a frozen lag does not wait for the worker: a superseded request may still be running
    # when the final comparison is made; it ends, nothing is left queued
    assert threaded['final'] and runner.wait_idle(timeout=30.0) and not runner.busy


def test_the_inline_runner_uses_each_estimate_at_once():
    t_pred, y_pred, t_meas, y_meas = streams()
    core = LiveComparison(('X', 'Y'), LiveSettings(max_lag_s=2.0, min_align_s=10.0,
                                                   realign_every_s=5.0))
    assert isinstance(core.lag_runner, InlineLag)
    core.add_prediction(t_pred, y_pred)
    for t, y in zip(t_meas, y_meas):
        core.add_measured(float(t), y)
        assert core.lag.estimates == core.lag_runner.submitted     # in the same call
    assert core.lag.estimates == 10   # from 10 s on, every 5 s, over 57 s of rows


def test_a_failing_estimator_is_reported_not_raised_and_a_closed_runner_drops_outcomes():
    def broken(request):
        raise ValueError('boom')

    runner = ThreadedLag(broken)
    t = np.arange(3.0)
    request = LagRequest(1, t, t, t, t, max_lag_s=1.0, window_s=0.0, stamp='end',
                         min_correlation=0.5)
    runner.submit(request)
    assert runner.wait_idle(timeout=10.0)
    out = runner.take()
    assert out is not None and out.found is None and 'boom' in out.reason
    assert runner.failed == 1 and runner.take() is None
    runner.close()
    runner.submit(request)
    assert runner.wait_idle(timeout=10.0) and runner.take() is None
    assert runner.submitted == 1


def test_too_few_samples_is_a_reason():
    t = np.arange(1.0)
    out = estimate_lag(LagRequest(7, t, t, t, t, max_lag_s=1.0, window_s=0.0, stamp='end',
                                  min_correlation=0.5))
    assert out.seq == 7 and out.found is None and out.reason
