"""The node graph's streaming power equals the offline simulation with declared effects."""
import numpy as np
from numpy.testing import assert_array_equal
import pytest

from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.graph.flow import StreamingPower
from feed_axis_energy.machine.file import load_machine, machine_from_dict, machine_to_dict
from feed_axis_energy.plan.motion import Motion
from feed_axis_energy.sim.simulate import simulate_program
from feed_axis_energy.paths import default_machine

PROGRAM = 'G21 G90 G94 G61\nG1 X200 F12000\nG4 P0.2\nG1 X0 F18000\n'
EFFECTS = [{'id': 'load_friction', 'axis': 'X', 'params': {'mu': 0.1}},
           {'id': 'standby', 'params': {'p0_w': 12.0}},
           {'id': 'copper', 'axis': 'X', 'params': {'k_w_nm2': 3.0}},
           {'id': 'thermal_drift', 'axis': 'X', 'params': {'rate_n_s': 0.5}}]


def _augmented():
    d = machine_to_dict(load_machine(default_machine()))
    d['effects'] = EFFECTS
    return machine_from_dict(d, file='augmented.yaml')


@pytest.mark.parametrize('seed', [0, 1])
def test_batches_give_the_offline_power_and_energy_bit_for_bit(seed):
    machine = _augmented()
    result = simulate_program(parse_gcode(PROGRAM, file='p.nc'), machine, load_kg=17.336)
    dyn, power = result.dynamics, result.power
    # The effects change the result, so equality below is not trivially the plain model's.
    plain = simulate_program(parse_gcode(PROGRAM, file='p.nc'),
                             load_machine(default_machine()), load_kg=17.336)
    assert power.total_energy_j[-1] > plain.power.total_energy_j[-1] + 10.0

    stream = StreamingPower(dyn.axes, braking=machine.braking, machine=machine, load_kg=17.336)
    rng = np.random.default_rng(seed)
    n = dyn.t.shape[0]
    cuts = np.unique(np.concatenate(([0, n], rng.integers(1, n, size=40))))
    got_power, got_energy = [], []
    for i0, i1 in zip(cuts[:-1], cuts[1:]):
        sl = slice(i0, i1)
        motion = Motion(t=dyn.t[sl], axes=dyn.axes, pos=result.motion.pos[sl],
                        vel=result.motion.vel[sl], acc=result.motion.acc[sl],
                        line=np.zeros(i1 - i0, dtype=np.int32))
        both, energy = stream.update(dyn.t[sl], dyn.torque_nm[sl], dyn.omega_rad_s[sl],
                                     motion=motion)
        got_power.append(both)
        got_energy.append(energy)
    both, energy = np.vstack(got_power), np.vstack(got_energy)
    k = len(dyn.axes)
    assert_array_equal(both[:, :k], power.power_w)
    assert_array_equal(both[:, k], power.total_w)
    assert_array_equal(energy[:, k], power.total_energy_j)
    assert_array_equal(stream.energy_j, energy[-1])


def test_effects_need_the_motion():
    machine = _augmented()
    stream = StreamingPower(('X',), braking=machine.braking, machine=machine)
    with pytest.raises(ValueError, match='needs the motion'):
        stream.update(np.array([0.0]), np.zeros((1, 1)), np.zeros((1, 1)))


def test_a_machine_without_effects_needs_no_motion():
    machine = load_machine(default_machine())
    stream = StreamingPower(('X',), braking=machine.braking, machine=machine)
    power, energy = stream.update(np.array([0.0, 1.0]), np.ones((2, 1)), np.full((2, 1), 2.0))
    assert_array_equal(power[:, 0], [2.0, 2.0])
    assert energy[-1, 0] == 2.0
