"""docs/nodes.md's job interface (topics, JSON keys, states) is what the code does."""
import json
from pathlib import Path
import re

import pytest

from feed_axis_energy.cell import (COMMANDS, EnergyReport, JobBoard, JobLimits, JobResult,
                                   JobSpec, JobState, reply)
from feed_axis_energy.errors import JobError
from feed_axis_energy.paths import config_dir, default_machine

ROOT = Path(__file__).resolve().parents[2]
DOC = (ROOT / 'docs' / 'nodes.md').read_text()
SECTION = DOC[DOC.index('## Jobs'):DOC.index('## Timing and flow control')]


def _table(first_header):
    """``{first cell: row cells}`` of the markdown table whose header starts so."""
    lines = SECTION[SECTION.index(f'| {first_header} |'):].splitlines()
    rows = {}
    for line in lines[2:]:
        if not line.startswith('|'):
            break
        cells = [c.strip() for c in line.strip('|').split('|')]
        rows[cells[0]] = cells[1:]
    return rows


def _keys(cell):
    return set(re.findall(r'`([a-z_0-9/]+)`', cell))


def test_documented_topics_are_the_ones_the_nodes_use():
    topics = {t for cell in _table('topic') for t in _keys(cell)}
    assert topics == {'job/command', 'job/reply', 'job/state', 'job/result', 'job/energy',
                      'job/live'}
    source = ''.join((ROOT / 'feed_axis_energy' / 'nodes' / f).read_text()
                     for f in ('gcode_trajectory.py', 'energy_estimator.py'))
    for topic in topics:
        assert f"'{topic}'" in source, topic


def test_documented_command_keys_are_exactly_the_accepted_ones(tmp_path):
    keys = set().union(*(_keys(c) for c in _table('command key')))
    assert set(COMMANDS) == {'start', 'abort', 'result'}
    assert {'command', 'request_id'} <= keys
    (tmp_path / 'p.nc').write_text('G1 X1 F100\n')
    board = JobBoard(JobLimits(program_root=tmp_path, default_machine=default_machine(),
                               machine_root=config_dir()))
    request = {'job_id': 'j', 'program': 'p.nc', 'load_kg': 1.0,
               'machine': 'demonstrator.yaml', 'overrides': {}}
    assert set(request) == keys - {'command', 'request_id'}
    board.start(request)       # every documented key is accepted
    with pytest.raises(JobError, match='unknown key'):
        JobBoard(board.limits).start({**request, 'job_id': 'k', 'priority': 1})


def test_documented_reply_result_state_and_energy_keys():
    reply_keys = set().union(*(_keys(c) for c in _table('reply key')))
    assert reply_keys == set(reply('r', accepted=True, message='m')) | {'result'}
    result_keys = set().union(*(_keys(c) for c in _table('result key')))
    spec = JobSpec(job_id='j', program=Path('/p.nc'), program_sha256='0' * 64, load_kg=0.0,
                   machine=Path('/m.yaml'))
    result = JobResult.build(spec, None, status='failed', message='x')
    assert result_keys == set(result.to_dict())
    energy_par = SECTION[SECTION.index('`job/energy` (internal) holds'):]
    energy_par = energy_par[:energy_par.index('\n\n')]
    report = EnergyReport(job_id='j', samples=0, duration_s=0.0, energy_j={'total': 0.0},
                          peak_power_w={'total': 0.0}, braking_returned_j=0.0)
    assert _keys(energy_par) - {'job/energy'} == set(report.to_dict())
    state_par = SECTION[SECTION.index('`job/state` keys:'):]
    state_par = state_par[:state_par.index('Legal transitions')]
    board_state = JobBoard(JobLimits(program_root=ROOT, default_machine=default_machine()))
    snap = board_state.snapshot.to_dict()
    documented = _keys(state_par) - {'job/state'}
    assert set(snap) <= documented
    assert {s.value for s in JobState} <= documented
    assert set(spec.to_dict()) <= documented
    json.dumps(snap, allow_nan=False)


def test_documented_transitions_are_the_state_machine():
    from feed_axis_energy.cell import TRANSITIONS
    text = SECTION[SECTION.index('Legal transitions'):]
    text = text[:text.index('A `start` while')]
    documented = set()
    for part in text.split(';'):
        m = re.search(r'([a-z |]+) -> ([a-z |]+)', part.replace('\n', ' '))
        if m:
            for old in m.group(1).split('|'):
                for new in m.group(2).split('|'):
                    documented.add((old.strip().split()[-1], new.strip().split()[0]))
    actual = {(o.value, n.value) for o, ns in TRANSITIONS.items() for n in ns}
    assert documented == actual


def test_documented_live_keys_are_the_payload_keys():
    import numpy as np
    from feed_axis_energy.graph import live_payload, StreamingPower
    from feed_axis_energy.machine import load_machine
    par = SECTION[SECTION.index('`job/live` keys:'):]
    par = par[:par.index('The launcher sets')]
    documented = _keys(par)
    machine = load_machine(config_dir() / 'three_axis_mill_drives.yaml')
    stream = StreamingPower(('X', 'Y', 'Z'), braking=machine.braking, machine=machine)
    from feed_axis_energy.plan import Motion
    t = np.array([0.0, 0.001])
    z = np.zeros((2, 3))
    stream.update(t, np.ones((2, 3)), np.ones((2, 3)),
                  motion=Motion(t=t, axes=('X', 'Y', 'Z'), pos=z, vel=z, acc=z,
                                line=np.zeros(2, dtype=np.int32)))
    d = live_payload(stream, job_id='j', stamp_ns=0, clock='wall')
    assert set(d) <= documented
    assert set(d['electrical']) <= documented
    assert {'wall', 'simulation'} <= documented
