"""KIT DMC 60H air cut: calibrate on the first half of the run, predict the second (issue 25).

``PYTHONPATH=. .venv/bin/python bench/bench_dmc60h.py``

Loads ``config/campaigns/kit_dmc60h.yaml`` (its data file looked up in the shared data
directory: env ``FAE_SHARED``, else ``../shared`` beside the repository) and
``config/kit_dmc60h.yaml`` (the machine written from public data, its guesses marked). The
record is split in time by the manifest's windows: ``val_air_1_first`` (0 to 121.7 s)
calibrates, ``val_air_1_second`` (121.7 s to the end) is held out.

(a) Motion from the data: ``fit-loss --method samples --fit-kt --fit-counterbalance`` as the
    command line does it (:func:`fit_drive_samples` on the first half: torque constant,
    Coulomb and viscous friction, the force held at rest in the last direction, the weight Y
    carries), then ``compare --role validate`` on the second half. Printed per axis: current
    RMSE [A] and R^2 on the held-out half, and the energy-like integral of ``|I·v|`` [A·m]
    measured and predicted (and its error [%]). Beside it the anchor of the issue, computed
    here from the file: per axis a least-squares fit of the current on ``(1, a, v, sgn v)``
    (sign with a 0.1 mm/s dead band) over the first half of the rows, evaluated on the
    second half.
(b) Motion simulated from the validation program (``nc/DMC_60H/V_S235JR_VALIDATION.MPF``;
    the config's B table turns it, ``G1 B0``) on the fitted machine. The record holds the
    program three times (1.5-79.0 s, 83.5-161.0 s, 164.1-241.6 s, each ending where it
    started); the third run, from 162 s on, lies wholly in the held-out half and is
    compared. First with the work offset G57 taken as 0 (the config's value removed) and the
    program starting at the origin: ``compare`` finds the time offset and estimates the work
    offset from the positions; then with the config's G57 (that estimate, rounded), starting
    where the trace's first row stands (``motion.start_m``): the translation left, and the
    current figures as in (a). No anchor.

CPU time at the end (``time.process_time``).
"""
from __future__ import annotations

from dataclasses import replace
import math
from types import MappingProxyType
import sys
import time

import numpy as np

from feed_axis_energy.identify import (fit_drive_samples, machine_with_sample_fits,
                                       SampleFitOptions)
from feed_axis_energy.machine import load_machine, Machine
from feed_axis_energy.measured import (Campaign, compare_campaign, load_campaign, load_run,
                                       MeasuredRun, TimeWindow)
from shared_lookup import HINT, REPO, shared_path  # bench/ is sys.path[0]

AXES = ('X', 'Y', 'Z')
FILE = 'I40_St_Val_Air_1_alldata_allcurrent.csv'
PROGRAM = ('nc', 'DMC_60H', 'V_S235JR_VALIDATION.MPF')
DEAD_BAND_M_S = 1.0e-4
THIRD_RUN_S = 162.0
"""The third run of the program in the record starts after this [s] (motion from 164.1 s)."""


def kit_campaign() -> Campaign | None:
    """The KIT campaign with its data in the shared directory, or None (said on stderr)."""
    data = shared_path('data', 'kit-dmc60h', needs=(FILE,))
    if data is None:
        print(f'KIT DMC 60H data not found: {HINT}', file=sys.stderr)
        return None
    campaign = load_campaign(REPO / 'config' / 'campaigns' / 'kit_dmc60h.yaml',
                             check_files=False)
    return replace(campaign, runs=tuple(replace(r, data=data / FILE) for r in campaign.runs))


def calibrate(campaign: Campaign, guessed: Machine) -> tuple[Machine, dict]:
    """The machine fitted on the calibrate run(s) as ``fit-loss --method samples --fit-kt
    --fit-counterbalance`` fits it; the fits by axis."""
    specs = campaign.runs_with_role('calibrate')
    runs = [load_run(s) for s in specs]
    fits = fit_drive_samples(runs, machine=guessed, measures='current',
                             gains={a: None for a in AXES},
                             velocity=[s.motion_from_data or 'auto' for s in specs],
                             invert=[s.instrument.invert for s in specs],
                             options=SampleFitOptions(fit_counterbalance=True))
    return machine_with_sample_fits(guessed, fits), fits


def r2(y: np.ndarray, p: np.ndarray) -> float:
    """Coefficient of determination of ``p`` for ``y``."""
    res = y - p
    return 1.0 - float(res @ res) / float(np.sum((y - y.mean()) ** 2))


def integral(t: np.ndarray, i: np.ndarray, v: np.ndarray) -> float:
    """The energy-like ``∫|I·v| dt`` [A·m] by the trapezoidal rule."""
    f = np.abs(i * v)
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t)))


def anchor(first: MeasuredRun, second: MeasuredRun, invert: tuple[str, ...]) -> dict:
    """The issue's 4-parameter regression per axis: fitted on ``first``, predicted on
    ``second`` (current in the manifest's sign convention, which R^2 does not see)."""
    out = {}
    for j, axis in enumerate(AXES):
        sign = -1.0 if axis in invert else 1.0

        def design(run: MeasuredRun) -> np.ndarray:
            v = run.velocity_m_s[:, j]
            a = run.acceleration_m_s2[:, j]
            s = np.where(np.abs(v) > DEAD_BAND_M_S, np.sign(v), 0.0)
            return np.column_stack([np.ones_like(v), a, v, s])

        y1 = sign * first.extra['current_a'][axis]
        coef, *_ = np.linalg.lstsq(design(first), y1, rcond=None)
        out[axis] = design(second) @ coef
    return out


def figures(t: np.ndarray, v: np.ndarray, meas: np.ndarray, pred: np.ndarray) -> tuple:
    """RMSE [A], R^2, measured and predicted ∫|I·v| dt [A·m], its error [%]."""
    e_m, e_p = integral(t, meas, v), integral(t, pred, v)
    rmse = math.sqrt(float(np.mean((meas - pred) ** 2)))
    return rmse, r2(meas, pred), e_m, e_p, 100.0 * (e_p - e_m) / e_m


def table(title: str, rows: list[tuple]) -> None:
    """Print one block of figures."""
    print(title)
    print(f'  {"axis":4} {"model":34} {"RMSE [A]":>9} {"R2":>7} {"∫|I·v| meas":>12} '
          f'{"pred [A·m]":>11} {"err [%]":>8}')
    for axis, model, (rmse, r2_, e_m, e_p, err) in rows:
        print(f'  {axis:4} {model:34} {rmse:9.4f} {r2_:7.4f} {e_m:12.4f} {e_p:11.4f} '
              f'{err:+8.2f}')


def main() -> int:
    """Print (a) and (b)."""
    c0 = time.process_time()
    campaign = kit_campaign()
    if campaign is None:
        return 1
    guessed = load_machine(campaign.machine)
    fitted, fits = calibrate(campaign, guessed)
    print('calibrated on the first half (val_air_1_first, fit-loss --method samples --fit-kt '
          '--fit-counterbalance):')
    for axis in AXES:
        f = fits[axis]
        extra = ('' if f.counterbalance_n is None
                 else f', counterbalance {f.counterbalance_n:.0f} N')
        print(f'  {axis}: kt {f.gain:.4g} N·m/A, Coulomb {f.coulomb_n:.1f} N, viscous '
              f'{f.viscous_n_s_m:.0f} N·s/m, hold at rest {f.standstill_hold_n:.1f} N'
              f'{extra}; moving samples R^2 {f.r2:.4f}')
    spec2 = campaign.run('val_air_1_second')
    first = load_run(campaign.run('val_air_1_first'))
    second = load_run(spec2)
    result = compare_campaign(campaign, machine=fitted, runs=['val_air_1_second']).runs[0]
    base = anchor(first, second, spec2.instrument.invert)
    rows = []
    for j, axis in enumerate(AXES):
        k = result.axes.index(axis)
        v = second.velocity_m_s[:, j]
        meas = result.signal_meas[:, k]
        rows.append((axis, 'anchor (1, a, v, sgn v), this run',
                     figures(second.t, v, meas, base[axis])))
        pred = result.signal_sim[:, k]
        rows.append((axis, 'fit-loss on the first half', figures(second.t, v, meas, pred)))
    table(f'(a) motion from the data, held-out second half ({second.t.size} samples, '
          f'{second.t[-1]:.1f} s):', rows)
    beaten = all(r[2][1] > b[2][1] for r, b in zip(rows[1::2], rows[0::2]))
    print(f'  the fitted model beats the anchor\'s R^2 on every axis: {beaten}')
    from_program(campaign, fitted)
    print(f'CPU time {time.process_time() - c0:.1f} s')
    return 0 if beaten else 1


def from_program(campaign: Campaign, fitted: Machine) -> None:
    """(b): the third run of the program in the record, simulated from the NC program."""
    program = shared_path('data', 'kit-dmc60h', *PROGRAM)
    if program is None:
        print(f'(b) skipped: {"/".join(PROGRAM)} not found ({HINT})')
        return
    whole = campaign.run('val_air_1')
    first = load_run(whole)
    start = tuple(float(v) for v in first.position_m[0])
    spec = replace(whole, name='third_run', motion_program=program, motion_from_data=None,
                   motion_start_m=start, window=TimeWindow(start=THIRD_RUN_S),
                   axes={a: {q: c for q, c in cols.items()
                             if q in ('position', 'current')}
                         for a, cols in whole.axes.items()})
    one = replace(campaign, runs=(spec,))
    run = load_run(spec)
    no_g57 = replace(fitted, gcode=replace(fitted.gcode, work_offsets_m=MappingProxyType({})))
    print(f'(b) motion from the program, its third run in the record ({THIRD_RUN_S:g} s to the '
          f'end, {run.t.size} samples), on the machine fitted in (a):')
    # G57 unknown: the program starts at the origin (where its first position would be
    # in machine coordinates is what is being estimated); then the config's G57, which is
    # that estimate rounded, from the trace's first position
    unknown = replace(campaign, runs=(replace(spec, motion_start_m=None),))
    for label, machine, runs in (('G57 taken as 0, start at the origin', no_g57, unknown),
                                 ('G57 of the config, start at the first row', fitted, one)):
        r = compare_campaign(runs, machine=machine).runs[0]
        w = r.work_offset
        assert w is not None
        cells = ', '.join(f'{a} {1e3 * u:+.2f} mm (spread {1e3 * sp:.1f})'
                          for a, u, sp in zip(w.axes, w.found_m, w.spread_m))
        print(f'  {label}: time offset {r.offset_used_s:+.3f} s ({r.offset.status}); work '
              f'offset found {cells} [{w.status}]')
    rows = []
    for k, axis in enumerate(r.axes):
        v = run.velocity_m_s[:, run.axes.index(axis)] if run.velocity_m_s is not None else \
            np.gradient(run.position_m[:, run.axes.index(axis)], run.t)
        rows.append((axis, 'fitted machine, program motion',
                     figures(run.t, v, r.signal_meas[:, k], r.signal_sim[:, k])))
    table('  current with the config\'s G57 (measured v in the integral):', rows)


if __name__ == '__main__':
    sys.exit(main())
