"""Bundles: the jobs of one program read once, planned once per plan, the same results."""
import concurrent.futures as cf
from pathlib import Path

import pytest

import feed_axis_energy.gcode as gcode_pkg
from feed_axis_energy.errors import PlanningError
import feed_axis_energy.plan as plan_pkg
from feed_axis_energy.sim.batch import BatchJob, run_job
from feed_axis_energy.sim.bundle import bundle_jobs, MAX_PLANS, run_batch, run_bundle

REPO = Path(__file__).resolve().parents[2]
MILL = str(REPO / 'config' / 'three_axis_mill.yaml')
DEMO = str(REPO / 'config' / 'demonstrator.yaml')
CONTOUR = REPO / 'config' / 'programs' / 'three_axis_contour.nc'


def _job(i, program=CONTOUR, machine=MILL, **kw):
    return BatchJob(index=i, program=Path(program).name, program_path=str(program),
                    machine=Path(machine).name, machine_path=machine, **kw)


def _variants():
    """Loads, overrides and machine changes of one program: three plans (as configured,
    feed override 0.6, rapid override 0.5; a mass or an efficiency does not change it)."""
    specs = [dict(), dict(load_kg=40.0), dict(load_kg=90.0, top_blocks=3),
             dict(feed_override=0.6), dict(feed_override=0.6, load_kg=40.0),
             dict(rapid_override=0.5, load_kg=10.0),
             dict(overrides=(('axes.*.table_mass_kg', 1.5, True),)),
             dict(overrides=(('axes.*.screw.efficiency', 0.8, False),), load_kg=5.0)]
    return [_job(i, **kw) for i, kw in enumerate(specs)]


def _dicts(results):
    return [r.to_dict() for r in results]


def test_bundled_results_equal_each_job_alone():
    jobs = _variants()
    (only,) = bundle_jobs(jobs, 1)
    assert sorted(only) == list(range(len(jobs)))
    alone = run_batch(jobs, share=0)
    bundled = run_batch(jobs, share=1)
    assert all(r.ok for r in alone)
    assert _dicts(bundled) == _dicts(alone)            # bit for bit, every key
    energies = [r.summary['energy_j']['total'] for r in bundled]
    assert len(set(energies)) == len(energies)          # every variant its own figures
    assert bundled[2].summary['top_blocks'] and 'rollups' in bundled[0].summary
    times = {r.summary['duration_s'] for r in bundled}
    assert len(times) >= 2                              # the feed override is slower


def test_a_bundle_reads_once_and_plans_once_per_plan(monkeypatch):
    reads, plans = [], []
    real_read, real_plan = gcode_pkg.iter_moves, plan_pkg.iter_window_motions

    def read(*a, **kw):
        reads.append(a[0])
        return real_read(*a, **kw)

    def planned(*a, **kw):
        plans.append(1)
        return real_plan(*a, **kw)
    monkeypatch.setattr(gcode_pkg, 'iter_moves', read)
    monkeypatch.setattr(plan_pkg, 'iter_window_motions', planned)
    jobs = _variants()
    results = run_bundle(jobs)
    assert all(r.ok for r in results)
    assert len(reads) == 1 and len(plans) == 3


def test_jobs_that_cannot_share_run_alone_and_groups_split(tmp_path):
    other = tmp_path / 'other.nc'
    other.write_text('G21 G90 G94\nG1 X50 F3000\nG1 X0\nM30\n')
    jobs = [_job(0), _job(1, load_kg=5.0), _job(2, method='samples'),
            _job(3, out=str(tmp_path / 'bag')), _job(4, max_samples=10 ** 9),
            _job(5, machine=str(tmp_path / 'missing.yaml')),
            _job(6, program=other), _job(7, program=other, load_kg=3.0),
            _job(8, load_kg=9.0), _job(9, machine=DEMO, program=other)]
    bundles = bundle_jobs(jobs, 1)
    assert sorted(i for b in bundles for i in b) == list(range(len(jobs)))
    assert [0, 1, 8] in [sorted(b) for b in bundles] and [6, 7] in bundles
    for alone in (2, 3, 4, 5, 9):                        # method, out, limit, no machine,
        assert [alone] in bundles                        # another way of reading
    two = bundle_jobs(jobs, 2)
    mine = [b for b in two if set(b) <= {0, 1, 8}]
    assert len(mine) == 2 and sorted(mine[0] + mine[1]) == [0, 1, 8]   # one per worker
    assert [6] in two and [7] in two


def test_a_bundle_holds_at_most_max_plans():
    jobs = [_job(i, feed_override=0.5 + 0.1 * i) for i in range(2 * MAX_PLANS + 1)]
    bundles = bundle_jobs(jobs, 1)
    assert len(bundles) == 3
    assert sorted(i for b in bundles for i in b) == list(range(len(jobs)))
    assert all(len(b) <= MAX_PLANS for b in bundles)


def test_an_error_of_the_read_fails_every_job_as_alone(tmp_path):
    bad = tmp_path / 'bad.nc'
    bad.write_text('G21 G90\nG1 X10 F600\nG33 Z-1 K1\nM30\n')
    jobs = [_job(i, program=bad, load_kg=float(i)) for i in range(3)]
    bundled = run_bundle(jobs)
    alone = [run_job(j) for j in jobs]
    assert not any(r.ok for r in bundled)
    assert _dicts(bundled) == _dicts(alone)
    assert 'bad.nc:3:1' in bundled[0].error and bundled[0].error_type == 'GcodeError'


def test_an_error_of_one_plan_fails_only_its_jobs(monkeypatch):
    real_plan = plan_pkg.iter_window_motions

    def planned(moves, limits, **kw):
        windows = real_plan(moves, limits, **kw)
        first = next(windows)
        yield first
        if first.win.t_end > 9.8:                      # the slow plan (override 0.6) only
            raise PlanningError('refused for the test', file='t.nc', line=7)
        yield from windows
    monkeypatch.setattr(plan_pkg, 'iter_window_motions', planned)
    jobs = _variants()
    results = run_bundle(jobs)
    failed = [r.job.index for r in results if not r.ok]
    assert failed == [3, 4]
    assert 'refused for the test' in results[3].error
    monkeypatch.setattr(plan_pkg, 'iter_window_motions', real_plan)
    for r in results:
        if r.ok:
            assert r.to_dict() == run_job(r.job).to_dict()


def test_share_on_an_executor_equals_serial_with_progress():
    jobs = _variants() + [_job(8, machine=DEMO, program=REPO / 'config' / 'programs'
                               / 'demonstrator_f500.nc', load_kg=3.0)]
    seen = []
    with cf.ThreadPoolExecutor(max_workers=2) as pool:
        shared = run_batch(jobs, executor=pool, share=2,
                           progress=lambda done, total, r: seen.append((done, total)))
    assert _dicts(shared) == _dicts(run_batch(jobs))
    assert seen == [(i + 1, len(jobs)) for i in range(len(jobs))]


@pytest.mark.parametrize('share', [1, 3])
def test_every_index_once_whatever_the_share(share):
    jobs = _variants()
    bundles = bundle_jobs(jobs, share)
    assert sorted(i for b in bundles for i in b) == list(range(len(jobs)))
    assert len(bundles) == min(share, len(jobs)) or len(bundles) > share


def test_energy_figures_are_the_full_summary_s_energy_within_its_error():
    jobs = [_job(i, figures='energy', **kw) for i, kw in enumerate(
        [dict(), dict(load_kg=40.0), dict(feed_override=0.6)])]
    full = run_batch([_job(j.index, load_kg=j.load_kg, feed_override=j.feed_override)
                      for j in jobs])
    lean = run_batch(jobs, share=1)
    assert _dicts(lean) == _dicts(run_batch(jobs))       # bundled = alone here too
    for a, b in zip(lean, full):
        s, f = a.summary, b.summary
        assert s['figures'] == 'energy' and 'figures' not in f
        assert 'energy_by_cause_j' not in s and 'rollups' not in s and 'top_blocks' not in s
        assert s['duration_s'] == f['duration_s'] and s['samples'] == f['samples']
        tol = s['quadrature_error_j']['total'] + f['quadrature_error_j']['total']
        assert abs(s['energy_j']['total'] - f['energy_j']['total']) <= tol


def test_with_drives_bundled_results_equal_each_job_alone():
    drives = str(REPO / 'config' / 'three_axis_mill_drives.yaml')
    jobs = [_job(0, machine=drives), _job(1, machine=drives, load_kg=30.0),
            _job(2, machine=drives, feed_override=0.7),
            _job(3, machine=drives, overrides=(('axes.*.drive.resistance_ohm', 2.0, True),)),
            _job(4, machine=drives, load_kg=30.0, figures='energy')]
    (only,) = bundle_jobs(jobs, 1)
    assert sorted(only) == list(range(len(jobs)))
    bundled = run_batch(jobs, share=1)
    assert all(r.ok for r in bundled)
    assert _dicts(bundled) == _dicts(run_batch(jobs, share=0))
    supply = [r.summary['electrical']['supply_energy_j']['total'] for r in bundled]
    assert len(set(supply[:4])) == 4                     # each variant its own drives
    assert supply[4] == pytest.approx(supply[1], rel=1e-9)   # the lean figures: the same
