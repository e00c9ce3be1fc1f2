"""StreamingPower's per-job figures (peak power, energy returned while braking, electrical
energies) equal the offline summary's, batch cuts anywhere."""
import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.gcode.load import parse_gcode
from feed_axis_energy.graph.flow import StreamingPower
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.paths import config_dir, default_machine
from feed_axis_energy.plan.motion import Motion
from feed_axis_energy.sim.simulate import simulate_program, summarize

PROGRAM = ('G21 G90 G94 G61\nG1 X200 Y50 Z-30 F12000\nG4 P0.2\nG1 X0 Y0 Z0 F18000\n'
           'G0 X100 Z-10\n')


def _stream(result, machine, seed, load_kg):
    dyn = result.dynamics
    stream = StreamingPower(dyn.axes, braking=machine.braking, machine=machine, load_kg=load_kg)
    rng = np.random.default_rng(seed)
    n = dyn.t.shape[0]
    cuts = np.unique(np.concatenate(([0, n], rng.integers(1, n, size=30))))
    for i0, i1 in zip(cuts[:-1], cuts[1:]):
        sl = slice(i0, i1)
        motion = Motion(t=dyn.t[sl], axes=dyn.axes, pos=result.motion.pos[sl],
                        vel=result.motion.vel[sl], acc=result.motion.acc[sl],
                        line=np.zeros(i1 - i0, dtype=np.int32))
        stream.update(dyn.t[sl], dyn.torque_nm[sl], dyn.omega_rad_s[sl], motion=motion)
    return stream


@pytest.mark.parametrize('machine_file, seed', [
    ('three_axis_mill_drives.yaml', 0), ('three_axis_mill_drives.yaml', 1),
    ('three_axis_mill.yaml', 2)])
def test_peak_braking_and_electrical_equal_the_offline_summary(machine_file, seed):
    machine = load_machine(config_dir() / machine_file)
    result = simulate_program(parse_gcode(PROGRAM, file='p.nc'), machine, load_kg=20.0)
    summary = summarize(result)
    stream = _stream(result, machine, seed, 20.0)
    axes = list(result.dynamics.axes)
    assert_allclose(stream.peak_w, [summary['peak_power_w'][a] for a in axes + ['total']],
                    rtol=1e-12)
    assert summary['regenerated_energy_j'] > 0.1     # the program brakes: not a 0 == 0 check
    assert_allclose(stream.regenerated_j, summary['regenerated_energy_j'], rtol=1e-9)
    assert_allclose(stream.duration_s, summary['duration_s'], rtol=1e-12)
    assert stream.n_samples == summary['samples']
    elec = stream.electrical_summary()
    if 'electrical' not in summary:
        assert elec is None
        return
    ref = summary['electrical']
    for key in ('motor_energy_j', 'supply_energy_j'):
        assert elec[key].keys() == ref[key].keys()
        for name, value in ref[key].items():
            assert_allclose(elec[key][name], value, rtol=1e-9, atol=1e-9, err_msg=key + name)
    assert_allclose(elec['returned_j'], ref['returned_j'], rtol=1e-9, atol=1e-12)
    assert ref['supply_energy_j']['total'] > ref['motor_energy_j']['total'] > 0
    last = stream.last_electrical
    assert last is not None and last.motor_w.shape[1] == len(axes)


def test_a_machine_without_drives_has_no_electrical_side():
    machine = load_machine(default_machine())
    stream = StreamingPower(('X',), braking=machine.braking, machine=machine)
    stream.update(np.array([0.0, 1.0]), np.ones((2, 1)), np.full((2, 1), -2.0))
    assert stream.electrical_summary() is None and stream.last_electrical is None
    assert stream.regenerated_j == pytest.approx(2.0)      # -(-2 W) * 1 s
    # regenerative braking: the drawn power is the signed -2 W, and the largest of it is that
    assert stream.peak_w.tolist() == [-2.0, -2.0]
    assert stream.energy_export_j.tolist() == [2.0, 2.0]
    assert stream.energy_import_j.tolist() == [0.0, 0.0]
    burnt = StreamingPower(('X',), braking='dissipated', machine=machine)
    burnt.update(np.array([0.0, 1.0]), np.ones((2, 1)), np.full((2, 1), -2.0))
    assert burnt.energy_export_j.tolist() == [0.0, 0.0]     # burned, not returned


def test_live_payload_holds_the_last_sample_and_the_energy_so_far():
    import json
    from feed_axis_energy.graph import live_payload
    machine = load_machine(config_dir() / 'three_axis_mill_drives.yaml')
    result = simulate_program(parse_gcode(PROGRAM, file='p.nc'), machine, load_kg=20.0)
    summary = summarize(result)
    stream = _stream(result, machine, 3, 20.0)
    d = live_payload(stream, job_id='j', stamp_ns=123, clock='wall', line=4)
    json.dumps(d, allow_nan=False)
    assert (d['job_id'], d['stamp_ns'], d['clock'], d['line']) == ('j', 123, 'wall', 4)
    assert d['samples'] == summary['samples']
    p = result.power
    assert d['power_w']['X'] == p.power_w[-1, 0] and d['power_w']['total'] == p.total_w[-1]
    assert_allclose(d['energy_j']['total'], summary['energy_j']['total'], rtol=1e-12)
    # drawn and returned: net = import - export per axis; under regenerative braking the
    # total returned is the offline summary's energy returned while braking
    for name in list(result.dynamics.axes) + ['total']:
        assert d['energy_import_j'][name] >= d['energy_export_j'][name] >= 0.0
        assert_allclose(d['energy_import_j'][name] - d['energy_export_j'][name],
                        d['energy_j'][name], rtol=1e-12, atol=1e-12)
    assert machine.braking == 'regenerative'
    assert_allclose(d['energy_export_j']['total'], summary['regenerated_energy_j'], rtol=1e-9)
    assert_allclose(sum(d['energy_export_j'][a] for a in result.dynamics.axes),
                    d['energy_export_j']['total'], rtol=1e-12)
    e = d['electrical']
    elec = p.electrical
    assert e['motor_w']['Z'] == elec.motor_w[-1, 2]
    assert e['supply_w']['cabinet'] == elec.cabinet_w > 0
    assert_allclose(e['supply_w']['total'], elec.supply_w[-1].sum() + elec.cabinet_w)
    assert_allclose(e['supply_energy_j']['total'],
                    summary['electrical']['supply_energy_j']['total'], rtol=1e-9)
    plain = _stream(result, load_machine(config_dir() / 'three_axis_mill.yaml'), 3, 20.0)
    assert live_payload(plain, job_id='', stamp_ns=0, clock='simulation')['electrical'] is None
    with pytest.raises(ValueError, match='clock'):
        live_payload(plain, job_id='', stamp_ns=0, clock='utc')
