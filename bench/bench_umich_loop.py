"""UMich mill: ``analyze`` against ``fit-loss`` on unseen runs, and the floor of the data.

``PYTHONPATH=. .venv/bin/python bench/bench_umich_loop.py``

Loads ``config/campaigns/umich_mill.yaml`` with its data files looked up in the shared data
directory (env ``FAE_SHARED``, else ``../shared`` beside the repository; see
``bench/shared_lookup.py``) and its guessed machine ``config/umich_mill.yaml``. Prints

1. *Unseen runs, side by side*: energy error [%] and RMSE of the summed axis power [W] of
   every run a method did not see, and the pooled RMSE over all five runs and over the
   validate runs (exp03, exp06):

   * the guessed machine as it is;
   * ``analyze`` (default options) with ``--holdout loro``: each run's *after* adds the
     effects fitted without it, re-aligned (what ``analyze --json`` lists under ``after``);
   * ``fit-loss --method samples`` left one run out: fitted on the other four runs, the
     held-out run compared with that machine (the same protocol as ``analyze``'s loro);
   * ``analyze --holdout roles`` and ``fit-loss --method samples`` fitted on the calibrate
     runs: the validate runs only.

2. *The floor*: how low the RMSE of any model that predicts power from the motion can go on
   these records, measured on the data themselves (numpy only, no pipeline):

   * the meter: the standard deviation of each axis's power while every axis stands still
     (speed below 0.1 mm/s on X, Y and Z);
   * a least-squares fit of each axis's measured power on the measured kinematics at the
     power's own stamps, left one run out: ``m·a·v``, Coulomb ``F+·v`` and ``F-·|v|`` by
     direction, viscous ``c·v²`` (the model ``fit-loss --method samples`` fits, with the
     kinematics read at the stamps instead of simulated), and a richer one that adds the
     kinematics of the two samples before and after, the commanded columns and every
     product of three of (v, a, commanded v, commanded a, sign v): what a better motion
     model could at most add;
   * the same fit with the measured drive current's ``I·v`` and ``I²`` added: not a
     prediction (the current is measured, not simulated), but it shows how much of the
     residual the drive current carries that the motion does not;
   * the effective moved mass fitted on each run alone, per axis.

3. *Why ``analyze`` does not add the inertia*: the residual design ``analyze`` builds (its
   selection is wrapped to keep it; a study, not an interface) after ``coulomb@Y``, the
   per-run held-out gain of adding ``mass_error`` on X, and on X and Y, scored per axis (as
   the selection scores) and on the summed power (as ``compare``, ``fit-loss`` and
   ``analyze``'s *after* report).

4. *Runs no method saw*: experiments 04, 05 and 07 (stopped early, so left out of the
   campaign; the same program, machine and meter, 46–57 s each) compared with the guessed
   machine, with ``analyze``'s augmented machine (default options, all five runs) and with
   ``fit-loss --method samples`` fitted on all five runs: energy error [%] and RMSE [W] per
   run, and the energy each machine misses per axis and speed band [J], since these records
   hold axis speeds that no campaign run reaches (Y at 40–50 mm/s).

CPU time at the end (``time.process_time``).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
import itertools
import time
from typing import Any

import numpy as np

from feed_axis_energy.identify import AnalyzeOptions
from feed_axis_energy.identify import analyze as analyze_module
from feed_axis_energy.identify.analyze import analyze_campaign
from feed_axis_energy.identify.selection import Block, Design
from feed_axis_energy.identify.fit.samplefit import fit_loss_samples, machine_with_sample_fits
from feed_axis_energy.machine import Machine
from feed_axis_energy.machine.file import load_machine
from feed_axis_energy.measured.campaign import Campaign
from feed_axis_energy.measured.compare import compare_campaign
from feed_axis_energy.measured.csvload import load_run
from feed_axis_energy.measured.metrics import group_metrics, Metrics
from feed_axis_energy.measured.run import MeasuredRun
from bench_umich_motion import umich_campaign  # bench/ is sys.path[0]

STILL_M_S = 1e-4
"""Speed below which an axis stands still [m/s] (0.1 mm/s)."""

Row = dict[str, Metrics]


# ----------------------------------------------------------------------------- methods

def analyze_rows(campaign: Campaign, holdout: str) -> Row:
    """``analyze`` with default options: the *after* metrics of its held-out runs."""
    res = analyze_campaign(campaign, options=AnalyzeOptions(holdout=holdout))
    found = [f'{e.id}@{e.axis}' for e in res.effects]
    offered = [f'{e.id}@{e.axis}' for e in res.offered]
    print(f'  analyze {holdout}: {res.status}; named {", ".join(found) or "none"}; offered '
          f'{", ".join(offered) or "none"}')
    return {r.name: r.after for r in res.runs if r.heldout}


def fit_loss_machine(campaign: Campaign, names: Sequence[str]) -> Machine:
    """``fit-loss --method samples`` on the named runs: the guessed machine refitted."""
    guessed = load_machine(campaign.machine)
    specs = [campaign.run(n) for n in names]
    fits = fit_loss_samples([load_run(s) for s in specs], machine=guessed,
                            velocity=[s.motion_from_data or 'auto' for s in specs])
    return machine_with_sample_fits(guessed, fits)


def fit_loss_rows(campaign: Campaign, folds: Sequence[tuple[list[str], list[str]]]) -> Row:
    """``fit-loss --method samples`` on each fold's train runs, compared on its test runs."""
    out: Row = {}
    for train, test in folds:
        machine = fit_loss_machine(campaign, train)
        for r in compare_campaign(campaign, machine=machine, runs=test).runs:
            out[r.name] = r.metrics
    return out


def declared_rows(campaign: Campaign, names: Sequence[str]) -> Row:
    """The guessed machine as it is."""
    return {r.name: r.metrics for r in compare_campaign(campaign, runs=list(names)).runs}


def print_table(names: Sequence[str], validate: Sequence[str],
                rows: Sequence[tuple[str, Row]]) -> None:
    """One line per method: dE [%] and RMSE [W] per run, pooled RMSE (all, validate)."""
    print(f'{"method":34}' + ''.join(f'{n:>17}' for n in names)
          + f'{"pooled":>9}{"validate":>10}')
    print(f'{"":34}' + ''.join(f'{"dE [%] RMSE [W]":>17}' for _ in names)
          + f'{"RMSE [W]":>9}{"RMSE [W]":>10}')
    for label, row in rows:
        cells = ''.join(f'{row[n].energy_error_pct:+9.2f} {row[n].rmse_w:6.3f} ' if n in row
                        else f'{"":>17}' for n in names)
        every = [row[n] for n in names if n in row]
        pooled = group_metrics(every).rmse_w if len(every) == len(names) else None
        val = group_metrics([row[n] for n in validate]).rmse_w
        print(f'{label:34}{cells}' + (f'{pooled:9.3f}' if pooled is not None else f'{"":>9}')
              + f'{val:10.3f}')


# ----------------------------------------------------------------------------- the floor

def _shift(x: np.ndarray, k: int) -> np.ndarray:
    """``x`` moved by ``k`` samples (later for ``k > 0``), edges held."""
    if k > 0:
        return np.concatenate([np.repeat(x[:1], k), x[:-k]])
    return np.concatenate([x[-k:], np.repeat(x[-1:], -k)])


def basic_columns(run: MeasuredRun, j: int) -> list[np.ndarray]:
    """``a·v``, ``v⁺``, ``|v⁻|``, ``v²`` of axis ``j`` at the stamps (SI)."""
    assert run.velocity_m_s is not None and run.acceleration_m_s2 is not None
    v, a = run.velocity_m_s[:, j], run.acceleration_m_s2[:, j]
    return [a * v, np.where(v > STILL_M_S, v, 0.0), np.where(v < -STILL_M_S, -v, 0.0), v * v]


def rich_columns(run: MeasuredRun, j: int) -> list[np.ndarray]:
    """The basic columns, the neighbours' kinematics, the commanded ones, cubic products."""
    assert run.velocity_m_s is not None and run.acceleration_m_s2 is not None
    assert run.command_velocity_m_s is not None and run.command_acceleration_m_s2 is not None
    v, a = run.velocity_m_s[:, j], run.acceleration_m_s2[:, j]
    vc, ac = run.command_velocity_m_s[:, j], run.command_acceleration_m_s2[:, j]
    cols = basic_columns(run, j)
    for k in (-2, -1, 1, 2):
        cols += [_shift(a, k) * v, _shift(ac, k) * v, np.where(v > STILL_M_S, _shift(v, k), 0.0),
                 np.where(v < -STILL_M_S, _shift(v, k), 0.0)]
    cols += [ac * v, ac * vc, a * vc]
    base = [v, a, vc, ac, np.sign(v) * (np.abs(v) > STILL_M_S)]
    cols += [base[p] * base[q] * base[r]
             for p, q, r in itertools.combinations_with_replacement(range(len(base)), 3)]
    return cols


def current_columns(run: MeasuredRun, j: int) -> list[np.ndarray]:
    """The basic columns and the measured current's ``I·v`` and ``I²``."""
    assert run.velocity_m_s is not None
    i = run.extra['current_a'][run.power_axes[j]]
    return basic_columns(run, j) + [i * run.velocity_m_s[:, j], i * i]


def loro_floor(runs: Sequence[MeasuredRun],
               columns: Callable[[MeasuredRun, int], list[np.ndarray]],
               *, ridge: float = 0.0) -> dict[str, tuple[float, float, float, int]]:
    """Leave one run out: per held-out run ``(RMSE [W], dE [%], SSE [W²], n)`` of the summed
    axis power, each axis fitted by (ridge) least squares on the other runs."""
    out = {}
    for held in runs:
        pred = np.zeros(held.t.shape[0])
        for j, axis in enumerate(held.power_axes):
            train = [r for r in runs if r is not held]
            x = np.vstack([np.column_stack(columns(r, r.power_axes.index(axis)))
                           for r in train])
            y = np.concatenate([r.power_w[:, r.power_axes.index(axis)] for r in train])
            scale = np.sqrt(np.mean(x * x, axis=0)) + 1e-300
            xs = x / scale
            theta = np.linalg.solve(xs.T @ xs + ridge * y.size * np.eye(xs.shape[1]),
                                    xs.T @ y) / scale
            pred += np.column_stack(columns(held, j)) @ theta
        meas = held.total_power_w
        res = meas - pred
        sse = float(res @ res)
        out[held.name] = (float(np.sqrt(sse / res.size)),
                          100.0 * (float(pred.sum()) / float(meas.sum()) - 1.0), sse, res.size)
    return out


def print_floor(runs: Sequence[MeasuredRun], validate: Sequence[str]) -> None:
    """Part 2 of the module docstring."""
    print('meter noise while every axis stands still: std of the axis power [W] (samples)')
    for r in runs:
        assert r.velocity_m_s is not None
        still = np.all(np.abs(r.velocity_m_s) < STILL_M_S, axis=1)
        cells = ' '.join(f'{a} {np.std(r.power_w[still, j]):.4f}'
                         for j, a in enumerate(r.power_axes))
        print(f'  {r.name}: {cells} ({int(still.sum())})')
    names = [r.name for r in runs]
    print('\nleave one run out, summed axis power: dE [%] and RMSE [W] per held-out run')
    print(f'{"model":34}' + ''.join(f'{n:>17}' for n in names) + f'{"pooled":>9}'
          f'{"validate":>10}')
    for label, columns, ridge in (
            ('m a v, Coulomb +/-, viscous', basic_columns, 0.0),
            ('richer motion model (ridge 1e-3)', rich_columns, 1e-3),
            ('... + measured I v, I^2 (no model)', current_columns, 0.0)):
        res = loro_floor(runs, columns, ridge=ridge)
        pooled = np.sqrt(sum(v[2] for v in res.values()) / sum(v[3] for v in res.values()))
        val = np.sqrt(sum(res[n][2] for n in validate) / sum(res[n][3] for n in validate))
        print(f'{label:34}' + ''.join(f'{res[n][1]:+9.2f} {res[n][0]:6.3f} ' for n in names)
              + f'{pooled:9.3f}{val:10.3f}')
    print('\ndrive current against the commanded kinematics (I on a, sign v, v; fitted on all '
          'runs): RMS of what is left [A] and its autocorrelation at one sample, moving samples')
    for j, axis in enumerate(runs[0].power_axes):
        def design_i(r: MeasuredRun) -> np.ndarray:
            assert r.command_velocity_m_s is not None
            assert r.command_acceleration_m_s2 is not None
            v, a = r.command_velocity_m_s[:, j], r.command_acceleration_m_s2[:, j]
            return np.column_stack([a, (v > STILL_M_S) * 1.0, -1.0 * (v < -STILL_M_S), v])
        current = [r.extra['current_a'][axis] for r in runs]
        theta, *_ = np.linalg.lstsq(np.vstack([design_i(r) for r in runs]),
                                    np.concatenate(current), rcond=None)
        cells = []
        for r, i in zip(runs, current):
            assert r.velocity_m_s is not None
            moving = np.abs(r.velocity_m_s[:, j]) > STILL_M_S
            e = (i - design_i(r) @ theta)[moving]
            e = e - e.mean()
            acf = float(e[:-1] @ e[1:] / (e @ e))
            cells.append(f'{r.name} {np.sqrt(np.mean(e * e)):.2f} ({acf:+.2f})')
        print(f'  {axis}: std of I {np.std(np.concatenate(current)):.2f} A; ' + ' '.join(cells))
    print('\neffective moved mass fitted on each run alone (m a v, Coulomb +/-, viscous) [kg], '
          '+- its standard error (heteroscedasticity-robust), and the chi-square of one mass')
    for j, axis in enumerate(runs[0].power_axes):
        masses, errors = [], []
        for r in runs:
            x = np.column_stack(basic_columns(r, j))
            theta, *_ = np.linalg.lstsq(x, r.power_w[:, j], rcond=None)
            res = r.power_w[:, j] - x @ theta
            inv = np.linalg.inv(x.T @ x)
            cov = inv @ (x.T * res ** 2) @ x @ inv
            masses.append(float(theta[0]))
            errors.append(float(np.sqrt(cov[0, 0])))
        m, e = np.array(masses), np.array(errors)
        mean = float(np.sum(m / e ** 2) / np.sum(1.0 / e ** 2))
        chi2 = float(np.sum(((m - mean) / e) ** 2))
        print(f'  {axis}: ' + ' '.join(f'{n} {a:.0f}+-{b:.0f}' for n, a, b in zip(names, m, e))
              + f'; weighted mean {mean:.0f}, chi2 {chi2:.1f} on {m.size - 1} dof')


def print_selection_study(campaign: Campaign) -> None:
    """Part 3 of the module docstring."""
    kept: dict[str, tuple[Design, Any]] = {}
    inner = analyze_module.select_consistent

    def keep(design: Design, folds: Any, options: AnalyzeOptions, **kw: Any) -> Any:
        kept.setdefault('design', (design, folds))
        return inner(design, folds, options, **kw)
    analyze_module.select_consistent = keep
    try:
        axes = analyze_campaign(campaign, options=AnalyzeOptions(realign=False)).axes
    finally:
        analyze_module.select_consistent = inner
    design, folds = kept['design']
    first: dict[tuple[str, str], Block] = {}
    for block in design.blocks:
        first.setdefault(block.key, block)
    k = len(axes)     # the residual of the measured axes is flattened sample by sample

    def cols(keys: Sequence[tuple[str, str]]) -> list[int]:
        return [c for key in keys for c in first[key].cols]

    def mse(keys: Sequence[tuple[str, str]], summed: bool) -> list[float]:
        out = []
        for train, test in folds:
            theta = design.fit(cols(keys), train)
            for r in test:
                res = design.y[r] - design.predict(cols(keys), theta, r)
                if summed:
                    res = res.reshape(-1, k).sum(axis=1)
                out.append(float(res @ res) / res.size)
        return out
    both = [('coulomb', 'X'), ('coulomb', 'Y'), ('mass_error', 'X'), ('mass_error', 'Y')]
    theta = design.fit(cols(both), range(design.runs))
    print('coulomb and mass_error on X and Y fitted on every run at the baseline offsets: '
          f'dm X {theta[4]:+.0f} kg, dm Y {theta[5]:+.0f} kg')
    base = [('coulomb', 'Y')]
    print('held-out gain [%] per run (1 - mse with / mse without), beside coulomb@Y, at the '
          'baseline offsets')
    for label, extra in (('mass_error@X', [('mass_error', 'X')]),
                         ('mass_error@X + @Y', [('mass_error', 'X'), ('mass_error', 'Y')])):
        for summed in (False, True):
            without, with_ = mse(base, summed), mse(base + extra, summed)
            gains = 100.0 * (1.0 - np.array(with_) / np.array(without))
            se = float(np.std(gains, ddof=1) / np.sqrt(gains.size))
            print(f'  {label:18} {"summed power" if summed else "per axis":12} '
                  + ' '.join(f'{g:+6.1f}' for g in gains)
                  + f'   mean {gains.mean():+.1f} +- {se:.1f}')


UNSEEN = (('exp04', 'experiment_04.csv'), ('exp05', 'experiment_05.csv'),
          ('exp07', 'experiment_07.csv'))
"""Runs of the data set that stopped early (``train.csv``: machining not finalized)."""

SPEED_BANDS_MM_S = (0.5, 4.0, 12.0, 25.0, 40.0, 60.0)
"""Edges of the speed bands of part 4 [mm/s] (below the first: standing still)."""


def unseen_campaign(campaign: Campaign) -> Campaign:
    """The campaign's settings on the runs of :data:`UNSEEN` (their files beside the others)."""
    first = campaign.runs[0]
    return replace(campaign, runs=tuple(
        replace(first, name=name, data=first.data.parent / file, role='validate')
        for name, file in UNSEEN))


def print_unseen(campaign: Campaign) -> None:
    """Part 4: the runs no method saw, compared with each method's machine."""
    unseen = unseen_campaign(campaign)
    guessed = load_machine(campaign.machine)
    fitted = fit_loss_machine(campaign, [s.name for s in campaign.runs])
    res = analyze_campaign(campaign, options=AnalyzeOptions())
    machines = (('guessed machine', guessed), ('analyze (all five runs)',
                                               res.augmented_machine()),
                ('fit-loss samples (all five runs)', fitted))
    names = [name for name, _ in UNSEEN]
    records = {s.name: load_run(s) for s in unseen.runs}
    print(f'{"machine":34}' + ''.join(f'{n:>17}' for n in names) + f'{"pooled":>9}')
    print(f'{"":34}' + ''.join(f'{"dE [%] RMSE [W]":>17}' for _ in names) + f'{"RMSE [W]":>9}')
    missed: dict[str, dict[tuple[str, int], float]] = {}
    for label, machine in machines:
        cmp = compare_campaign(unseen, machine=machine)
        cells = ''.join(f'{r.metrics.energy_error_pct:+9.2f} {r.metrics.rmse_w:6.3f} '
                        for r in cmp.runs)
        print(f'{label:34}{cells}{group_metrics([r.metrics for r in cmp.runs]).rmse_w:9.3f}')
        band = missed.setdefault(label, {})
        for r in cmp.runs:
            rec = records[r.name]
            if r.signal_meas is None or r.signal_sim is None:
                continue
            dt = np.gradient(r.t)
            for j, axis in enumerate(rec.axes[:r.signal_meas.shape[1]]):
                speed = 1e3 * np.abs(rec.velocity_m_s[:, j])
                k = np.searchsorted(SPEED_BANDS_MM_S, speed, side='right')
                gap = (r.signal_meas[:, j] - r.signal_sim[:, j]) * dt
                for b in range(len(SPEED_BANDS_MM_S)):
                    band[(axis, b)] = band.get((axis, b), 0.0) + float(gap[k == b].sum())
    pairs = zip(SPEED_BANDS_MM_S, SPEED_BANDS_MM_S[1:])
    edges = ('still',) + tuple(f'{lo:g}-{hi:g}' for lo, hi in pairs)
    print('energy the machine misses (measured - simulated) [J], runs pooled, by axis and '
          'speed band [mm/s]')
    axes = sorted({a for b in missed.values() for a, _ in b})
    print(f'{"machine":34}' + ''.join(f'{a + " " + e:>11}' for a in axes for e in edges))
    for label, band in missed.items():
        print(f'{label:34}' + ''.join(f'{band.get((a, b), 0.0):+11.1f}' for a in axes
                                      for b in range(len(edges))))
    for label, c in (('the campaign runs', campaign), ('the unseen runs', unseen)):
        print(f'fastest measured axis speed in {label} [mm/s]: '
              + ', '.join(f'{a} {v:.1f}' for a, v in sorted(fastest(c).items())))


def fastest(campaign: Campaign) -> dict[str, float]:
    """The fastest absolute measured speed of each axis over the campaign's runs [mm/s]."""
    top: dict[str, float] = {}
    for spec in campaign.runs:
        rec = load_run(spec)
        for j, axis in enumerate(rec.axes):
            top[axis] = max(top.get(axis, 0.0), 1e3 * float(np.abs(rec.velocity_m_s[:, j]).max()))
    return top


def main() -> int:
    """Print the four parts."""
    c0 = time.process_time()
    campaign = umich_campaign()
    if campaign is None:
        return 1
    names = [s.name for s in campaign.runs]
    calibrate = [s.name for s in campaign.runs_with_role('calibrate')]
    validate = [s.name for s in campaign.runs_with_role('validate')]
    print('1. unseen runs: dE [%] and RMSE [W] of the summed axis power')
    rows = [('guessed machine', declared_rows(campaign, names)),
            ('analyze, loro', analyze_rows(campaign, 'loro')),
            ('fit-loss samples, loro', fit_loss_rows(
                campaign, [([n for n in names if n != held], [held]) for held in names])),
            ('analyze, roles', analyze_rows(campaign, 'roles')),
            ('fit-loss samples, calibrate runs', fit_loss_rows(campaign,
                                                               [(calibrate, validate)]))]
    print_table(names, validate, rows)
    print('\n2. the floor')
    print_floor([load_run(s) for s in campaign.runs], validate)
    print('\n3. why the selection does not name the inertia')
    print_selection_study(campaign)
    print('\n4. runs no method saw (stopped early, not in the campaign)')
    print_unseen(campaign)
    print(f'CPU time {time.process_time() - c0:.1f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
