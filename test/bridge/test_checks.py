"""The bridges' pure parts: request checks, result summary, payloads, measured input."""
from __future__ import annotations

import json
import math

from hypothesis import given, settings, strategies as st
import pytest

from feed_axis_energy.bridge import (AxisPower, check_job_id, check_load_kg, LiveSample,
                                     MAX_PAYLOAD_BYTES, MeasuredInput, parse_measured,
                                     POWER_KEYS, power_payload, result_payload, result_summary,
                                     TopicTree, unece_unit_id)
from feed_axis_energy.errors import ConfigError, RequestError


def test_unece_unit_ids_are_the_codes_bytes() -> None:
    # OPC 10000-8 5.6.3: UnitId = the common code's characters, 8 bits each
    assert unece_unit_id('WTT') == 0x575454
    assert unece_unit_id('WHR') == 0x574852
    assert unece_unit_id('P1') == 0x5031


@pytest.mark.parametrize('job_id', ['a', 'Order 4711/2', 'x' * 64, 'Auftrag-Ä1'])
def test_good_job_ids_pass(job_id: str) -> None:
    assert check_job_id(job_id, request='StartJob') == job_id


@pytest.mark.parametrize('load', [0, 0.0, 12.5, 10000.0])
def test_good_loads_pass(load: float) -> None:
    assert check_load_kg(load, request='StartJob') == float(load)


@pytest.mark.parametrize('load', [True, None, 'x', math.nan, -math.inf, -0.1, 10000.5])
def test_bad_loads_are_request_errors(load: object) -> None:
    with pytest.raises(RequestError, match='^StartJob LoadKg: '):
        check_load_kg(load, request='StartJob')


def test_a_result_summary_needs_finite_numbers_and_a_final_state() -> None:
    good = {'job_id': 'j', 'status': 'ended', 'energy_j': 1.0, 'duration_s': 2,
            'peak_power_w': 3.0, 'other': [1]}
    assert result_summary(good).duration_s == 2.0
    for key, value, match in (('energy_j', math.nan, 'energy_j: expected a finite number'),
                              ('status', 'running', 'status: expected one of ended'),
                              ('job_id', None, 'job_id: expected the job id as text'),
                              ('peak_power_w', '3', 'expected a finite number, got text')):
        with pytest.raises(RequestError, match=match):
            result_summary({**good, key: value})


def test_power_payload_has_units_in_keys_and_no_nan() -> None:
    sample = LiveSample(job_id='j', stamp_ns=1_764_280_000_500_000_000,
                        axes={'X': AxisPower(10.0, 5.0, 1.0), 'Y': AxisPower(math.nan, 0, 0)},
                        total=AxisPower(10.0, 5.0, 1.0))
    text = power_payload(sample).decode()
    assert 'NaN' not in text
    data = json.loads(text)
    assert tuple(data) == POWER_KEYS
    assert data['stamp'] == 1764280000.5
    assert data['power_w'] == {'X': 10.0, 'Y': None, 'total': 10.0}
    assert data['energy_j']['X'] == 4.0
    with pytest.raises(RequestError, match='cannot be published as JSON'):
        result_payload({'energy_j': math.inf}, stamp_ns=0)


@pytest.mark.parametrize('prefix,machine', [('', 'm'), ('a/+', 'm'), ('a', 'm/x'),
                                            ('a', '#'), ('/a', 'm'), ('a//b', 'm'),
                                            ('$SYS', 'm'), ('a', 'x' * 65), ('a', 'm\n')])
def test_bad_topic_levels_are_config_errors(prefix: str, machine: str) -> None:
    with pytest.raises(ConfigError, match='expected a topic level'):
        TopicTree(prefix=prefix, machine=machine)


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.binary(max_size=200),
                 st.recursive(st.none() | st.booleans() | st.floats() | st.integers()
                              | st.text(max_size=10),
                              lambda inner: st.lists(inner, max_size=4)
                              | st.dictionaries(st.sampled_from(['stamp', 'value', 'quantity',
                                                                 'x']), inner, max_size=4),
                              max_leaves=10).map(lambda v: json.dumps(v).encode())))
def test_any_payload_is_a_sample_or_a_request_error(payload: bytes) -> None:
    try:
        sample = parse_measured('X', payload, topic='t')
    except RequestError as exc:
        assert exc.code
        return
    assert math.isfinite(sample.value) and sample.stamp_ns > 0


def test_the_rate_limit_admits_a_second_of_burst_then_the_rate() -> None:
    now = [0.0]
    got = []
    gate = MeasuredInput(got.append, max_rate_hz=10.0, clock=lambda: now[0])
    payload = b'{"stamp": 1.7e9, "value": 1, "quantity": "power_w"}'
    for _ in range(25):
        gate.handle('X', 't/X', payload)
    assert (gate.accepted, gate.drops['rate_limited']) == (10, 15)
    now[0] = 0.5
    for _ in range(10):
        gate.handle('X', 't/X', payload)
    assert gate.accepted == 15 and len(got) == 15
    now[0] = 10.0
    assert gate.handle('X', 't/X', b'x' * (MAX_PAYLOAD_BYTES + 1)) is None
    assert gate.drops['too_large'] == 1


def test_the_bounded_log_writes_powers_of_two(caplog) -> None:
    import logging

    from feed_axis_energy.bridge.logbound import BoundedLog
    log = BoundedLog(logging.getLogger('fae-test-bounded'))
    with caplog.at_level(logging.WARNING, logger='fae-test-bounded'):
        for _ in range(1000):
            log.log(logging.WARNING, 'same', 'it failed again')
    assert log.counts == {'same': 1000}
    assert [r.getMessage() for r in caplog.records][-1] == 'it failed again (same, 512 so far)'
    assert len(caplog.records) == 10     # 1, 2, 4, ..., 512
