"""Job requests: every hostile input refused with the field and the reason."""
import hashlib
import math
import os
from pathlib import Path
import socket

import pytest

from feed_axis_energy.cell import (check_job_id, check_load, file_sha256, job_machine,
                                   JobLimits, JobSpec, MAX_JOB_ID_CHARS, parse_job_request)
from feed_axis_energy.errors import JobError
from feed_axis_energy.paths import config_dir, default_machine

PROGRAM = 'G21 G90 G94\nG1 X10 F3000\n'


@pytest.fixture
def root(tmp_path):
    r = tmp_path / 'programs'
    (r / 'sub').mkdir(parents=True)
    (r / 'a.nc').write_text(PROGRAM)
    (r / 'sub' / 'b.nc').write_text(PROGRAM + 'G1 X0\n')
    (tmp_path / 'outside.nc').write_text(PROGRAM)
    return r


@pytest.fixture
def limits(root):
    return JobLimits(program_root=root, default_machine=default_machine(),
                     machine_root=config_dir(), max_load_kg=500.0, max_program_bytes=4096)


def _refused(request, limits, field, words):
    with pytest.raises(JobError) as info:
        parse_job_request(request, limits)
    assert info.value.field == field, str(info.value)
    assert words in str(info.value), str(info.value)
    return info.value


def test_a_good_request_gives_a_resolved_spec_with_the_program_hash(root, limits):
    spec = parse_job_request({'job_id': 'job-1', 'program': 'sub/b.nc', 'load_kg': 12},
                             limits)
    assert spec.program == Path(os.path.realpath(root / 'sub' / 'b.nc'))
    assert spec.program_sha256 == hashlib.sha256((PROGRAM + 'G1 X0\n').encode()).hexdigest()
    assert spec.load_kg == 12.0 and isinstance(spec.load_kg, float)
    assert spec.machine == default_machine()
    # absolute paths inside the root are fine too, and the JSON form round-trips
    spec2 = parse_job_request({'job_id': 'j2', 'program': str(root / 'a.nc')}, limits)
    assert spec2.load_kg == 0.0
    assert JobSpec.from_dict(spec.to_dict()) == spec


@pytest.mark.parametrize('job_id, words', [
    ('', 'must not be empty'),
    ('x' * (MAX_JOB_ID_CHARS + 1), f'at most {MAX_JOB_ID_CHARS} characters'),
    ('a b', 'characters other than'),
    ('a/b', 'characters other than'),
    ('../x', 'characters other than'),
    ('.hidden', 'start with a letter or digit'),
    ('tab\there', 'characters other than'),
    ('nul\x00', 'characters other than'),
    ('é', 'characters other than'),
    (7, 'must be text'),
    (None, 'must be text'),
    (['a'], 'must be text'),
])
def test_job_ids_are_bounded_and_printable(job_id, words, limits):
    err = _refused({'job_id': job_id, 'program': 'a.nc'}, limits, 'job_id', words)
    assert '\x00' not in str(err) and '\t' not in str(err)


def test_the_longest_job_id_is_accepted():
    assert check_job_id('A' * MAX_JOB_ID_CHARS) == 'A' * MAX_JOB_ID_CHARS


@pytest.mark.parametrize('program, words', [
    ('../outside.nc', '".." is not allowed'),
    ('sub/../../outside.nc', '".." is not allowed'),
    ('missing.nc', 'No such file'),
    ('sub', 'is a directory, not a regular file'),
    ('', 'must be a path of 1 to'),
    ('a.nc\x00.txt', 'without NUL'),
    ('x' * 5000, 'must be a path of 1 to'),
    (12, 'must be a path (text)'),
    ('/dev/null', 'outside the program root'),
    ('/etc/passwd', 'outside the program root'),
])
def test_programs_must_be_regular_files_inside_the_root(program, words, limits):
    _refused({'job_id': 'j', 'program': program}, limits, 'program', words)


def test_a_symlink_out_of_the_root_is_refused_one_inside_is_followed(root, limits, tmp_path):
    (root / 'escape.nc').symlink_to(tmp_path / 'outside.nc')
    (root / 'dir_escape').symlink_to(tmp_path)
    (root / 'alias.nc').symlink_to(root / 'a.nc')
    _refused({'job_id': 'j', 'program': 'escape.nc'}, limits, 'program',
             'outside the program root')
    _refused({'job_id': 'j', 'program': 'dir_escape/outside.nc'}, limits, 'program',
             'through a symbolic link')
    spec = parse_job_request({'job_id': 'j', 'program': 'alias.nc'}, limits)
    assert spec.program == Path(os.path.realpath(root / 'a.nc'))


def test_device_files_fifos_and_sockets_are_refused(root, tmp_path, limits):
    os.mkfifo(root / 'pipe.nc')
    _refused({'job_id': 'j', 'program': 'pipe.nc'}, limits, 'program', 'is a FIFO')
    (root / 'null.nc').symlink_to('/dev/null')    # leaves the root first
    _refused({'job_id': 'j', 'program': 'null.nc'}, limits, 'program', 'outside')
    dev_limits = JobLimits(program_root=Path('/dev'), default_machine=default_machine())
    _refused({'job_id': 'j', 'program': 'null'}, dev_limits, 'program', 'is a device')
    sock_path = root / 's.nc'
    s = socket.socket(socket.AF_UNIX)
    try:
        s.bind(str(sock_path))
        _refused({'job_id': 'j', 'program': 's.nc'}, limits, 'program', 'is a socket')
    finally:
        s.close()


def test_a_program_above_the_size_limit_is_refused(root, limits):
    (root / 'big.nc').write_text('G1 X1\n' * 1000)
    _refused({'job_id': 'j', 'program': 'big.nc'}, limits, 'program', 'above the limit')


def test_file_sha256_does_not_follow_a_final_link_or_wait_on_a_fifo(root):
    (root / 'link.nc').symlink_to(root / 'a.nc')
    with pytest.raises(JobError, match='link.nc'):
        file_sha256(root / 'link.nc', max_bytes=100)
    os.mkfifo(root / 'fifo')
    with pytest.raises(JobError, match='not a regular file'):
        file_sha256(root / 'fifo', max_bytes=100)     # returns at once, no writer needed


@pytest.mark.parametrize('load, words', [
    (math.nan, 'must be finite'), (math.inf, 'must be finite'), (-math.inf, 'must be finite'),
    (-0.001, 'must be >= 0 kg'), (1e300, 'above the limit of 500 kg'),
    (500.0001, 'above the limit'), ('5', 'must be a number'), (True, 'must be a number'),
    (None, 'must be a number'), ([1], 'must be a number'),
])
def test_loads_must_be_finite_non_negative_and_bounded(load, words, limits):
    _refused({'job_id': 'j', 'program': 'a.nc', 'load_kg': load}, limits, 'load_kg', words)


def test_the_load_limit_itself_is_accepted():
    assert check_load(500, max_load_kg=500.0) == 500.0
    assert check_load(0, max_load_kg=500.0) == 0.0


def test_unknown_keys_and_non_objects_are_refused(limits):
    _refused({'job_id': 'j', 'program': 'a.nc', 'load': 5}, limits, 'request',
             "unknown key(s) 'load'")
    _refused(['a.nc'], limits, 'request', 'a mapping')
    _refused({'job_id': 'j'}, limits, 'program', 'is required')


def test_a_machine_preset_resolves_inside_the_machine_root(limits, tmp_path):
    spec = parse_job_request({'job_id': 'j', 'program': 'a.nc',
                              'machine': 'three_axis_mill.yaml'}, limits)
    assert spec.machine == Path(os.path.realpath(config_dir() / 'three_axis_mill.yaml'))
    assert set(job_machine(spec).axis_names) >= {'X', 'Y', 'Z'}
    _refused({'job_id': 'j', 'program': 'a.nc', 'machine': '../x.yaml'}, limits, 'machine',
             '".."')
    _refused({'job_id': 'j', 'program': 'a.nc', 'machine': str(tmp_path / 'outside.nc')},
             limits, 'machine', 'outside the machine root')
    one = JobLimits(program_root=limits.program_root, default_machine=default_machine())
    _refused({'job_id': 'j', 'program': 'a.nc', 'machine': 'demonstrator.yaml'}, one,
             'machine', 'may not name another')


def test_overrides_are_checked_then_validated_with_the_machine(limits):
    spec = parse_job_request({'job_id': 'j', 'program': 'a.nc',
                              'overrides': {'axes.X.table_mass_kg': 80}}, limits)
    assert spec.overrides == (('axes.X.table_mass_kg', 80.0),)
    assert job_machine(spec).axis('X').table_mass_kg == 80.0
    for bad, words in [({'axes.X.table_mass_kg': math.nan}, 'finite number'),
                       ({'axes.X.table_mass_kg': 'heavy'}, 'finite number'),
                       ({'a b': 1}, 'not a dotted machine-config key'),
                       ([1, 2], 'must be a mapping'),
                       ({f'k{i}': 1 for i in range(40)}, 'at most 32 keys')]:
        _refused({'job_id': 'j', 'program': 'a.nc', 'overrides': bad}, limits, 'overrides',
                 words)
    wrong = parse_job_request({'job_id': 'j', 'program': 'a.nc',
                               'overrides': {'axes.X.table_mass_kg': -5}}, limits)
    with pytest.raises(JobError) as info:
        job_machine(wrong)
    assert info.value.field == 'overrides' and 'table_mass_kg' in str(info.value)


def test_limits_need_existing_directories_and_a_finite_load_limit(tmp_path):
    with pytest.raises(JobError, match='not a directory'):
        JobLimits(program_root=tmp_path / 'nope', default_machine=default_machine())
    with pytest.raises(JobError, match='max_load_kg'):
        JobLimits(program_root=tmp_path, default_machine=default_machine(),
                  max_load_kg=math.nan)


def test_spec_from_dict_refuses_missing_keys():
    with pytest.raises(JobError, match='not a job spec'):
        JobSpec.from_dict({'job_id': 'j'})


@pytest.mark.parametrize('kind', ['dir', 'file', 'dangling link'])
def test_a_job_id_whose_recording_exists_is_refused(root, tmp_path, kind):
    rec = tmp_path / 'recordings'
    rec.mkdir()
    limits = JobLimits(program_root=root, default_machine=default_machine(), record_root=rec)
    assert parse_job_request({'job_id': 'j1', 'program': 'a.nc'}, limits).job_id == 'j1'
    target = rec / 'j1'
    if kind == 'dir':
        target.mkdir()
    elif kind == 'file':
        target.write_text('')
    else:
        target.symlink_to(tmp_path / 'nowhere')
    _refused({'job_id': 'j1', 'program': 'a.nc'}, limits, 'job_id', 'exists already')
    # a root that does not exist yet (the recorder creates it) refuses nothing
    later = JobLimits(program_root=root, default_machine=default_machine(),
                      record_root=tmp_path / 'not-yet')
    assert parse_job_request({'job_id': 'j1', 'program': 'a.nc'}, later).job_id == 'j1'
