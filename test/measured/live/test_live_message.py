"""The measured/live and measured/comparison JSON: the node's contract (live/message.py)."""
import json

import numpy as np
import pytest

from feed_axis_energy.bridge import QUANTITIES as MQTT_QUANTITIES
from feed_axis_energy.measured.live import (COMPARISON_KEYS, comparison_text, COUNTER_KEYS,
                                            LIVE_QUANTITIES, LiveMonitor, MAX_BATCH, parse_live)


def test_one_sample():
    text = '{"axis": "X", "stamp": 1764280000.125, "quantity": "power_w", "value": 41.5}'
    samples, rejects = parse_live(text)
    assert samples == [('X', 'power_w', 1764280000125000000, 41.5)] and rejects == {}


def test_a_batch_keeps_good_samples_and_counts_bad_ones():
    good = {'axis': 'Y', 'stamp': 1764280000, 'quantity': 'velocity_m_s', 'value': -0.01}
    bad = [{'axis': 'Y', 'stamp': 1764280000, 'quantity': 'power_kw', 'value': 1.0},
           {'axis': 'Y', 'stamp': 1764280000, 'quantity': 'power_w', 'value': True},
           {'axis': 'Y', 'stamp': -1, 'quantity': 'power_w', 'value': 1.0},
           {'axis': '', 'stamp': 1764280000, 'quantity': 'power_w', 'value': 1.0},
           {'axis': 'Y', 'stamp': 1764280000, 'quantity': 'power_w', 'value': 10 ** 400},
           'text']
    samples, rejects = parse_live(json.dumps({'samples': [good] + bad}))
    assert samples == [('Y', 'velocity_m_s', 1764280000 * 10 ** 9, -0.01)]
    assert rejects == {'bad_sample': len(bad)}


@pytest.mark.parametrize('text, reason', [
    ('{"axis": "X", "stamp": NaN, "quantity": "power_w", "value": 1}', 'bad_json'),
    ('not json', 'bad_json'),
    ('[1, 2]', 'not_object'),
    ('{"axis": "X"}', 'bad_sample'),
    ('{"samples": 3}', 'bad_sample'),
    ('[' * 100_000, 'bad_json'),
    (' ' * (4 * 1024 * 1024 + 1), 'too_large'),
])
def test_what_cannot_be_used_is_counted_never_raised(text, reason):
    samples, rejects = parse_live(text)
    assert samples == [] and rejects == {reason: 1}


def test_a_batch_too_long_is_refused_whole():
    one = {'axis': 'X', 'stamp': 1764280000.0, 'quantity': 'power_w', 'value': 1.0}
    samples, rejects = parse_live(json.dumps({'samples': [one] * (MAX_BATCH + 1)}))
    assert samples == [] and rejects == {'batch_too_long': 1}


def test_quantities_are_the_mqtt_bridges():
    assert set(LIVE_QUANTITIES) == set(MQTT_QUANTITIES)


def test_comparison_text_is_strict_json_with_units_in_the_keys():
    monitor = LiveMonitor(('X', 'Y'), source='job_live', job_id='j1')
    ns = 1764280000 * 10 ** 9
    monitor.add_sample('X', 'power_w', ns, 1.0)            # a row without Y: never complete
    monitor.add_sample('Z', 'power_w', ns, 1.0)            # not a measured axis
    monitor.add_sample('X', 'current_a', ns, 1.0)          # not used by the comparison
    data = json.loads(comparison_text(monitor.snapshot()))
    assert tuple(data) == COMPARISON_KEYS
    assert data['job_id'] == 'j1' and data['source'] == 'job_live'
    assert data['stamp'] is None                            # NaN -> null, nothing evaluated
    assert data['measured_power_w'] == {'X': None, 'Y': None, 'total': None}
    assert set(data['counters']['measured']) == set(COUNTER_KEYS)
    assert data['counters']['unknown_axis'] == 1 and data['counters']['unused_quantity'] == 1
    for key in data:
        exempt = ('lag', 'alarm', 'rows', 'counters', 'signal')
        if isinstance(data[key], dict) and key not in exempt:
            assert key.endswith(('_w', '_j', '_pct')), key


def test_job_live_prediction_against_measured_rows():
    """The job/live path: predicted power per axis at 10 Hz, measured rows on the same clock."""
    monitor = LiveMonitor(('X',), source='job_live')
    t0 = 1764280000 * 10 ** 9
    rng = np.random.default_rng(0)
    for k in range(200):
        stamp = t0 + k * 100_000_000
        p = float(rng.uniform(5.0, 50.0))
        monitor.add_prediction(stamp, {'X': p, 'Y': 0.0, 'total': p})
        monitor.add_sample('X', 'power_w', stamp, 1.2 * p)
    assert monitor.add_prediction(t0, {'Y': 1.0}) is False
    out = monitor.finish()
    assert out['final'] and out['lag']['status'] == 'ok' and abs(out['lag']['lag_s']) < 1e-3
    assert abs(out['energy_error_pct']['total'] - 100.0 * (1 / 1.2 - 1)) < 0.01
    assert out['counters']['prediction_unusable'] == 1
    assert out['counters']['measured']['rows'] == 200
