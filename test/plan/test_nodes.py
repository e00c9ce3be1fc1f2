"""Quadrature nodes on the planned phases (plan/nodes.py, issue 23 part 1)."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from feed_axis_energy.gcode.load import load_gcode, parse_gcode
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.machine.limits import AxisLimits, PlannerOptions
from feed_axis_energy.physics import apply_braking, compute_dynamics
from feed_axis_energy.plan.nodes import gauss_legendre, iter_nodes
from feed_axis_energy.plan.stream import estimate_plan
from feed_axis_energy.sim.stream import simulate_stream

REPO = Path(__file__).resolve().parents[2]
LIM = {'X': AxisLimits(0.5, 3.0, 60.0), 'Y': AxisLimits(0.4, 2.0, 40.0),
       'Z': AxisLimits(0.3, 1.5, 30.0)}
# straight blocks only, some passed at speed inside a group (G64), some stopping (G61),
# a dwell, a reversal
LINES = """G21 G90 G64
G1 X10 Y5 F3000
X25 Y5
X40 Y-3 Z2
G61 X0 Y0 Z0
G4 P0.3
G64 G1 X-12 F1200
X-12 Y20
M2
"""


def _nodes(text, order, options=PlannerOptions(profile='jerk')):
    prog = parse_gcode(text, file='t.nc')
    return list(iter_nodes(prog.moves, LIM, options=options, file='t.nc', order=order))


def test_the_rule_integrates_polynomials_of_degree_2n_minus_1_exactly() -> None:
    x, w = gauss_legendre(4)
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    for deg in range(8):
        assert float(w @ x ** deg) == pytest.approx(1.0 / (deg + 1), rel=1e-13)
    assert abs(float(w @ x ** 8) - 1.0 / 9) > 1e-6        # degree 8: not exact any more
    with pytest.raises(ValueError, match='order'):
        gauss_legendre(0)


@pytest.mark.parametrize('profile', ['jerk', 'trapezoid'])
def test_nodes_cover_the_program_and_integrate_its_motion_exactly(profile) -> None:
    """The weights add up to the program's duration, and the integral of every axis's speed
    over the nodes is its displacement, of its acceleration (the corners' velocity steps
    included, as ramps) its speed change (zero: the program starts and ends at rest): the
    pieces are where the motion is polynomial."""
    options = PlannerOptions(profile=profile)
    chunks = _nodes(LINES, 3, options)
    prog = parse_gcode(LINES, file='t.nc')
    duration = estimate_plan(prog.moves, LIM, options=options, file='t.nc').duration_s
    weight = np.concatenate([c.weight_s for c in chunks])
    vel = np.concatenate([c.motion.vel for c in chunks])
    acc = np.concatenate([c.motion.acc for c in chunks])
    t = np.concatenate([c.motion.t for c in chunks])
    assert np.all(np.diff(t) > 0.0)
    assert weight.sum() == pytest.approx(duration, rel=1e-12)
    assert weight @ vel == pytest.approx([-0.012, 0.020, 0.0], abs=1e-12)
    # the corners' velocity steps are ramps in the motion (one interpolation cycle each)
    assert weight @ acc == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    # a polynomial of the motion of degree <= 5 in time (speed^2 x acceleration) is exact at
    # three nodes per piece: the same at three and at six
    six = _nodes(LINES, 6, options)
    w6 = np.concatenate([c.weight_s for c in six])
    v6 = np.concatenate([c.motion.vel for c in six])
    a6 = np.concatenate([c.motion.acc for c in six])
    assert weight @ (vel ** 2 * acc) == pytest.approx(w6 @ (v6 ** 2 * a6), abs=1e-14)


def test_lines_of_the_nodes_are_the_blocks_they_lie_in() -> None:
    chunks = _nodes(LINES, 3)
    line = np.concatenate([c.motion.line for c in chunks])
    assert set(line.tolist()) <= set(range(2, 10))
    assert np.all(np.diff(line) >= 0)              # in program order


@pytest.mark.parametrize('feed', ['100', '500'])
def test_energy_on_the_nodes_is_what_the_samples_converge_to(feed) -> None:
    """The paper's demonstrator strokes: the energy summed over the nodes (the same dynamics
    per node as per sample) is what the sampled trapezoid sums approach as the rate rises,
    closer at 100 kHz than at 1 kHz, from far fewer evaluations."""
    machine = load_machine(REPO / 'config' / 'demonstrator.yaml')
    path = REPO / 'config' / 'programs' / f'demonstrator_f{feed}.nc'
    energy, nodes = 0.0, 0
    for chunk in iter_nodes(load_gcode(path).moves, machine.limits(),
                            options=machine.planner.options(), file=str(path), order=8):
        dyn = compute_dynamics(chunk.motion, machine)
        power = apply_braking(dyn.torque_nm * dyn.omega_rad_s, braking=machine.braking)
        energy += float(chunk.weight_s @ power[:, 0])
        nodes += chunk.weight_s.size
    sampled = {}
    for rate in (1e3, 1e5):
        m = replace(machine, planner=replace(machine.planner, rate_hz=rate))
        summary, _ = simulate_stream(load_gcode(path).moves, m, file=str(path))
        sampled[rate] = summary['energy_j']['X']
    assert abs(energy - sampled[1e5]) < abs(energy - sampled[1e3])
    assert energy == pytest.approx(sampled[1e5], rel=1e-8)
    assert nodes < 0.05 * summary['samples'] / 100      # vs the 1 kHz samples


def test_an_axis_turning_on_an_arc_cuts_the_piece() -> None:
    """X stops and turns halfway along each half circle (Coulomb friction changes sign
    there): the pieces are cut at that time, so X's energy no longer depends on the rule's
    order and is what the samples converge to. (Without the cut: 13.85 / 15.00 / 14.89 J at
    5 / 8 / 12 nodes.)"""
    text = 'G21 G90 G17 G61\nG0 X0 Y-20\nG3 X0 Y20 I0 J20 F1200\nG2 X0 Y-20 I0 J-20\nM2\n'
    machine = replace(load_machine(REPO / 'config' / 'three_axis_mill.yaml'),
                      braking='regenerative')
    energy = {}
    for order in (5, 8, 12):
        e = 0.0
        for chunk in iter_nodes(parse_gcode(text, file='arc.nc').moves, machine.limits(),
                                options=machine.planner.options(), order=order):
            dyn = compute_dynamics(chunk.motion, machine)
            e += float(chunk.weight_s @ (dyn.torque_nm * dyn.omega_rad_s)[:, 0])
        energy[order] = e
    m = replace(machine, planner=replace(machine.planner, rate_hz=1e5))
    summary, _ = simulate_stream(parse_gcode(text, file='arc.nc').moves, m, file='arc.nc')
    assert energy[5] == pytest.approx(energy[12], rel=1e-9)
    assert energy[8] == pytest.approx(energy[12], rel=1e-9)
    assert energy[12] == pytest.approx(summary['energy_j']['X'], rel=1e-7)
