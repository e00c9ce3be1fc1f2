"""Tests of the simulation glue and the summary (planner tests live with the planner)."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.gcode.load import load_gcode, parse_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.plan.motion import Motion
from feed_axis_energy.sim.simulate import simulate_motion, simulate_program, summarize

CONFIG = Path(__file__).resolve().parents[2] / 'config'
SUMMARY_KEYS = {'program', 'machine', 'load_kg', 'duration_s', 'samples', 'rate_hz', 'braking',
                'energy_j', 'peak_power_w', 'regenerated_energy_j', 'loss_energy_j',
                'top_blocks', 'causes', 'energy_by_cause_j', 'gross_by_cause_j',
                'braking_returned_j'}


@pytest.fixture(scope='module')
def demo():
    return load_machine(CONFIG / 'demonstrator.yaml')


def f_loss_n(v_m_s):
    """Force of eq. (3) in our unit reading, by hand: 1000 * 0.2505 * (1000 v)**0.3471 N."""
    return 1000.0 * 0.2505 * (1000.0 * v_m_s) ** 0.3471


def test_simulate_motion_and_summary(demo):
    t = np.arange(0.0, 3.0005, 0.001)
    v = np.where(t < 1.0, 0.0, 0.2)[:, None]
    line = np.where(t < 1.0, 4, 5).astype(np.int32)
    mot = Motion(t=t, axes=('X',), pos=np.cumsum(v, axis=0) * 0.001, vel=v,
                 acc=np.zeros_like(v), line=line, source='hand.nc')
    res = simulate_motion(mot, demo, load_kg=10.0)
    s = summarize(res, top_blocks=1)
    assert set(s) == SUMMARY_KEYS
    json.dumps(s)
    assert s['program'] == 'hand.nc' and s['machine'] == 'demonstrator' and s['load_kg'] == 10.0
    assert s['samples'] == t.size and s['rate_hz'] == pytest.approx(1000.0)
    assert s['duration_s'] == pytest.approx(3.0)
    # the jump of v at t = 1 s costs half an interval of loss power in the trapezoid rule
    p = f_loss_n(0.2) * 0.2
    assert s['energy_j']['X'] == pytest.approx(p * 2.0005, rel=1e-9)
    assert s['energy_j']['total'] == s['energy_j']['X']
    assert s['peak_power_w']['X'] == pytest.approx(p)
    assert s['regenerated_energy_j'] == 0.0
    # line 5 owns every interval ending at t >= 1 s: [0.999, 1] .. [2.999, 3], 2.001 s
    top = s['top_blocks']
    assert [{k: b[k] for k in ('line', 'energy_j', 'duration_s')} for b in top] == [
        {'line': 5, 'energy_j': pytest.approx(p * 2.0005), 'duration_s': pytest.approx(2.001)}]
    # constant speed on a horizontal, loss-free screw (eta = 1): friction only
    causes = top[0]['energy_by_cause_j']
    assert causes['friction'] == pytest.approx(p * 2.0005, rel=1e-9)
    assert all(value == 0.0 for name, value in causes.items() if name != 'friction')
    assert s['energy_by_cause_j']['friction']['X'] == pytest.approx(p * 2.0005, rel=1e-9)


PROGRAM = """G21 G90 G94 G61
G0 X0
G1 X100 F6000
G4 P0.5
X0
M30
"""


def test_simulate_program_conserves_energy(demo):
    res = simulate_program(parse_gcode(PROGRAM, file='rt.nc'), demo, load_kg=17.336)
    p = res.power
    assert res.program == 'rt.nc' and p.axes == ('X',)
    assert np.max(np.abs(res.motion.vel)) == pytest.approx(0.1, rel=1e-6)
    # strokes of 0.1 m at <= 0.1 m/s, plus the dwell
    assert res.motion.duration_s >= 2.0 + 0.5
    # Horizontal, eta = 1, rest to rest, regenerative: all net energy went into the losses.
    loss = np.sum(0.5 * (p.loss_power_w[1:, 0] + p.loss_power_w[:-1, 0]) * np.diff(p.t))
    assert p.total_energy_j[-1] == pytest.approx(loss, rel=1e-6)
    # and int F(v) dx <= F(vmax) * stroke since F grows with speed; ramps are short
    blocks = {b['line']: b['energy_j'] for b in summarize(res, top_blocks=10)['top_blocks']}
    for ln in (3, 5):
        assert 0.95 * f_loss_n(0.1) * 0.1 < blocks[ln] <= f_loss_n(0.1) * 0.1


@pytest.mark.parametrize('feed', [100, 300, 500])
def test_paper_programs_plan_and_stay_within_bounds(demo, feed):
    program = load_gcode(CONFIG / 'programs' / f'demonstrator_f{feed}.nc')
    res = simulate_program(program, demo)
    v = feed / 1000.0
    assert np.max(np.abs(res.motion.vel)) == pytest.approx(v, rel=1e-6)
    assert np.min(res.motion.pos) >= -1e-9 and np.max(res.motion.pos) <= 0.4 + 1e-9
    # 6 strokes of 0.4 m, 7 dwells of 1 s
    assert res.motion.duration_s >= 6 * 0.4 / v + 7.0
    strokes = [b['energy_j'] for b in summarize(res, top_blocks=100)['top_blocks']
               if b['energy_j'] > 1.0]
    assert len(strokes) == 6
    for e in strokes:
        assert 0.8 * f_loss_n(v) * 0.4 < e <= f_loss_n(v) * 0.4 * (1 + 1e-9)
    assert math.isfinite(summarize(res)['peak_power_w']['total'])


def test_three_axis_contour_runs():
    mill = load_machine(CONFIG / 'three_axis_mill.yaml')
    res = simulate_program(load_gcode(CONFIG / 'programs' / 'three_axis_contour.nc'),
                           mill, load_kg=30.0, options=mill.planner.options())
    s = summarize(res)
    assert set(s['energy_j']) == {'X', 'Y', 'Z', 'total'}
    assert s['braking'] == 'dissipated'
    assert np.all(res.power.power_w >= 0.0)
    assert s['energy_j']['total'] == pytest.approx(sum(s['energy_j'][a] for a in 'XYZ'),
                                                   rel=1e-9)
    # dissipated: what is drawn covers the losses plus what the brake resistor burns
    assert s['energy_j']['total'] >= s['loss_energy_j']
