"""Campaign runner: jobs as plain data, results in job order whatever the executor."""
import concurrent.futures as cf
import math
import multiprocessing
import os
from pathlib import Path
import pickle
import shutil
import tempfile

from hypothesis import given, settings, strategies as st
import pytest
import yaml

from feed_axis_energy.sim.batch import BatchJob, JobResult, MAX_JOBS, run_job
from feed_axis_energy.sim.bundle import run_batch
from feed_axis_energy.sim.batchspec import expand_programs, load_batch_file, make_jobs
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.gcode.load import iter_moves
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.sim.phasesum import summarize_phases
from feed_axis_energy.sim.stream import simulate_stream

REPO = Path(__file__).resolve().parents[2]
DEMO = str(REPO / 'config' / 'demonstrator.yaml')
MILL = str(REPO / 'config' / 'three_axis_mill.yaml')
PROGRAMS = REPO / 'config' / 'programs'


def _job(i, program, machine=DEMO, **kw):
    return BatchJob(index=i, program=Path(program).name, program_path=str(program),
                    machine=Path(machine).name, machine_path=machine, **kw)


@pytest.fixture()
def campaign(tmp_path):
    """Jobs of two shipped programs at two loads, a refused program and a missing one."""
    bad = tmp_path / 'bad.nc'
    bad.write_text('G21 G90\nG1 X10 F600\nG33 Z-1 K1\nM30\n')
    progs = [(p.name, str(p)) for p in (PROGRAMS / 'demonstrator_f500.nc',
                                        PROGRAMS / 'demonstrator_f100.nc')]
    progs += [('bad.nc', str(bad)), ('missing.nc', str(tmp_path / 'missing.nc'))]
    return make_jobs(progs, [('demonstrator.yaml', DEMO)], [0.0, 22.711], rate_hz=500.0)


def _dicts(results):
    return [r.to_dict() for r in results]


def test_serial_equals_process_pool_and_thread_pool(campaign):
    serial = run_batch(campaign)
    # forkserver: pytest may run threads (a Dask cluster of another test) that fork would copy
    ctx = multiprocessing.get_context('forkserver')
    with cf.ProcessPoolExecutor(max_workers=2, mp_context=ctx) as pool:
        procs = run_batch(campaign, executor=pool)
    with cf.ThreadPoolExecutor(max_workers=3) as pool:
        threads = run_batch(campaign, executor=pool)
    assert _dicts(serial) == _dicts(procs) == _dicts(threads)
    assert [r.job.index for r in procs] == list(range(len(campaign)))
    assert [r.ok for r in serial] == [True] * 4 + [False] * 4


def test_results_follow_job_order_not_completion_order():
    # the long program first: on two threads the short ones finish before it
    jobs = [_job(0, PROGRAMS / 'demonstrator_f100.nc', rate_hz=2000.0)]
    jobs += [_job(i, PROGRAMS / 'demonstrator_f500.nc', rate_hz=50.0) for i in range(1, 6)]
    order = []
    with cf.ThreadPoolExecutor(max_workers=2) as pool:
        results = run_batch(jobs, executor=pool,
                            progress=lambda done, total, r: order.append(r.job.index))
    assert [r.job.index for r in results] == list(range(6))
    assert sorted(order) == list(range(6))
    assert results[0].summary['samples'] > results[1].summary['samples']


def test_job_equals_direct_streaming_simulation():
    path = PROGRAMS / 'three_axis_contour.nc'
    result = run_job(_job(0, path, MILL, load_kg=50.0, top_blocks=3, method='samples'))
    machine = load_machine(MILL)
    # as simulate's streamed path runs it: the moves read with the machine's G-code settings,
    # the roll-ups from their operation context
    stream = iter_moves(path, **machine.gcode_keywords())
    ref, _ = simulate_stream(stream, machine, file=stream.file, load_kg=50.0, top_blocks=3,
                             rollup=True, context=stream.context)
    ref['program'] = 'three_axis_contour.nc'
    ref['method'] = 'samples'
    assert result.ok and result.summary == ref
    # by default by phase, as simulate
    phased = run_job(_job(0, path, MILL, load_kg=50.0, top_blocks=3))
    stream = iter_moves(path, **machine.gcode_keywords())
    by_phase, _ = summarize_phases(stream, machine, file=stream.file, load_kg=50.0,
                                   top_blocks=3, rollup=True, context=stream.context)
    by_phase['program'] = 'three_axis_contour.nc'
    assert phased.ok and phased.summary == by_phase
    # the roll-ups add up to the program's energy
    for group in ('operation', 'tool', 'subroutine'):
        items = result.summary['rollups'][group]
        assert math.isclose(math.fsum(it['energy_j'] for it in items),
                            ref['energy_j']['total'], rel_tol=1e-9)


def test_load_rate_and_profile_reach_the_simulation():
    prog = PROGRAMS / 'demonstrator_f300.nc'
    light, heavy = run_batch([_job(0, prog), _job(1, prog, load_kg=22.711)])
    # same motion; the heavier table needs more power to accelerate
    assert light.summary['samples'] == heavy.summary['samples']
    assert heavy.summary['peak_power_w']['X'] > light.summary['peak_power_w']['X']
    slow = run_job(_job(0, prog, rate_hz=100.0)).summary
    assert slow['samples'] == pytest.approx(slow['duration_s'] * 100.0 + 1, abs=1.0)
    assert slow['rate_hz'] == pytest.approx(100.0)
    trap = run_job(_job(0, prog, profile='trapezoid')).summary
    assert trap['duration_s'] != light.summary['duration_s']


def test_failed_job_is_a_row_naming_the_place(campaign):
    results = run_batch(campaign)
    bad = [r for r in results if r.job.program == 'bad.nc']
    assert len(bad) == 2 and not any(r.ok for r in bad)
    assert bad[0].error_type == 'GcodeError'
    assert 'bad.nc:3:1' in bad[0].error and 'G33' in bad[0].error
    missing = [r for r in results if r.job.program == 'missing.nc'][0]
    assert 'missing.nc' in missing.error and 'cannot read' in missing.error
    row = missing.to_dict()
    assert row['status'] == 'failed' and 'summary' not in row


def test_max_samples_fails_the_job_before_simulating():
    r = run_job(_job(0, PROGRAMS / 'demonstrator_f100.nc', max_samples=1000))
    assert not r.ok and r.error_type == 'PlanningError'
    assert 'max_samples 1,000' in r.error and 'Hz fits' in r.error


class _LosingExecutor(cf.Executor):
    """Every other job's worker "dies": its future ends in an exception."""

    def submit(self, fn, *args, **kwargs):
        future = cf.Future()
        job = args[0]
        if job.index % 2:
            future.set_exception(cf.process.BrokenProcessPool('worker died'))
        else:
            future.set_result(fn(*args, **kwargs))
        return future


def test_lost_job_is_a_worker_error_row():
    jobs = [_job(i, PROGRAMS / 'demonstrator_f500.nc', rate_hz=100.0) for i in range(4)]
    results = run_batch(jobs, executor=_LosingExecutor())
    assert [r.ok for r in results] == [True, False, True, False]
    assert results[1].error_type == 'WorkerError'
    assert 'worker died' in results[1].error


def test_jobs_and_results_pickle():
    job = _job(0, PROGRAMS / 'demonstrator_f500.nc', rate_hz=100.0)
    result = run_job(job)
    assert pickle.loads(pickle.dumps(job)) == job
    assert pickle.loads(pickle.dumps(result)).to_dict() == result.to_dict()
    assert isinstance(result, JobResult)


@pytest.mark.parametrize('kw', [{'load_kg': math.nan}, {'load_kg': -1.0},
                                {'rate_hz': 0.0}, {'rate_hz': math.inf},
                                {'profile': 'cubic'}, {'max_samples': -1}])
def test_invalid_job_is_refused(kw):
    with pytest.raises(ConfigError, match='job 1'):
        _job(0, PROGRAMS / 'demonstrator_f500.nc', **kw)


def test_too_many_jobs_refused_before_building_them():
    progs = [(f'p{i}.nc', f'/p{i}.nc') for i in range(1000)]
    with pytest.raises(ConfigError, match='1000 programs x 1 machines x 101 loads'):
        make_jobs(progs, [('m', DEMO)], [0.0] * 101)
    assert MAX_JOBS == 100_000
    with pytest.raises(ConfigError, match='no jobs'):
        make_jobs([], [('m', DEMO)], [0.0])


def test_expand_programs_files_globs_and_directories(tmp_path):
    d = tmp_path / 'parts'
    d.mkdir()
    for name in ('b.nc', 'a.ngc', 'notes.txt', 'c.TAP'):
        (d / name).write_text('G1 X1 F100\n')
    (d / 'sub').mkdir()
    found = expand_programs(['parts', 'parts/*.nc', 'x.nc'], base=tmp_path)
    assert [s for s, _ in found] == ['parts/a.ngc', 'parts/b.nc', 'parts/c.TAP',
                                     'parts/b.nc', 'x.nc']
    assert all(os.path.isabs(p) for _, p in found)
    assert found[-1][1] == str(tmp_path / 'x.nc')
    with pytest.raises(ConfigError, match="no program file matches 'parts/\\*.gcode'"):
        expand_programs(['parts/*.gcode'], base=tmp_path)
    with pytest.raises(ConfigError, match="directory 'parts/sub' holds no program"):
        expand_programs(['parts/sub'], base=tmp_path)


def test_batch_file(tmp_path):
    (tmp_path / 'progs').mkdir()
    (tmp_path / 'progs' / 'a.nc').write_text('G1 X1 F100\n')
    f = tmp_path / 'campaign.yaml'
    f.write_text('programs: [progs/*.nc]\nmachines: [m.yaml]\nloads_kg: [0, 17.336]\n'
                 'rate_hz: 250\nprofile: trapezoid\n')
    spec = load_batch_file(f)
    assert spec.programs == (('progs/a.nc', str(tmp_path / 'progs' / 'a.nc')),)
    assert spec.machines == (('m.yaml', str(tmp_path / 'm.yaml')),)
    assert spec.loads_kg == (0.0, 17.336)
    assert (spec.rate_hz, spec.profile) == (250.0, 'trapezoid')


@pytest.mark.parametrize('text, match', [
    ('- a.nc\n', 'expected a mapping'),
    ('programs: [a.nc]\nmachine: [m.yaml]\n', 'machine: unknown key'),
    ('machines: [m.yaml]\n', 'programs: missing'),
    ('programs: []\n', 'programs: expected a non-empty list'),
    ('programs: [a.nc, 3]\n', r'programs\[1\]: expected a path'),
    ('programs: [a.nc]\nloads_kg: [0, .nan]\n', r'loads_kg\[1\]: expected a number'),
    ('programs: [a.nc]\nloads_kg: [true]\n', r'loads_kg\[0\]: expected a number'),
    ('programs: [a.nc]\nrate_hz: 0\n', 'rate_hz: expected a number > 0'),
    ('programs: [a.nc]\nprofile: [jerk]\n', 'profile: expected one of'),
    ('programs: [nothing/*.nc]\n', 'no program file matches'),
    ('programs: [a.nc\n', 'YAML'),
])
def test_bad_batch_file_names_file_and_key(tmp_path, text, match):
    f = tmp_path / 'c.yaml'
    f.write_text(text)
    with pytest.raises(ConfigError, match=match) as err:
        load_batch_file(f)
    assert str(f) in str(err.value)


_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-10**30, 10**30)
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=20),
    lambda inner: (st.lists(inner, max_size=4)
                   | st.dictionaries(st.text(max_size=8), inner, max_size=4)),
    max_leaves=10)


@settings(derandomize=True, database=None, deadline=None, max_examples=150)
@given(st.dictionaries(st.sampled_from(['programs', 'machines', 'loads_kg', 'rate_hz',
                                        'profile', 'jobs']), _VALUES, max_size=5))
def test_any_batch_file_is_a_spec_or_a_config_error(doc):
    d = Path(tempfile.mkdtemp(prefix='fae-batch-'))
    try:
        f = d / 'b.yaml'
        f.write_text(yaml.safe_dump(doc))
        try:
            spec = load_batch_file(f)
        except ConfigError as err:
            assert str(f) in str(err) and len(str(err)) < 400
        else:
            assert spec.programs and all(os.path.isabs(p) for _, p in spec.programs)
            assert all(math.isfinite(x) and 0 <= x <= 1e6 for x in spec.loads_kg)
            assert spec.rate_hz is None or 0 < spec.rate_hz <= 1e6
    finally:
        shutil.rmtree(d, ignore_errors=True)
