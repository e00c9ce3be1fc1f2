"""A ball-screw positioning test stand with a force trace, as an independent truth (issue 24 §5).

``PYTHONPATH=. .venv/bin/python bench/truth_stand.py [--seed N] [--keep DIR]``

The stand: one ball-screw axis moving a carriage between positions at 1 kHz; the "measured
force" is the position controller's output times a gain, i.e. the motor torque expressed as
a force at the nut (``M·2·pi/lead``): smooth (first-order filtered, 5 ms) and low-noise
(0.2 N). The physics is written here again (nothing of the package's dynamics, loss models
or effect catalog is called), with ``truth_model.Timeline`` for rest-to-rest jerk-limited
moves::

    F_motor = (m + J·(2·pi/lead)²)·a + F(v)            moving
    F(v)    = F+·max(sgn v, 0) - F-·max(-sgn v, 0) + c±·v + Fs·exp(-|v|/vs)·sgn(v) + F0
    F_motor = F0                                        at rest (friction holds nothing)

with asymmetric Coulomb (``F+ != F-``) and viscous (``c+ != c-``) friction, an exponential
Stribeck excess and a constant offset force ``F0`` (a cable carrier). The campaign has
positioning programs at several feeds and strokes in both directions with dwells; the
manifest declares ``instrument.measures: force`` and motion from the data. The script runs
``fit-loss --method samples --friction extended``'s core (``fit_drive_friction``) and prints
each recovered figure against the truth, and the validation run's power RMSE and energy
error of the fitted model against those of the truth's own parameters.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass
import math
from pathlib import Path
import sys
import tempfile

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import truth_model as tm  # noqa: E402

RATE_HZ = 1000.0
LEAD_M = 0.01


@dataclass(frozen=True)
class StandTruth:
    """The true stand (SI units)."""

    mass_kg: float = 18.0
    rotor_kg_m2: float = 1.5e-4          # motor + coupling + screw, lumped
    f_pos_n: float = 30.0
    f_neg_n: float = 22.0
    c_pos_n_s_m: float = 60.0
    c_neg_n_s_m: float = 50.0
    stribeck_n: float = 12.0
    stribeck_v_m_s: float = 0.004
    offset_n: float = 15.0
    noise_n: float = 0.2
    filter_s: float = 0.005

    @property
    def equivalent_mass_kg(self) -> float:
        """Mass the acceleration sees: carriage + rotor inertia through the screw."""
        return self.mass_kg + self.rotor_kg_m2 * (2.0 * math.pi / LEAD_M) ** 2

    @property
    def coulomb_n(self) -> float:
        """Symmetric Coulomb force."""
        return 0.5 * (self.f_pos_n + self.f_neg_n)

    @property
    def viscous_n_s_m(self) -> float:
        """Symmetric viscous coefficient."""
        return 0.5 * (self.c_pos_n_s_m + self.c_neg_n_s_m)


AXIS = tm.AxisData(table_kg=18.0, lead_m=LEAD_M, inertia_kg_m2=1.5e-4, v_max=0.5, a_max=3.0,
                   j_max=60.0, loss_a=0.0, loss_b=0.0, sin_theta=0.0)
# positioning programs: (feed [m/s], [targets ...]) with 0.5 s dwells, from and back to 0
PROGRAMS = {
    'p050': (0.05, [0.05, 0.02, 0.12, 0.0]),
    'p100': (0.10, [0.15, 0.05, 0.25, 0.0]),
    'p200': (0.20, [0.30, 0.10, 0.20, 0.0]),
    'p300': (0.30, [0.25, 0.05, 0.35, 0.0]),
    'p400': (0.40, [0.35, 0.0, 0.20, 0.0]),
}
VALIDATE = 'p250v'
VALIDATE_PROGRAM = (0.25, [0.20, 0.08, 0.30, 0.0])
DWELL_S = 0.5


def timeline(feed: float, targets: list[float]) -> tm.Timeline:
    """Dwell, then rest-to-rest moves to each target with dwells."""
    line = tm.Timeline()
    line.dwell(DWELL_S)
    x = 0.0
    for target in targets:
        line.move(target - x, v=feed, axis=AXIS)
        line.dwell(DWELL_S)
        x = target
    return line


def true_force(v: np.ndarray, a: np.ndarray, truth: StandTruth) -> np.ndarray:
    """Motor force at the nut [N] (module docstring)."""
    sgn = np.sign(v)
    speed = np.abs(v)
    fric = np.where(v > 0, truth.f_pos_n + truth.c_pos_n_s_m * speed,
                    np.where(v < 0, -(truth.f_neg_n + truth.c_neg_n_s_m * speed), 0.0))
    strib = truth.stribeck_n * np.exp(-speed / truth.stribeck_v_m_s) * sgn
    return truth.equivalent_mass_kg * a + fric + strib + truth.offset_n


def _smooth(y: np.ndarray, tau: float) -> np.ndarray:
    alpha = 1.0 - math.exp(-1.0 / (RATE_HZ * tau))
    out = np.empty_like(y)
    acc = y[0]
    for i, value in enumerate(y):
        acc += alpha * (value - acc)
        out[i] = acc
    return out


def record(name: str, feed: float, targets: list[float], truth: StandTruth,
           rng: np.random.Generator) -> dict[str, np.ndarray]:
    """One run at 1 kHz: time, position, velocity, acceleration, measured force."""
    line = timeline(feed, targets)
    t = np.arange(0.0, line.duration + DWELL_S, 1.0 / RATE_HZ)
    x, v, a = line.sample(t)
    force = true_force(v, a, truth)
    noise = _smooth(rng.normal(0.0, truth.noise_n * 3.0, size=t.size), truth.filter_s)
    return {'t': t, 'x': x, 'v': v, 'a': a, 'force': force + noise, 'true': force}


def machine_doc(*, direct: bool = False) -> dict:
    """The declared stand (what fit-loss starts from): carriage mass known, friction guessed.

    ``direct``: a linear motor stand (``transmission: direct``, no screw).
    """
    doc = {
        'name': 'positioning_stand', 'braking': 'regenerative', 'load_axis': 'X',
        'planner': {'profile': 'jerk', 'corner_tolerance_m': 1e-4, 'rate_hz': RATE_HZ,
                    'cycle_s': 1.0 / RATE_HZ},
        'axes': {'X': {
            'table_mass_kg': StandTruth().mass_kg, 'rides_on': None, 'inclination_deg': 0.0,
            'screw': {'diameter_m': 0.016, 'lead_m': LEAD_M, 'length_m': 0.5, 'starts': 1,
                      'efficiency': 1.0},
            'inertias': {'motor_kg_m2': 1.0e-4, 'coupling_kg_m2': 0.0, 'screw_kg_m2': 0.0},
            'limits': {'velocity_m_s': AXIS.v_max, 'acceleration_m_s2': AXIS.a_max,
                       'jerk_m_s3': AXIS.j_max},
            'loss': {'model': 'coulomb_viscous', 'coulomb_n': 20.0, 'viscous_n_s_m': 30.0,
                     'mu': 0.0}}},
    }
    if direct:
        x = doc['axes']['X']
        del x['screw'], x['inertias']
        x['transmission'] = 'direct'
    return doc


def write_campaign(out: Path, *, seed: int, truth: StandTruth = StandTruth(),
                   direct: bool = False) -> Path:
    """Write machine, manifest and CSVs of the calibration runs and the validation run.

    ``direct``: the machine file declares a linear motor stand (the truth then needs
    ``rotor_kg_m2 = 0``: a linear motor has no rotor).
    """
    rng = np.random.default_rng(seed)
    out.mkdir(parents=True)
    (out / 'runs').mkdir()
    (out / 'machine.yaml').write_text(yaml.safe_dump(machine_doc(direct=direct),
                                                     sort_keys=False),
                                      encoding='utf-8')
    entries = []
    for name, (feed, targets) in list(PROGRAMS.items()) + [(VALIDATE, VALIDATE_PROGRAM)]:
        r = record(name, feed, targets, truth, rng)
        rows = ['time_s,x_mm,v_mm_s,a_mm_s2,force_n']
        rows += [f'{t:.3f},{x * 1e3:.6f},{v * 1e3:.6f},{a * 1e3:.6f},{f:.5f}'
                 for t, x, v, a, f in zip(r['t'], r['x'], r['v'], r['a'], r['force'])]
        (out / 'runs' / f'{name}.csv').write_text('\n'.join(rows) + '\n', encoding='utf-8')
        entries.append({'name': name, 'data': f'runs/{name}.csv', 'load_kg': 0.0,
                        'role': 'validate' if name == VALIDATE else 'calibrate'})
    axis = {'position': {'column': 'x_mm', 'unit': 'mm'},
            'velocity': {'column': 'v_mm_s', 'unit': 'mm/s'},
            'acceleration': {'column': 'a_mm_s2', 'unit': 'mm/s^2'},
            'force': {'column': 'force_n', 'unit': 'N'}}
    manifest = {'name': f'positioning_stand_{seed}', 'machine': 'machine.yaml',
                'defaults': {'time': {'column': 'time_s', 'unit': 's'},
                             'motion': {'from_data': 'actual', 'reconstruct': 'samples'},
                             'instrument': {'measures': 'force'}, 'axes': {'X': axis}},
                'runs': entries}
    path = out / 'manifest.yaml'
    path.write_text(yaml.safe_dump(manifest, sort_keys=False), encoding='utf-8')
    return path


def recovery(fit, truth: StandTruth) -> dict[str, tuple[float, float]]:
    """``{name: (fitted, true)}`` of the figures the stand's identification reports."""
    return {
        'equivalent mass [kg]': (fit.effective_mass_kg, truth.equivalent_mass_kg),
        'Coulomb (symmetric) [N]': (fit.coulomb_n, truth.coulomb_n),
        'Coulomb asymmetry (F+ - F-)/2 [N]': (fit.coulomb_asymmetry_n,
                                              0.5 * (truth.f_pos_n - truth.f_neg_n)),
        'viscous (symmetric) [N s/m]': (fit.viscous_n_s_m, truth.viscous_n_s_m),
        'viscous asymmetry (c+ - c-)/2 [N s/m]': (fit.viscous_asymmetry_n_s_m,
                                                  0.5 * (truth.c_pos_n_s_m - truth.c_neg_n_s_m)),
        'offset force [N]': (fit.offset_n, truth.offset_n),
        'Stribeck excess [N]': (fit.stribeck_n, truth.stribeck_n),
        'Stribeck speed [mm/s]': (1e3 * fit.stribeck_v_m_s, 1e3 * truth.stribeck_v_m_s),
    }


def fit_campaign(manifest: Path):
    """``fit_drive_friction`` on the calibration runs (as ``fit-loss`` runs it)."""
    from feed_axis_energy.identify.fit.frictionfit import fit_drive_friction
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.measured import load_campaign, load_run
    campaign = load_campaign(manifest)
    machine = load_machine(campaign.machine)
    specs = [s for s in campaign.runs if s.role == 'calibrate']
    runs = [load_run(s) for s in specs]
    # force: torque per newton is the lead / (2 pi) (1 m on a direct axis)
    gain = machine.axis('X').screw.lead_m / (2.0 * math.pi)
    return fit_drive_friction(runs, machine=machine, measures='force', gains={'X': gain},
                              velocity='actual')['X']


def fit_reference(manifest: Path):
    """The symmetric Coulomb + viscous fit (``fit-loss --method samples`` without
    ``--friction extended``) on the same runs: the reference identification."""
    from feed_axis_energy.identify import fit_drive_samples
    from feed_axis_energy.machine import load_machine
    from feed_axis_energy.measured import load_campaign, load_run
    campaign = load_campaign(manifest)
    specs = [s for s in campaign.runs if s.role == 'calibrate']
    return fit_drive_samples([load_run(s) for s in specs],
                             machine=load_machine(campaign.machine), measures='force',
                             gains={'X': LEAD_M / (2.0 * math.pi)}, velocity='actual')['X']


def validation(fit, truth: StandTruth, *, seed: int, reference=None) -> dict[str, float]:
    """Power RMSE [W] and net energy error [%] of the fitted model on the validation run, and
    the RMSE of the truth's own parameters on the same noisy record (the reference)."""
    feed, targets = VALIDATE_PROGRAM
    r = record(VALIDATE, feed, targets, truth, np.random.default_rng(seed + 1000))
    v, a = r['v'], r['a']
    sgn = np.sign(v)
    speed = np.abs(v)
    fm = fit.moving_offset_n
    f_fit = np.where(speed > 0, fit.effective_mass_kg * a + fit.coulomb_n * sgn
                     + fit.viscous_n_s_m * v + fm + fit.viscous_asymmetry_n_s_m * speed
                     + fit.stribeck_n * np.exp(-(speed / fit.stribeck_v_m_s)
                                               ** fit.stribeck_delta) * sgn, fit.offset_n)
    p_meas = r['force'] * v
    p_fit = f_fit * v
    p_true = r['true'] * v
    dt = 1.0 / RATE_HZ
    e_meas = float(np.sum(p_meas)) * dt
    out = {'rmse_w': float(np.sqrt(np.mean((p_fit - p_meas) ** 2))),
           'truth_rmse_w': float(np.sqrt(np.mean((p_true - p_meas) ** 2))),
           'energy_error_pct': 100.0 * (float(np.sum(p_fit)) * dt - e_meas) / e_meas}
    if reference is not None:
        f_ref = (reference.effective_mass_kg * a + reference.coulomb_n * sgn
                 + reference.viscous_n_s_m * v)
        out['reference_rmse_w'] = float(np.sqrt(np.mean((f_ref * v - p_meas) ** 2)))
        out['reference_energy_error_pct'] = 100.0 * (float(np.sum(f_ref * v)) * dt
                                                     - e_meas) / e_meas
    return out


def main(argv: list[str] | None = None) -> int:
    """Write a campaign, fit it, print recovery and validation."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--seed', type=int, default=1, help='noise seed (default 1)')
    p.add_argument('--keep', type=Path, default=None, metavar='DIR',
                   help='write the campaign here (must not exist) and keep it')
    args = p.parse_args(argv)
    truth = StandTruth()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep if args.keep is not None else Path(tmp) / 'stand'
        manifest = write_campaign(out, seed=args.seed, truth=truth)
        fit = fit_campaign(manifest)
        ref = fit_reference(manifest)
    print(f'positioning stand, seed {args.seed}: {fit.message}')
    print('| figure | fitted | truth | error |')
    print('| --- | --- | --- | --- |')
    for name, (got, want) in recovery(fit, truth).items():
        print(f'| {name} | {got:.4g} | {want:.4g} | {100.0 * (got - want) / want:+.2f} % |')
    val = validation(fit, truth, seed=args.seed, reference=ref)
    print(f'validation run: power RMSE {val["rmse_w"]:.4g} W with the extended friction fit, '
          f'{val["reference_rmse_w"]:.4g} W with the symmetric Coulomb + viscous fit (ratio '
          f'{val["rmse_w"] / val["reference_rmse_w"]:.3f}), {val["truth_rmse_w"]:.4g} W with '
          f'the truth\'s own parameters (the noise); net energy error '
          f'{val["energy_error_pct"]:+.2f} % (symmetric fit '
          f'{val["reference_energy_error_pct"]:+.2f} %)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
