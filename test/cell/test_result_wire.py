"""Result and energy-report JSON contracts; the command parser against hostile text."""
import json
import math

import pytest

from feed_axis_energy.cell import (dumps, EnergyReport, JobResult, JobSpec, MAX_COMMAND_BYTES,
                                   parse_command, reply, ResultStore)
from feed_axis_energy.errors import DataError, JobError

RESULT_KEYS = {'job_id', 'status', 'message', 'program', 'program_sha256', 'machine',
               'load_kg', 'duration_s', 'samples', 'lost_samples', 'energy_j', 'peak_power_w',
               'braking_returned_j', 'electrical'}


def _spec():
    return JobSpec(job_id='j1', program='/r/p.nc', program_sha256='ab' * 32, load_kg=3.0,
                   machine='/c/m.yaml')


def _report(**kw):
    base = dict(job_id='j1', samples=1000, duration_s=0.999,
                energy_j={'X': 4.0, 'Y': 1.0, 'total': 5.0},
                peak_power_w={'X': 9.0, 'Y': 2.0, 'total': 10.0}, braking_returned_j=0.25,
                electrical={'measured_at': 'supply',
                            'motor_energy_j': {'X': 6.0, 'Y': 2.0, 'total': 8.0},
                            'supply_energy_j': {'X': 7.0, 'Y': 3.0, 'cabinet': 1.0,
                                                'total': 11.0},
                            'returned_j': 0.1})
    base.update(kw)
    return EnergyReport(**base)


def test_the_result_json_holds_exactly_the_documented_keys_and_round_trips():
    res = JobResult.build(_spec(), _report(), status='ended', message='', sent_samples=1003)
    d = json.loads(dumps(res.to_dict()))
    assert set(d) == RESULT_KEYS
    assert d['lost_samples'] == 3 and d['energy_j']['total'] == 5.0
    assert set(d['electrical']) == {'measured_at', 'motor_energy_j', 'supply_energy_j',
                                    'returned_j'}
    assert JobResult.from_dict(d) == res
    rep = _report()
    assert EnergyReport.from_dict(json.loads(dumps(rep.to_dict()))) == rep
    plain = _report(electrical=None)
    assert EnergyReport.from_dict(json.loads(dumps(plain.to_dict()))).electrical is None


@pytest.mark.parametrize('key, value, words', [
    ('status', 'done', 'must be one of'),
    ('samples', -1, 'whole number >= 0'),
    ('samples', 1.5, 'whole number >= 0'),
    ('duration_s', None, 'finite number'),
    ('load_kg', -1.0, 'must be >= 0'),
    ('energy_j', {'X': 1.0}, '"total"'),
    ('energy_j', {'X': 'a', 'total': 1.0}, 'finite number'),
    ('peak_power_w', [1, 2], 'object of numbers'),
    ('electrical', 'yes', 'object or null'),
    ('job_id', 5, 'must be text'),
])
def test_result_from_dict_names_the_bad_key(key, value, words):
    d = JobResult.build(_spec(), _report(), status='ended').to_dict()
    d[key] = value
    with pytest.raises(DataError) as info:
        JobResult.from_dict(d)
    assert words in str(info.value)
    assert info.value.column.split('.')[0] == key


def test_no_nan_gets_into_a_result_or_onto_the_wire():
    with pytest.raises(DataError, match='not finite'):
        JobResult.build(_spec(), _report(energy_j={'X': math.nan, 'total': 1.0}),
                        status='ended')
    with pytest.raises(ValueError):
        dumps({'x': math.inf})
    with pytest.raises(DataError, match='finite'):
        EnergyReport.from_dict({**_report().to_dict(), 'duration_s': math.nan})


def test_the_result_store_keeps_the_last_n_and_refuses_a_second_result_per_id():
    store = ResultStore(2)
    for i in range(3):
        store.add(JobResult.build(JobSpec(**{**_spec().__dict__, 'job_id': f'j{i}'}), None,
                                  status='failed', message='x'))
    assert store.job_ids() == ['j1', 'j2'] and store.last().job_id == 'j2'
    assert 'j0' not in store and len(store) == 2
    with pytest.raises(JobError, match='stored already'):
        store.add(store.get('j2'))
    with pytest.raises(JobError, match='no result'):
        store.get('j0')
    for bad in (0, -1, 1.5, True):
        with pytest.raises(JobError):
            ResultStore(bad)


def test_commands_parse_into_word_request_id_and_body():
    cmd = parse_command(json.dumps({'command': 'start', 'request_id': 'r1', 'job_id': 'j',
                                    'program': 'p.nc', 'load_kg': 2.5}))
    assert cmd.command == 'start' and cmd.request_id == 'r1'
    assert cmd.body == {'job_id': 'j', 'program': 'p.nc', 'load_kg': 2.5}
    assert parse_command(b'{"command": "abort", "job_id": "j"}').request_id == ''


@pytest.mark.parametrize('text, words', [
    ('', 'not JSON'),
    ('{', 'not JSON'),
    ('[1, 2]', 'a JSON object'),
    ('"start"', 'a JSON object'),
    ('{"command": "launch"}', 'must be one of start, abort, result'),
    ('{"job_id": "j"}', 'must be one of'),
    ('{"command": "start", "load_kg": NaN}', 'not a number JSON allows'),
    ('{"command": "start", "load_kg": Infinity}', 'not a number JSON allows'),
    ('{"command": "start", "request_id": 5}', 'request_id'),
    ('{"command": "start", "request_id": "' + 'r' * 65 + '"}', 'request_id'),
    ('{"command": "start", "overrides": {"a": {"b": {"c": {"d": 1}}}}}', 'nested'),
    ('[' * 100000 + ']' * 100000, 'at most'),
    ('[' * 8000 + ']' * 8000, 'not JSON'),
    ('{"a":' * 2500 + '1' + '}' * 2500, 'not JSON'),
    (b'{"command": "start", "x": "\xff"}', 'not JSON'),
    ('{"command": "start", "pad": "' + 'x' * MAX_COMMAND_BYTES + '"}', 'at most 16384 bytes'),
])
def test_hostile_command_text_is_refused_with_a_reason(text, words):
    with pytest.raises(JobError) as info:
        parse_command(text)
    assert info.value.field == 'request'
    assert words in str(info.value)


def test_reply_holds_the_documented_keys():
    r = reply('r1', accepted=False, message='no', job_id='j', state='running', field='state')
    assert set(json.loads(dumps(r))) == {'request_id', 'accepted', 'message', 'job_id', 'state',
                                         'field'}
