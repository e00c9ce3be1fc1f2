"""``measured_live`` (``source: job_live``): a job's comparison is final ``final_after_s``
after the job ends, so that drive data still on their way are compared (docs/nodes.md,
"measured_live")."""
from contextlib import contextmanager
import json
import time

import must_run
import pytest

must_run.import_or_skip('rclpy', 'rclpy')
from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from feed_axis_energy.nodes.measured_live import MeasuredLive  # noqa: E402

RATE_HZ = 50.0
RUN_S = 3.0
LATE_S = 0.5        # the last half second of measured data arrives after the job's end


def _node(context, final_after_s):
    node = MeasuredLive(context=context, parameter_overrides=[
        Parameter('source', value='job_live'), Parameter('measured_axes', value='X'),
        Parameter('final_after_s', value=final_after_s)])
    sent = []
    node.pub.publish = lambda msg: sent.append(json.loads(msg.data))
    return node, sent


@contextmanager
def _live(context, final_after_s):
    """``(node, sent)`` for the block, the node destroyed after it."""
    node, sent = _node(context, final_after_s)
    try:
        yield node, sent
    finally:
        node.destroy_node()


def _state(node, state):
    node._on_job_state(String(data=json.dumps({'state': state, 'job_id': 'j1'})))


def _measured(node, stamps):
    for t in stamps:
        node._on_measured(String(data=json.dumps(
            {'axis': 'X', 'stamp': t, 'quantity': 'power_w', 'value': 110.0})))


def _run_job(node):
    """A 3 s job predicted at 100 W; measured 110 W, the last LATE_S arriving after its end.
    Returns the stamps that arrive late."""
    t0 = time.time() - RUN_S - 1.0
    stamps = [t0 + k / RATE_HZ for k in range(int(RUN_S * RATE_HZ) + 1)]
    _state(node, 'running')
    for t in stamps:
        node._on_job_live(String(data=json.dumps({
            'job_id': 'j1', 'stamp_ns': int(t * 1e9), 'clock': 'wall',
            'power_w': {'X': 100.0, 'total': 100.0}})))
    on_time = [t for t in stamps if t <= stamps[-1] - LATE_S]
    _measured(node, on_time)
    _state(node, 'ended')
    return stamps[len(on_time):]


@child_only
def test_samples_arriving_after_the_end_are_compared(context):
    with _live(context, 0.8) as (node, sent):
        late = _run_job(node)
        assert not any(m['final'] for m in sent)        # not final at the job's end
        _measured(node, late)
        node._tick()
        assert not any(m['final'] for m in sent)        # not yet: 0.8 s
        time.sleep(0.9)
        node._tick()
        finals = [m for m in sent if m['final']]
        assert len(finals) == 1 and finals[0]['job_id'] == 'j1'
        counters = finals[0]['counters']
        rows = counters['measured']['rows']
        # every measured sample is in the comparison, the late ones too
        assert rows == int(RUN_S * RATE_HZ) + 1, counters
        assert counters['outside_job'] == 0
        assert abs(finals[0]['energy_error_pct']['total'] - 100.0 * (1 / 1.1 - 1)) < 0.5
        # samples after the final comparison count as outside any job
        _measured(node, [late[-1] + 0.1])
        assert node.outside_job == 1


@child_only
def test_zero_makes_it_final_at_the_end_and_the_late_samples_are_outside(context):
    with _live(context, 0.0) as (node, sent):
        late = _run_job(node)
        finals = [m for m in sent if m['final']]
        assert len(finals) == 1
        assert finals[0]['counters']['measured']['rows'] < int(RUN_S * RATE_HZ) + 1
        _measured(node, late)
        assert node.outside_job == len(late)


@child_only
def test_the_next_job_or_the_node_stopping_makes_it_final_at_once(context):
    with _live(context, 30.0) as (node, sent):
        _run_job(node)
        node._on_job_state(String(data=json.dumps({'state': 'running', 'job_id': 'j2'})))
        assert [m['job_id'] for m in sent if m['final']] == ['j1']
    node, sent = _node(context, 30.0)
    _run_job(node)
    node.destroy_node()
    assert [m['job_id'] for m in sent if m['final']] == ['j1']


@pytest.mark.parametrize('value', [-1.0, float('nan')])
@child_only
def test_a_bad_value_is_refused_at_start_up(context, value):
    from feed_axis_energy.nodes.runner import StartupError
    with pytest.raises(StartupError, match='final_after_s'):
        _node(context, value)


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The tests above, in their own interpreter (see conftest.run_module_in_child)."""
    run_module_in_child(__file__)
