"""The job service on the graph's job topics (bridge/graphjobs.py), without ROS: a fake graph
answers the commands the service sends; topic messages are fed in as the node would."""
from __future__ import annotations

import json
import threading
import time

import pytest

from feed_axis_energy.bridge import (GraphJobService, LiveSample, MEASURED_LIVE_KEYS,
                                     measured_live_payload, MeasuredSample, read_users_file,
                                     service_result, StateChange)
from feed_axis_energy.errors import ConfigError

GRAPH_RESULT = {
    'job_id': 'j1', 'status': 'ended', 'message': 'program completed', 'program': '/p/a.nc',
    'program_sha256': '0' * 64, 'machine': '/m.yaml', 'load_kg': 2.0, 'duration_s': 1.5,
    'samples': 1501, 'lost_samples': 0, 'energy_j': {'X': 3.0, 'Y': 1.5, 'total': 4.5},
    'peak_power_w': {'X': 20.0, 'Y': 5.0, 'total': 22.0}, 'braking_returned_j': 0.25,
    'electrical': None}


def _state(state, job_id, sequence, planned=0):
    return json.dumps({'state': state, 'job_id': job_id, 'message': '', 'sequence': sequence,
                       'planned_samples': planned, 'spec': None})


def _live(job_id, samples, line, total_w=10.0):
    return json.dumps({'job_id': job_id, 'stamp_ns': 1_764_280_000_000_000_000 + samples,
                       'clock': 'wall', 'time_s': samples / 1000, 'samples': samples,
                       'line': line, 'power_w': {'X': total_w - 1, 'Y': 1.0, 'total': total_w},
                       'energy_j': {'X': 2.0, 'Y': 0.5, 'total': 2.5}, 'electrical': None})


class FakeGraph:
    """Answers each command on a thread of its own, as gcode_trajectory does on job/reply."""

    def __init__(self, accept=True, message='planning', delay_s=0.01):
        self.sent = []
        self.service = None
        self.accept, self.message, self.delay_s = accept, message, delay_s

    def send(self, text):
        cmd = json.loads(text)
        self.sent.append(cmd)
        reply = {'request_id': cmd['request_id'], 'accepted': self.accept,
                 'message': self.message, 'job_id': cmd.get('job_id', ''), 'state': 'idle',
                 'field': ''}
        if cmd['command'] == 'result' and self.accept:
            reply['result'] = dict(GRAPH_RESULT, job_id=cmd['job_id'])

        def answer():
            time.sleep(self.delay_s)
            # a reply to somebody else first: it must not be taken for ours
            self.service.on_reply(json.dumps({**reply, 'request_id': 'other-client-1'}))
            self.service.on_reply(json.dumps(reply))
        threading.Thread(target=answer, daemon=True).start()


@pytest.fixture
def graph():
    fake = FakeGraph()
    fake.service = GraphJobService(('X', 'Y'), fake.send, reply_timeout_s=2.0, keep=3,
                                   result_wait_s=0.2)
    return fake


def test_start_and_abort_send_commands_and_answer_the_matching_reply(graph):
    service = graph.service
    assert service.start_job('j1', 'a.nc', 2.5) == (True, 'planning')
    start = graph.sent[-1]
    assert {k: start[k] for k in ('command', 'job_id', 'program', 'load_kg')} == {
        'command': 'start', 'job_id': 'j1', 'program': 'a.nc', 'load_kg': 2.5}
    graph.accept, graph.message = False, "job 'j1' is running; abort it"
    assert service.start_job('j2', 'a.nc', 0.0) == (False, "job 'j1' is running; abort it")
    assert service.abort_job('j1')[0] is False and graph.sent[-1]['command'] == 'abort'
    assert len({c['request_id'] for c in graph.sent}) == 3


def test_no_reply_is_a_refusal_naming_the_timeout():
    service = GraphJobService(('X',), lambda text: None, reply_timeout_s=0.2)
    t0 = time.monotonic()
    accepted, message = service.start_job('j1', 'a.nc', 0.0)
    assert not accepted and 'did not answer the start command within 0.2 s' in message
    assert time.monotonic() - t0 < 1.5
    assert service.result('nope') is None


def test_state_follows_the_newest_sequence_and_live_gives_line_and_progress(graph):
    service = graph.service
    events = []
    unsubscribe = service.subscribe(events.append)
    assert (service.state(), service.active_job(), service.progress()) == ('idle', '', 0.0)
    service.on_state(_state('planning', 'j1', 5))
    service.on_state(_state('running', 'j1', 6, planned=1000))
    service.on_state(_state('idle', '', 0))             # latched history: older, ignored
    assert service.state() == 'running' and service.active_job() == 'j1'
    service.on_live(_live('j1', 250, 7))
    assert service.active_line() == 7 and service.progress() == pytest.approx(0.25)
    sample = events[-1]
    assert isinstance(sample, LiveSample) and sample.job_id == 'j1'
    assert sample.stamp_ns == 1_764_280_000_000_000_250        # the wall-clock stamp
    assert sample.total.power_w == 10.0 and sample.axes['X'].power_w == 9.0
    assert sample.total.energy_import_j == 2.5 and sample.total.energy_export_j == 0.0
    assert [e.state for e in events if isinstance(e, StateChange)] == ['planning', 'running']
    unsubscribe()
    service.on_live(_live('j1', 300, 8))
    assert len(events) == 3


def test_a_final_state_waits_for_its_result(graph):
    service = graph.service
    events = []
    service.subscribe(events.append)
    service.on_state(_state('planning', 'j1', 1))
    service.on_state(_state('running', 'j1', 2, planned=10))
    service.on_state(_state('ended', 'j1', 3))
    assert [e.state for e in events] == ['planning', 'running']    # held: no result yet
    assert service.state() == 'ended' and service.progress() == 1.0
    service.on_result(json.dumps(GRAPH_RESULT))
    assert [e.state for e in events] == ['planning', 'running', 'ended']
    assert service.last_result()['energy_j'] == 4.5
    # a result that never comes: released after result_wait_s by tick()
    service.on_state(_state('planning', 'j2', 4))
    service.on_state(_state('failed', 'j2', 5))
    service.tick()
    assert events[-1].state == 'planning'
    time.sleep(0.25)
    service.tick()
    assert events[-1].state == 'failed' and events[-1].job_id == 'j2'


def test_results_are_kept_in_the_bridges_form_and_older_ones_asked_of_the_graph(graph):
    service = graph.service
    for k in range(5):
        service.on_result(json.dumps(dict(GRAPH_RESULT, job_id=f'k{k}')))
    assert service.result('k4')['peak_power_w'] == 22.0
    assert service.result('k4')['energy_by_axis_j'] == {'X': 3.0, 'Y': 1.5}
    n_sent = len(graph.sent)
    assert service.result('k1')['job_id'] == 'k1'     # beyond keep=3: the result command
    assert graph.sent[n_sent]['command'] == 'result'
    graph.accept = False
    assert service.result('k0') is None


def test_service_result_totals_and_refusals():
    out = service_result(GRAPH_RESULT)
    assert (out['energy_j'], out['peak_power_w'], out['duration_s']) == (4.5, 22.0, 1.5)
    assert out['peak_power_by_axis_w'] == {'X': 20.0, 'Y': 5.0}
    assert out['braking_returned_j'] == 0.25 and out['program_sha256'] == '0' * 64
    nothing = service_result(dict(GRAPH_RESULT, status='failed', energy_j={}, peak_power_w={}))
    assert nothing['energy_j'] == 0.0 and nothing['energy_by_axis_j'] == {}
    for bad in ({**GRAPH_RESULT, 'status': 'running'}, {**GRAPH_RESULT, 'job_id': 3},
                {**GRAPH_RESULT, 'energy_j': {'total': 'x'}}):
        with pytest.raises(ValueError):
            service_result(bad)


@pytest.mark.parametrize('text', ['', 'null', '[1]', '{"state": "running"}',
                                  '{"state": "flying", "job_id": "a", "sequence": 9}',
                                  '{"state": "idle", "job_id": "a", "sequence": true}',
                                  b'\xff\xfe', '{"job_id": "a", "power_w": {"total": null},'
                                  ' "energy_j": {"total": 1}}'])
def test_malformed_topic_messages_are_counted_and_dropped(graph, text):
    service = graph.service
    events = []
    service.subscribe(events.append)
    for feed in (service.on_state, service.on_result, service.on_live, service.on_reply):
        feed(text)
    assert service.bad_messages >= 3 and events == [] and service.state() == 'idle'


def test_a_listener_that_raises_does_not_stop_the_others(graph):
    service = graph.service
    seen = []

    def broken(event):
        raise RuntimeError('listener fault')
    service.subscribe(broken)
    service.subscribe(seen.append)
    service.on_state(_state('planning', 'j1', 1))
    assert len(seen) == 1 and service.listener_errors == 1


def test_measured_live_payload_is_the_documented_contract():
    sample = MeasuredSample(axis='X', quantity='power_w', value=41.5,
                            stamp_ns=1_764_280_000_125_000_000)
    data = json.loads(measured_live_payload(sample))
    assert tuple(sorted(data)) == tuple(sorted(MEASURED_LIVE_KEYS))
    assert data == {'axis': 'X', 'stamp': 1764280000.125, 'quantity': 'power_w',
                    'value': 41.5}


def test_users_file(tmp_path):
    path = tmp_path / 'users'
    path.write_text('# cell users\nalice:s3cret:with:colons\n\n bob : pw\n')
    assert read_users_file(path) == {'alice': 's3cret:with:colons', 'bob': ' pw'}
    for text, where in (('alice\n', ':1'), ('a:b\n:pw\n', ':2'), ('a:b\na:c\n', ':2'),
                        ('a:\n', ':1')):
        path.write_text(text)
        with pytest.raises(ConfigError, match=where) as err:
            read_users_file(path)
        assert 'pw' not in str(err.value) or text.startswith(':')
    with pytest.raises(ConfigError, match='cannot read'):
        read_users_file(tmp_path / 'missing')
