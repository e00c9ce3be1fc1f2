"""The job state machine and the board a shell drives: legal and illegal sequences."""
import itertools
import json
import math

import pytest

from feed_axis_energy.cell import (ACTIVE, check_transition, EnergyReport, JobBoard, JobLimits,
                                   JobResult, JobState, TERMINAL, TRANSITIONS)
from feed_axis_energy.errors import JobError
from feed_axis_energy.paths import default_machine


def test_the_transition_table_is_exactly_the_documented_one():
    S = JobState
    legal = {(S.IDLE, S.PLANNING), (S.PLANNING, S.RUNNING), (S.PLANNING, S.ABORTED),
             (S.PLANNING, S.FAILED), (S.RUNNING, S.ENDED), (S.RUNNING, S.ABORTED),
             (S.RUNNING, S.FAILED), (S.ENDED, S.PLANNING), (S.ABORTED, S.PLANNING),
             (S.FAILED, S.PLANNING)}
    for old, new in itertools.product(S, S):
        if (old, new) in legal:
            assert check_transition(old, new) is new
        else:
            with pytest.raises(JobError) as info:
                check_transition(old, new)
            assert info.value.field == 'state'
            assert f'cannot go from {old.value} to {new.value}' in str(info.value)
    assert set(TRANSITIONS) == set(S)
    assert {s.value for s in S} == {'idle', 'planning', 'running', 'ended', 'aborted',
                                    'failed'}
    assert TERMINAL.isdisjoint(ACTIVE)


@pytest.fixture
def board(tmp_path):
    (tmp_path / 'p.nc').write_text('G1 X10 F3000\n')
    return JobBoard(JobLimits(program_root=tmp_path, default_machine=default_machine()),
                    keep=3)


def _report(job_id, total=10.0):
    return EnergyReport(job_id=job_id, samples=100, duration_s=0.099,
                        energy_j={'X': total, 'total': total},
                        peak_power_w={'X': 5.0, 'total': 5.0}, braking_returned_j=0.5)


def _run(board, job_id, *, status='ended', sent=100):
    spec = board.start({'job_id': job_id, 'program': 'p.nc', 'load_kg': 2})
    board.planned(job_id)
    board.finish(JobResult.build(spec, _report(job_id), status=status, sent_samples=sent))
    return spec


def test_a_job_runs_through_planning_running_ended_and_its_result_is_kept(board):
    seen = []
    board.on_change.append(lambda snap: seen.append((snap.state.value, snap.job_id)))
    assert board.state is JobState.IDLE and board.snapshot.job_id == ''
    _run(board, 'a1')
    assert seen == [('planning', 'a1'), ('running', 'a1'), ('ended', 'a1')]
    res = board.result('a1')
    assert res.status == 'ended' and res.energy_total_j == 10.0 and res.lost_samples == 0
    assert res.load_kg == 2.0 and len(res.program_sha256) == 64
    snap = board.snapshot.to_dict()
    assert snap['state'] == 'ended' and snap['spec']['job_id'] == 'a1'
    assert snap['sequence'] == 3
    json.dumps(snap, allow_nan=False)


def test_a_second_start_while_running_is_a_clear_state_error(board):
    board.start({'job_id': 'a1', 'program': 'p.nc'})
    for state_step in ('planning', 'running'):
        with pytest.raises(JobError) as info:
            board.start({'job_id': 'a2', 'program': 'p.nc'})
        assert info.value.field == 'state'
        assert f"job 'a1' is {state_step}" in str(info.value)
        assert info.value.job_id == 'a2'
        if state_step == 'planning':
            board.planned('a1')
    assert board.snapshot.job_id == 'a1' and board.state is JobState.RUNNING


def test_abort_marks_the_running_job_and_its_result_says_aborted(board):
    with pytest.raises(JobError, match='no job is running'):
        board.abort('a1')
    spec = board.start({'job_id': 'a1', 'program': 'p.nc'})
    board.planned('a1')
    with pytest.raises(JobError, match="current job is 'a1'"):
        board.abort('other')
    assert not board.abort_requested
    board.abort('a1')
    assert board.abort_requested
    board.finish(JobResult.build(spec, _report('a1'), status='aborted',
                                 message='aborted by request', sent_samples=100))
    assert board.state is JobState.ABORTED and not board.abort_requested
    assert board.result('a1').status == 'aborted'
    with pytest.raises(JobError, match='nothing to abort'):
        board.abort('a1')


def test_a_job_cannot_end_while_planning_but_can_fail_or_be_aborted(board):
    spec = board.start({'job_id': 'a1', 'program': 'p.nc'})
    with pytest.raises(JobError, match='cannot end from planning'):
        board.finish(JobResult.build(spec, None, status='ended'))
    board.finish(JobResult.build(spec, None, status='failed', message='p.nc:1:1: bad'))
    assert board.state is JobState.FAILED and board.snapshot.message == 'p.nc:1:1: bad'
    res = board.result('a1')
    assert res.samples == 0 and res.energy_j == {} and res.energy_total_j == 0.0
    _run(board, 'a2')      # a new job after a failure


def test_job_ids_are_not_reused_while_their_result_is_kept_and_the_store_is_bounded(board):
    _run(board, 'a1')
    with pytest.raises(JobError, match='used already'):
        board.start({'job_id': 'a1', 'program': 'p.nc'})
    for i in range(2, 6):
        _run(board, f'a{i}')
    assert board.results.job_ids() == ['a3', 'a4', 'a5']
    with pytest.raises(JobError, match='the last 3 jobs are kept'):
        board.result('a1')
    _run(board, 'a1')      # dropped from the store: the id is free again


def test_results_of_another_job_are_refused(board):
    spec = board.start({'job_id': 'a1', 'program': 'p.nc'})
    board.planned('a1')
    with pytest.raises(JobError, match='not the current job'):
        board.finish(JobResult.build(spec, _report('a1'), status='ended').__class__(
            **{**JobResult.build(spec, _report('a1'), status='ended').__dict__,
               'job_id': 'zz'}))
    with pytest.raises(JobError, match="energy report of job 'b'"):
        JobResult.build(spec, _report('b'), status='ended')


def test_a_rejected_request_leaves_the_board_as_it_was(board):
    _run(board, 'a1')
    before = board.snapshot
    for bad in ({'job_id': 'x', 'program': '../p.nc'}, {'job_id': 'x y', 'program': 'p.nc'},
                {'job_id': 'x', 'program': 'p.nc', 'load_kg': math.nan}, 'not a mapping'):
        with pytest.raises(JobError):
            board.start(bad)
        assert board.snapshot is before
