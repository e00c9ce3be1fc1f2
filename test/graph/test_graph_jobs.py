"""Which job a stream message belongs to, and messages held until their job's spec arrives."""
import json
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.cell import JobSpec
from feed_axis_energy.errors import DataError
from feed_axis_energy.graph import header_frame_id, JobRouter, parse_state_text
from feed_axis_energy.record import typestore


def _cdr(frame_id):
    ts = typestore()
    Header = ts.types['std_msgs/msg/Header']
    Time = ts.types['builtin_interfaces/msg/Time']
    return bytes(ts.serialize_cdr(Header(stamp=Time(sec=3, nanosec=7), frame_id=frame_id),
                                  'std_msgs/msg/Header'))


@pytest.mark.parametrize('frame_id', ['', 'j1', 'job-2024.11_a', 'x' * 64, 'ünïcode'])
def test_frame_id_is_read_from_the_serialized_header(frame_id):
    assert header_frame_id(_cdr(frame_id)) == frame_id


def test_the_graph_encoder_and_the_reader_agree():
    pytest.importorskip('rclpy')
    from feed_axis_energy.nodes import convert
    data = convert.encode_trajectory(5, np.array([0, 1000]), ['X'],
                                     {'positions': np.zeros((2, 1))}, frame_id='abc')
    assert header_frame_id(data) == 'abc'


@pytest.mark.parametrize('data', [b'', b'\x00\x01\x00\x00' + b'\x00' * 8,
                                  b'\x00\x00\x00\x00' + b'\x00' * 20,
                                  _cdr('abc')[:17], _cdr('a' * 300)])
def test_damaged_headers_are_data_errors(data):
    with pytest.raises(DataError):
        header_frame_id(data)


def _spec(job_id):
    return JobSpec(job_id=job_id, program=Path('/p.nc'), program_sha256='0' * 64,
                   load_kg=1.0, machine=Path('/m.yaml'))


def test_state_text_round_trip_and_garbage():
    text = json.dumps({'state': 'running', 'job_id': 'j', 'message': '', 'sequence': 2,
                       'spec': _spec('j').to_dict()})
    state, job_id, spec = parse_state_text(text)
    assert (state, job_id, spec) == ('running', 'j', _spec('j'))
    assert parse_state_text('{"state": "idle", "job_id": "", "spec": null}')[2] is None
    for bad in ('', 'nope', '[]', '{"state": 1, "job_id": "j"}',
                '{"state": "running", "job_id": "j", "spec": {"job_id": "bad id"}}'):
        with pytest.raises(DataError):
            parse_state_text(bad)


def test_router_holds_messages_until_the_spec_and_is_bounded():
    router = JobRouter(keep=2, max_held=3)
    assert router.spec('a') is None
    router.hold('a', 1)
    router.hold('b', 2)
    router.hold('a', 3)
    assert router.note(_spec('a')) == [(_spec('a'), 1), (_spec('a'), 3)]
    assert router.held == 1 and router.spec('a') == _spec('a')
    for i in range(5):
        router.hold('c', i)
    assert router.held == 3 and router.dropped == 3      # 'b' and c0, c1 dropped
    assert [item for _, item in router.note(_spec('c'))] == [2, 3, 4]
    router.note(_spec('d'))
    assert router.spec('a') is None and router.spec('c') is not None    # keep=2
