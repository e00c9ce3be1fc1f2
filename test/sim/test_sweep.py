"""What-if sweeps (core): the --vary grammar, machine variants, overrides, Pareto front."""
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from feed_axis_energy.sim.batch import BatchJob, run_job
from feed_axis_energy.errors import ConfigError
from feed_axis_energy.machine.file import load_machine, machine_to_dict
from feed_axis_energy.gcode.program import MoveKind, straight_move
from feed_axis_energy.sim.sweep import (apply_overrides, override_moves, parse_vary, pareto_front,
                                        resolve_paths, sweep_rows, variant_machine)
from feed_axis_energy.machine.limits import AxisLimits

ROOT = Path(__file__).resolve().parents[2]
MILL = ROOT / 'config' / 'three_axis_mill.yaml'
DEMO = ROOT / 'config' / 'demonstrator.yaml'
CONTOUR = ROOT / 'config' / 'programs' / 'three_axis_contour.nc'


def test_values_ranges_and_aliases():
    v = parse_vary('feed_override=0.5, 1,1.5')
    assert v.key == 'feed_override' and v.values == (0.5, 1.0, 1.5) and v.is_run_key
    r = parse_vary('jerk=10:50:5')
    assert r.key == 'axes.*.limits.jerk_m_s3'
    assert r.values == pytest.approx((10.0, 20.0, 30.0, 40.0, 50.0))
    f = parse_vary('axes.Z.table_mass_kg*=1,2')
    assert f.relative and f.key == 'axes.Z.table_mass_kg' and f.values == (1.0, 2.0)
    b = parse_vary('braking=regenerative,resistive')
    assert b.values == ('regenerative', 'resistive') and not b.is_run_key


@pytest.mark.parametrize('spec, words', [
    ('feed_override', 'NAME=VALUES'),
    ('=1,2', 'NAME=VALUES'),
    ('feed_override=0,1', '> 0'),
    ('rapid_override=0.5,2', '<= 1'),
    ('load_kg=-1', '>= 0'),
    ('feed_override=fast', 'numbers'),
    ('lead*=a,b', 'numbers'),
    ('lead*=-1,2', '>= 0'),
    ('lead=1,,2', 'commas'),
    ('lead=1,1', 'twice'),
    ('lead=1:2', 'START:STOP:N'),
    ('lead=1:2:1', 'whole number of 2'),
    ('lead=1:2:2.5', 'whole number of 2'),
    ('lead=nan,1', 'finite'),
    ('axes..lead=1', 'dotted path'),
    ('feed_override*=1,2', 'factor already'),
])
def test_bad_specs_are_config_errors(spec, words):
    with pytest.raises(ConfigError, match='vary') as err:
        parse_vary(spec)
    assert words in str(err.value)


def test_paths_wildcards_and_unknown_keys():
    d = machine_to_dict(load_machine(MILL))
    paths = resolve_paths('axes.*.screw.lead_m', d)
    assert paths == [('axes', a, 'screw', 'lead_m') for a in d['axes']]
    assert resolve_paths('braking', d) == [('braking',)]
    with pytest.raises(ConfigError, match="no key 'scerw'"):
        resolve_paths('axes.X.scerw.lead_m', d)
    with pytest.raises(ConfigError, match='holds a value'):
        resolve_paths('braking.x', d)


def test_overrides_copy_and_relative_keeps_axis_ratios():
    d = machine_to_dict(load_machine(MILL))
    before = {a: v['limits']['jerk_m_s3'] for a, v in d['axes'].items()}
    out = apply_overrides(d, [('axes.*.limits.jerk_m_s3', 0.5, True)])
    assert {a: v['limits']['jerk_m_s3'] for a, v in d['axes'].items()} == before
    assert {a: v['limits']['jerk_m_s3'] for a, v in out['axes'].items()} == pytest.approx(
        {a: 0.5 * j for a, j in before.items()})
    with pytest.raises(ConfigError, match='cannot be multiplied'):
        apply_overrides(d, [('braking', 2.0, True)])


def test_variant_out_of_range_names_the_key():
    with pytest.raises(ConfigError, match='lead_m'):
        variant_machine(str(DEMO), (('axes.*.screw.lead_m', -0.01, False),))


def test_pareto_front_by_hand():
    pts = [(10.0, 100.0), (12.0, 90.0), (12.0, 95.0), (11.0, 120.0), (15.0, 90.0),
           (9.0, 150.0), (10.0, 100.0)]
    assert pareto_front(pts) == [True, True, False, False, False, True, True]
    assert pareto_front([]) == []


def test_override_moves_feed_and_rapid():
    lim = {'X': AxisLimits(0.6, 2.5, 50.0), 'Y': AxisLimits(0.3, 2.5, 50.0)}
    g1 = straight_move(MoveKind.LINEAR, 2, (0, 0, 0), (0.1, 0, 0), 0.05, True, 0.1)
    g0 = straight_move(MoveKind.RAPID, 3, (0.1, 0, 0), (0.2, 0.1, 0), math.inf, True,
                       0.1 * math.sqrt(2.0))
    out = list(override_moves([g1, g0], feed=0.5, rapid=0.25, limits=lim))
    assert out[0].feed_m_s == pytest.approx(0.025)
    # 45 degrees in XY: Y (0.3 m/s) limits first, at a path speed of 0.3 * sqrt(2)
    assert out[1].feed_m_s == pytest.approx(0.25 * 0.3 * math.sqrt(2.0))
    assert list(override_moves([g1, g0], limits=lim)) == [g1, g0]


def _energy(tmp_path, text, **job):
    prog = tmp_path / f'p{len(list(tmp_path.iterdir()))}.nc'
    prog.write_text(text)
    kw = dict(index=0, program=prog.name, program_path=str(prog), machine='m',
              machine_path=str(job.pop('machine', DEMO)), rate_hz=500.0)
    res = run_job(BatchJob(**kw, **job))
    assert res.ok, res.error
    return res.summary


def test_feed_override_equals_the_slower_program(tmp_path):
    """A 50 % feed override on F600 runs exactly as the program written with F300."""
    body = 'G21 G90 G61\nG1 X{} F{}\nG1 X0\nM30\n'
    slow = _energy(tmp_path, body.format(200, 300))
    over = _energy(tmp_path, body.format(200, 600), feed_override=0.5)
    assert over['duration_s'] == pytest.approx(slow['duration_s'], rel=1e-12)
    assert over['energy_j']['total'] == pytest.approx(slow['energy_j']['total'], rel=1e-12)


def test_machine_variant_equals_the_edited_file(tmp_path):
    """Doubling the table mass by --vary equals a machine file with the doubled mass."""
    d = yaml.safe_load(DEMO.read_text())
    d['axes']['X']['table_mass_kg'] *= 2.0
    edited = tmp_path / 'edited.yaml'
    edited.write_text(yaml.safe_dump(d))
    body = 'G21 G90 G61\nG1 X300 F30000\nG1 X0\nM30\n'
    ref = _energy(tmp_path, body, machine=edited)
    var = _energy(tmp_path, body, overrides=(('axes.*.table_mass_kg', 2.0, True),))
    base = _energy(tmp_path, body)
    assert var['energy_j']['total'] == pytest.approx(ref['energy_j']['total'], rel=1e-12)
    assert var['peak_power_w']['total'] == pytest.approx(ref['peak_power_w']['total'],
                                                         rel=1e-12)
    # the heavier table asks more power to accelerate; its energy is the same (the paper's
    # loss depends on the feed only, regenerative braking returns the kinetic energy: by
    # phase exactly, the samples differ from it at 1e-10)
    assert var['peak_power_w']['total'] > base['peak_power_w']['total']
    assert var['energy_j']['total'] == pytest.approx(base['energy_j']['total'], rel=1e-12)


def test_rapid_override_slows_rapids_only(tmp_path):
    body = 'G21 G90 G61\nG0 X300\nG1 X0 F3000\nM30\n'
    base = _energy(tmp_path, body)
    slow = _energy(tmp_path, body, rapid_override=0.25)
    # a jerk-limited move that reaches its cruise speed v (and the acceleration limit a, as
    # v >= a^2/j here) lasts L/v + v/a + a/j: the rapid of 0.3 m at 0.6 m/s, or at
    # 0.25 * 0.6 m/s with the override (a = 2.5 m/s^2, j = 50 m/s^3 in the demonstrator)

    def move_s(v):
        return 0.3 / v + v / 2.5 + 2.5 / 50.0
    expected = move_s(0.15) - move_s(0.6)
    assert slow['duration_s'] - base['duration_s'] == pytest.approx(expected, abs=2.0 / 500)
    assert slow['energy_j']['total'] < base['energy_j']['total']


def test_overrides_refused_on_trajectory_csv(tmp_path):
    csv = tmp_path / 't.csv'
    csv.write_text('t,X\n0,0\n0.001,0\n')
    res = run_job(BatchJob(index=0, program='t.csv', program_path=str(csv), machine='m',
                           machine_path=str(DEMO), feed_override=0.5))
    assert not res.ok and 'trajectory CSV' in res.error


def test_rows_carry_the_loss_function_uncertainty_where_known():
    from types import SimpleNamespace
    from feed_axis_energy.report.sweep_report import render_sweep

    def result(e, sd=None):
        summary = {'duration_s': 10.0, 'energy_j': {'total': e}}
        if sd is not None:
            summary['energy_uncertainty'] = {'energy_sd_j': {'total': sd}}
        return SimpleNamespace(ok=True, summary=summary, error='')
    rows = sweep_rows([('p.nc', None, result(200.0, 3.0)), ('p.nc', (2.0,), result(100.0, 1.5)),
                       ('q.nc', None, result(50.0))])
    assert [r.energy_sd_j for r in rows[:2]] == [3.0, 1.5] and math.isnan(rows[2].energy_sd_j)
    assert rows[1].to_dict([])['energy_sd_j'] == 1.5 and 'energy_sd_j' not in rows[2].to_dict([])
    html = render_sweep(rows, ['lead'])
    assert '±1.5 % from the loss-function uncertainty' in html     # 1.5 J of 100 J
    assert 'not known' not in html.split('q.nc')[0] and 'uncertainty [J]' in html


def _peak_path_speed(motion) -> float:
    return float(np.max(np.linalg.norm(motion.vel, axis=1)))


def test_rapid_override_uses_the_planners_speed_limit_per_axis():
    # Per-axis speed limits and a rapid along (0.2, 0.4, 0.4), 0.6 m long: by hand X allows
    # 0.5 / (1/3) = 1.5, Y 0.2 / (2/3) = 0.3, Z 0.3 / (2/3) = 0.45 m/s, so Y limits the path
    # speed to 0.3 m/s. The planned rapid cruises there; the override at 0.5 runs the same
    # move at half of it, i.e. sweep and planner agree on the limit.
    from feed_axis_energy.gcode.program import Program
    from feed_axis_energy.plan.trajectory import plan
    lim = {'X': AxisLimits(0.5, 20.0, 2000.0), 'Y': AxisLimits(0.2, 20.0, 2000.0),
           'Z': AxisLimits(0.3, 20.0, 2000.0)}
    end = (0.2, 0.4, 0.4)
    g0 = straight_move(MoveKind.RAPID, 1, (0.0, 0.0, 0.0), end, math.inf, True, 0.6)
    program = Program('rapid.nc', (g0,))
    full = plan(program, lim)
    assert _peak_path_speed(full) == pytest.approx(0.3, rel=1e-9)
    half = plan(Program('rapid.nc', tuple(override_moves([g0], rapid=0.5, limits=lim))), lim)
    assert _peak_path_speed(half) == pytest.approx(0.5 * 0.3, rel=1e-9)
    (moved,) = override_moves([g0], rapid=0.5, limits=lim)
    assert moved.feed_m_s == pytest.approx(0.5 * 0.3, rel=1e-12)


def test_rapid_override_has_no_rule_of_its_own(monkeypatch):
    # One source of truth: the override follows whatever the planner's rule says.
    import feed_axis_energy.plan as plan
    lim = {'X': AxisLimits(0.6, 2.5, 50.0)}
    g0 = straight_move(MoveKind.RAPID, 3, (0.0, 0, 0), (0.1, 0, 0), math.inf, True, 0.1)
    monkeypatch.setattr(plan, 'line_speed_limits', lambda u, vmax: np.float64(0.125))
    (moved,) = override_moves([g0], rapid=0.5, limits=lim)
    assert moved.feed_m_s == 0.0625


def test_variants_read_the_machine_file_once(tmp_path):
    path = tmp_path / 'machine.yaml'
    path.write_bytes(DEMO.read_bytes())
    first = variant_machine(str(path), (('axes.*.limits.jerk_m_s3', 0.5, True),))
    path.unlink()               # the other variants come from the parsed file
    base = variant_machine(str(path), ())
    second = variant_machine(str(path), (('axes.*.limits.jerk_m_s3', 2.0, True),))
    want = load_machine(DEMO)
    assert base == want
    for got, factor in ((first, 0.5), (second, 2.0)):
        assert got.axis_names == want.axis_names
        for axis in want.axes:
            assert got.axis(axis.name).limits.jerk_m_s3 == factor * axis.limits.jerk_m_s3
