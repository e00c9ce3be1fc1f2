"""Virtual test rig: effect specs, the instrument, campaign files, determinism, truth."""
import json
from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose
import pytest

from feed_axis_energy.errors import ConfigError, OutputError
from feed_axis_energy.gcode.load import load_gcode
from feed_axis_energy.units import GRAVITY_M_S2
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.align import interval_average
from feed_axis_energy.measured.manifest import load_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.identify.rig import (EffectSpec, Instrument, instrument_record,
                                                parse_effects)
from feed_axis_energy.identify.rig import make_campaign, paper_scenario, RigConfig, stroke_program
from feed_axis_energy.sim.simulate import simulate_program

ROOT = Path(__file__).resolve().parents[2]
MACHINE = ROOT / 'config' / 'demonstrator.yaml'
EXACT = Instrument(noise_w=0.0, quantum_w=0.0)


def _small(**kw) -> RigConfig:
    base = dict(machine=MACHINE, loads_kg=(0.0,), feeds_mm_s=(300.0,), cycles=1,
                instrument=EXACT, offset_s=0.3)
    base.update(kw)
    return RigConfig(**base)


def _declared(out: Path, run_name: str, load_kg: float):
    """Simulation of the declared model on the run's program, independent of the rig."""
    campaign = load_campaign(out / 'manifest.yaml')
    spec = campaign.run(run_name)
    machine = load_machine(campaign.machine)
    return spec, simulate_program(load_gcode(spec.motion_program), machine, load_kg=load_kg)


# ----------------------------------------------------------------------------- specs

def test_parse_effects_spec() -> None:
    specs = parse_effects('coulomb=f_pos_n:20,f_neg_n:-5, viscous=c_n_s_m:100,standby')
    assert [s.id for s in specs] == ['coulomb', 'viscous', 'standby']
    assert specs[0].params == {'f_pos_n': 20.0, 'f_neg_n': -5.0}
    assert specs[1].params == {'c_n_s_m': 100.0}
    assert specs[2].params == {'p0_w': 15.0}   # id alone: example values
    assert parse_effects('none') == ()
    assert parse_effects('') == ()


@pytest.mark.parametrize('spec, named', [
    ('frobnicate=k:1', "'frobnicate'"),
    ('coulomb=f_up_n:3', "'f_up_n'"),
    ('viscous=c_n_s_m:lots', 'c_n_s_m'),
    ('mu:0.1', 'names no effect'),
])
def test_parse_effects_rejects_bad_specs(spec: str, named: str) -> None:
    with pytest.raises(ConfigError, match=named):
        parse_effects(spec)


def test_stroke_program_moves_the_load_axis() -> None:
    text = stroke_program(250.0, axis='Y', stroke_mm=300.0, cycles=2, dwell_s=0.5)
    assert 'G1 Y300 F15000' in text
    assert text.count('G1 Y300') == 2
    assert 'G4 P0.5' in text


# ----------------------------------------------------------------------------- instrument

def test_instrument_is_the_interval_average_on_a_ramp() -> None:
    t = np.arange(0, 10001) * 1e-3
    ramp = 3.0 * t + 2.0
    inst = Instrument(window_s=0.05, period_s=0.05, noise_w=0.0, quantum_w=0.0)
    stamps, y = instrument_record(t, ramp, instrument=inst, offset_s=0.2, end_s=9.0)
    assert_allclose(np.diff(stamps), 0.05)
    assert_allclose(stamps[-1], 9.2)
    inside = stamps - 0.2 - 0.05 >= 0.0
    # mean of a ramp over [s - 0.2 - 0.05, s - 0.2] is its value at the window's middle
    assert_allclose(y[inside], 3.0 * (stamps[inside] - 0.2 - 0.025) + 2.0, rtol=1e-12)
    # before the signal starts the held first value is averaged
    assert_allclose(y[0], 2.0)


def test_instrument_quantises_drifts_and_adds_noise() -> None:
    t = np.arange(0, 20001) * 1e-3
    flat = np.full_like(t, 100.0)
    q = Instrument(noise_w=0.0, quantum_w=2.5)
    _, y = instrument_record(t, flat + 0.3, instrument=q, offset_s=0.0, end_s=20.0)
    assert_allclose(y, 100.0)      # 100.3 rounds to the nearest 2.5 W
    drift = Instrument(noise_w=0.0, quantum_w=0.0, gain_drift_per_s=0.01,
                       offset_drift_w_per_s=0.5)
    stamps, y = instrument_record(t, flat, instrument=drift, offset_s=0.0, end_s=20.0)
    assert_allclose(y, 100.0 * (1 + 0.01 * stamps) + 0.5 * stamps)
    noisy = Instrument(noise_w=4.0, quantum_w=0.0)
    _, y = instrument_record(t, flat, instrument=noisy, offset_s=0.0, end_s=20.0,
                             rng=np.random.default_rng(1))
    assert abs(np.std(y) - 4.0) < 0.4
    assert abs(np.mean(y) - 100.0) < 0.5
    with pytest.raises(ConfigError, match='random generator'):
        instrument_record(t, flat, instrument=noisy, offset_s=0.0, end_s=20.0)


# ----------------------------------------------------------------------------- campaigns

def test_manifest_loads_and_runs_load(tmp_path: Path) -> None:
    cfg = _small(loads_kg=(0.0, 17.336), feeds_mm_s=(200.0, 400.0), offset_s=None,
                 instrument=Instrument(noise_w=2.0))
    manifest = make_campaign(tmp_path / 'rig', cfg)
    campaign = load_campaign(manifest)
    assert [r.name for r in campaign.runs] == [
        'f200_load0kg', 'f200_load17.336kg', 'f400_load0kg', 'f400_load17.336kg']
    assert campaign.machine == (tmp_path / 'rig' / 'machine.yaml').resolve()
    assert load_machine(campaign.machine).name == 'demonstrator'
    truth = json.loads((tmp_path / 'rig' / 'truth.json').read_text())
    for spec, t_run in zip(campaign.runs, truth['runs']):
        run = load_run(spec)
        assert spec.load_kg == t_run['load_kg']
        assert spec.motion_program.is_file()
        assert run.power_axes == ('X',)
        assert_allclose(np.diff(run.t), 0.05, atol=1e-9)
        # quantised to 1 W: whole watts after the kW -> W conversion
        assert_allclose(run.power_w, np.round(run.power_w), atol=1e-6)
        assert 0.2 <= t_run['offset_s'] < 0.8
        # positions in mm converted to m: the 400 mm stroke
        assert_allclose(run.position_m.max(), 0.4, atol=1e-6)
    assert {r.role for r in campaign.runs} == {'calibrate', 'validate'}


def test_no_effects_no_noise_equals_interval_averaged_simulation(tmp_path: Path) -> None:
    out = tmp_path / 'rig'
    make_campaign(out, _small(loads_kg=(17.336,)))
    spec, sim = _declared(out, 'f300_load17.336kg', 17.336)
    run = load_run(spec)
    want = interval_average(sim.power.t, sim.power.power_w[:, 0], run.t - 0.3, window_s=0.05)
    assert np.max(want) > 100.0
    assert_allclose(run.power_w[:, 0], want, atol=1e-6)
    # the record covers the program and 1 s after it
    assert run.t[-1] - 0.3 <= sim.power.t[-1] + 1.0 + 1e-9
    assert run.t[-1] - 0.3 > sim.power.t[-1] + 1.0 - 0.05


def test_truth_effects_appear_in_the_measured_power(tmp_path: Path) -> None:
    out = tmp_path / 'rig'
    effects = (EffectSpec('standby', {'p0_w': 40.0}), EffectSpec('load_friction', {'mu': 0.1}))
    make_campaign(out, _small(loads_kg=(22.711,), effects=effects))
    spec, sim = _declared(out, 'f300_load22.711kg', 22.711)
    run = load_run(spec)
    mass = load_machine(MACHINE).axis('X').table_mass_kg + 22.711
    # hand: P0 + mu·m·g·|v| on top of the declared power, then the 50 ms meter
    extra = 40.0 + 0.1 * mass * GRAVITY_M_S2 * np.abs(sim.motion.vel[:, 0])
    want = interval_average(sim.power.t, sim.power.power_w[:, 0] + extra, run.t - 0.3,
                            window_s=0.05)
    assert_allclose(run.power_w[:, 0], want, atol=1e-6)
    truth = json.loads((out / 'truth.json').read_text())
    assert truth['effects'] == [{'id': 'standby', 'params': {'p0_w': 40.0}},
                                {'id': 'load_friction', 'params': {'mu': 0.1}}]


def test_outside_catalog_periodic_disturbance(tmp_path: Path) -> None:
    out = tmp_path / 'rig'
    make_campaign(out, _small(outside='periodic'))
    spec, sim = _declared(out, 'f300_load0kg', 0.0)
    run = load_run(spec)
    declared = interval_average(sim.power.t, sim.power.power_w[:, 0], run.t - 0.3,
                                window_s=0.05)
    resid = run.power_w[:, 0] - declared
    # 20 W at 3.7 Hz, averaged over 50 ms: amplitude 20·sinc(3.7·0.05) ≈ 18.9 W
    amp = 20.0 * np.sinc(3.7 * 0.05)
    s = run.t - 0.3
    wave = (np.cos(2 * np.pi * 3.7 * (s - 0.05)) - np.cos(2 * np.pi * 3.7 * s)) \
        / (2 * np.pi * 3.7 * 0.05) * 20.0
    inside = s - 0.05 >= 0.0
    # the 1 kHz truth is averaged as piecewise linear: relative error (2·pi·3.7·1 ms)²/12
    assert_allclose(resid[inside], wave[inside], atol=2e-3)
    assert abs(np.max(np.abs(resid[inside])) - amp) < 0.3
    assert json.loads((out / 'truth.json').read_text())['outside']['kind'] == 'periodic'


def test_same_seed_same_files_other_seed_other_noise(tmp_path: Path) -> None:
    cfg = _small(feeds_mm_s=(200.0, 500.0), offset_s=None, instrument=Instrument(noise_w=3.0),
                 effects=parse_effects('coulomb,torque_ripple'), seed=42)
    a = make_campaign(tmp_path / 'a', cfg).parent
    b = make_campaign(tmp_path / 'b', cfg).parent
    c = make_campaign(tmp_path / 'c', _small(**{**cfg.__dict__, 'seed': 43})).parent
    files = sorted(p.relative_to(a) for p in a.rglob('*') if p.is_file())
    assert Path('truth.json') in files and len(files) == 8
    for rel in files:
        assert (a / rel).read_bytes() == (b / rel).read_bytes(), rel
    assert (a / 'runs' / 'f200_load0kg.csv').read_bytes() != \
        (c / 'runs' / 'f200_load0kg.csv').read_bytes()


def test_refuses_a_foreign_directory_and_replaces_its_own(tmp_path: Path) -> None:
    foreign = tmp_path / 'mine'
    foreign.mkdir()
    (foreign / 'thesis.tex').write_text('precious')
    for force in (False, True):
        with pytest.raises(OutputError, match='exists'):
            make_campaign(foreign, _small(), force=force)
    assert [p.name for p in foreign.iterdir()] == ['thesis.tex']
    out = tmp_path / 'rig'
    make_campaign(out, _small(feeds_mm_s=(100.0,)))
    # an earlier rig output is replaced only with force (it was replaced silently before)
    with pytest.raises(OutputError, match='exists already'):
        make_campaign(out, _small(feeds_mm_s=(200.0,)))
    make_campaign(out, _small(feeds_mm_s=(200.0,)), force=True)
    assert sorted(p.name for p in (out / 'runs').iterdir()) == ['f200_load0kg.csv']
    assert sorted(p.name for p in tmp_path.iterdir()) == ['mine', 'rig']   # no temporary


def test_paper_scenario_errors_grow_with_load(tmp_path: Path) -> None:
    cfg = paper_scenario(MACHINE, seed=3)
    assert cfg.loads_kg == (0.0, 17.336, 22.711)
    assert cfg.feeds_mm_s == (100.0, 200.0, 300.0, 400.0, 500.0)
    assert [e.id for e in cfg.effects] == ['load_friction']
    small = RigConfig(**{**cfg.__dict__, 'feeds_mm_s': (500.0,), 'cycles': 1})
    out = tmp_path / 'paper'
    make_campaign(out, small)
    truth = {r['name']: r for r in json.loads((out / 'truth.json').read_text())['runs']}
    mean_error = []
    for load in cfg.loads_kg:
        name = f'f500_load{load:g}kg'
        spec, sim = _declared(out, name, load)
        run = load_run(spec)
        declared = interval_average(sim.power.t, sim.power.power_w[:, 0],
                                    run.t - truth[name]['offset_s'], window_s=0.05)
        mean_error.append(float(np.mean(run.power_w[:, 0] - declared)))
    assert mean_error[0] < mean_error[1] < mean_error[2]
    # hand: mu·dm·g·mean|v| between 0 and 22.711 kg, mean |v| from the simulation
    mean_speed = float(np.mean(np.abs(sim.motion.vel)))
    duration = sim.power.t[-1]
    covered = mean_speed * duration / (run.t[-1] + 0.05)
    assert_allclose(mean_error[2] - mean_error[0], 0.1 * 22.711 * GRAVITY_M_S2 * covered,
                    rtol=0.1)


def test_optional_bags_hold_the_same_record(tmp_path: Path) -> None:
    from feed_axis_energy.record import bagio
    out = tmp_path / 'rig'
    make_campaign(out, _small(bags=True, instrument=Instrument(noise_w=1.0)))
    run = load_run(load_campaign(out / 'manifest.yaml').run('f300_load0kg'))
    power = bagio.read_series(out / 'bags' / 'f300_load0kg', bagio.TOPIC_MEASURED_POWER)
    assert power.names == ('X', 'total')
    assert_allclose(power.t - power.t[0], run.t, atol=1e-9)
    assert_allclose(power.velocities[:, 0], run.power_w[:, 0], atol=1e-6)
    # energy is the trapezoid integral of the recorded power
    assert_allclose(power.positions[-1, 1], np.trapezoid(run.power_w[:, 0], run.t), rtol=1e-9)
    kin = bagio.read_series(out / 'bags' / 'f300_load0kg', bagio.TOPIC_MEASURED_KINEMATICS)
    assert_allclose(kin.positions[:, 0], run.position_m[:, 0], atol=1e-6)
