"""Virtual test rig: "measured" campaigns made from a truth model, for testing the analysis.

The truth model and the instrument that records it (one run, in memory) are in
:mod:`.truth`; this module builds campaigns of such runs (one per feed and load) and
writes them to disk.

Output directory (:func:`make_campaign`)::

    manifest.yaml      campaign manifest read by measured.load_campaign
    machine.yaml       copy of the declared machine file
    programs/f<F>.nc   reciprocating stroke at F mm/s on the machine's load axis
    runs/<run>.csv     one CSV per run (layout below)
    truth.json         true effects, parameters and offsets (for tests only)
    bags/<run>/        optional rosbag2/MCAP of the same record (RigConfig.bags)

CSV layout, one row per instrument stamp: ``time_ms`` (instrument clock [ms], starts at
``CLOCK_START_MS``), then per axis ``<A>_power_kW`` [kW], ``<A>_position_mm`` [mm] and
``<A>_velocity_mm_s`` [mm/s] (instantaneous values at the stamp). The same seed gives
byte-identical files.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, replace
import json
import math
from pathlib import Path
import shutil
from typing import Any, Callable

import numpy as np
import yaml

from ...effects import get_effect
from ...errors import ConfigError
from ...machine import load_machine
from ...outputs import marked_or_empty, staged_directory
from .truth import EffectSpec, Instrument, OUTSIDE_KINDS, RigRun, simulate_run

__all__ = ['PAPER_LOADS_KG', 'PAPER_FEEDS_MM_S', 'CLOCK_START_MS', 'RigConfig', 'paper_scenario',
           'stroke_program', 'make_campaign']

PAPER_LOADS_KG = (0.0, 17.336, 22.711)
PAPER_FEEDS_MM_S = (100.0, 200.0, 300.0, 400.0, 500.0)
CLOCK_START_MS = 60000.0
MARKER = '.feed_axis_energy_rig'


@dataclass(frozen=True)
class RigConfig:
    """A virtual campaign.

    Attributes
    ----------
    machine
        Declared machine file (also the truth's base).
    loads_kg, feeds_mm_s
        One run per (feed, load).
    effects
        Truth effects the declared model lacks.
    instrument
        Measurement artefacts.
    seed
        Seed of every random draw (offsets, noise).
    offset_s
        Start offset of every record [s]; ``None`` draws one per run in [0.2, 0.8) s.
    outside
        ``None`` or a key of :data:`OUTSIDE_KINDS`.
    stroke_mm, cycles, dwell_s
        The reciprocating program (paper: 400 mm, 1 s dwell).
    tail_s
        Recording after the program ends [s].
    bags
        Also write ``bags/<run>/`` (rosbag2/MCAP, topics ``/measured/power`` and
        ``/measured/kinematics``, file time); not byte-reproducible, so off by default.
    program
        ``program(feed_mm_s) -> NC text`` of each feed's run; ``None``: the reciprocating
        stroke on the machine's load axis (``stroke_mm``, ``cycles``, ``dwell_s``).
    record_window_s
        ``(late, early)`` [s]: the meter started ``late`` after the record's start and
        stopped ``early`` before its end (file times keep their values), so a record can
        miss the program's non-periodic start and end; ``(0, 0)``: the whole record.
    """

    machine: Path
    loads_kg: tuple[float, ...] = PAPER_LOADS_KG
    feeds_mm_s: tuple[float, ...] = PAPER_FEEDS_MM_S
    effects: tuple[EffectSpec, ...] = ()
    instrument: Instrument = Instrument()
    seed: int = 0
    offset_s: float | None = None
    outside: str | None = None
    stroke_mm: float = 400.0
    cycles: int = 3
    dwell_s: float = 1.0
    tail_s: float = 1.0
    bags: bool = False
    program: Callable[[float], str] | None = None
    record_window_s: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        late, early = self.record_window_s
        if not (math.isfinite(late) and math.isfinite(early) and late >= 0.0
                and early >= 0.0):
            msg = f'record window must be two finite numbers >= 0 s, got {self.record_window_s}'
            raise ConfigError(msg, key='record_window_s')


def paper_scenario(machine: str | Path, *, seed: int = 0, mu: float = 0.1,
                   noise_w: float = 2.0, outside: str | None = None) -> RigConfig:
    """The paper's verification campaign with load-dependent friction in the truth.

    Declared loss function as in ``machine``; runs at 0, 17.336 and 22.711 kg and 100 ... 500
    mm/s; truth adds ``load_friction`` with ``mu``; 50 ms averaging meter with noise and 1 W
    quantisation; a random start offset per run. With ``mu = 0.1`` the 22.711 kg load adds
    2.2 W at 100 mm/s and 11 W at 500 mm/s of friction power over the empty table.
    """
    return RigConfig(machine=Path(machine), effects=(EffectSpec('load_friction', {'mu': mu}),),
                     instrument=Instrument(noise_w=noise_w), seed=seed, outside=outside)


def stroke_program(feed_mm_s: float, *, axis: str, stroke_mm: float = 400.0,
                   cycles: int = 3, dwell_s: float = 1.0) -> str:
    """NC text of the paper's reciprocating stroke: ``cycles`` back-and-forth moves."""
    feed = f'{feed_mm_s * 60.0:g}'
    lines = [f'( virtual rig: reciprocating {stroke_mm:g} mm stroke on {axis} at '
             f'{feed_mm_s:g} mm/s, {dwell_s:g} s dwell )', 'G21 G90 G94 G61',
             f'G0 {axis}0', f'G4 P{dwell_s:g}']
    for _ in range(cycles):
        lines += [f'G1 {axis}{stroke_mm:g} F{feed}', f'G4 P{dwell_s:g}',
                  f'{axis}0', f'G4 P{dwell_s:g}']
    lines.append('M30')
    return '\n'.join(lines) + '\n'


def _prepare_out(out: Path) -> None:
    (out / 'programs').mkdir(parents=True)
    (out / 'runs').mkdir()
    (out / MARKER).write_text('written by the feed_axis_energy virtual rig\n')


def _trim(run: RigRun, window: tuple[float, float], name: str) -> RigRun:
    """The samples of ``run`` the meter recorded within ``window`` (late, early) [s]."""
    late, early = window
    if late == 0.0 and early == 0.0:
        return run
    keep = (run.stamps_s >= run.stamps_s[0] + late) & (run.stamps_s <= run.stamps_s[-1] - early)
    if int(keep.sum()) < 2:
        msg = (f'run {name}: the record window ({late:g} s late, {early:g} s early) leaves '
               f'fewer than 2 of its {run.stamps_s.size} samples')
        raise ConfigError(msg, key='record_window_s')
    # file time starts at the first recorded sample (what a reader of the file sees): the
    # record's offset moves with it
    first = float(run.stamps_s[keep][0])
    return replace(run, stamps_s=run.stamps_s[keep] - first, measured_w=run.measured_w[keep],
                   offset_s=run.offset_s - first)


def _write_csv(path: Path, run: RigRun, axes: tuple[str, ...]) -> None:
    motion_t = run.result.motion.t
    sim_t = run.stamps_s - run.offset_s
    header = ['time_ms']
    cols = [CLOCK_START_MS + run.stamps_s * 1000.0]
    fmt = ['{:.3f}']
    for j, axis in enumerate(axes):
        pos = np.interp(sim_t, motion_t, run.result.motion.pos[:, j])
        vel = np.interp(sim_t, motion_t, run.result.motion.vel[:, j])
        header += [f'{axis}_power_kW', f'{axis}_position_mm', f'{axis}_velocity_mm_s']
        cols += [run.measured_w[:, j] / 1000.0, pos * 1000.0, vel * 1000.0]
        fmt += ['{:.12g}', '{:.4f}', '{:.4f}']
    lines = [','.join(header)]
    for row in zip(*cols):
        # '+ 0.0' turns -0.0 into 0.0 so that files do not depend on rounding signs.
        lines.append(','.join(f.format(float(v) + 0.0) for f, v in zip(fmt, row)))
    path.write_text('\n'.join(lines) + '\n', encoding='utf-8')


def _write_bag(path: Path, run: RigRun, axes: tuple[str, ...]) -> None:
    from ...record import bagio, StreamBagWriter
    power = run.measured_w
    total = power.sum(axis=1)
    both = np.column_stack([power, total])
    dt = np.diff(run.stamps_s)[:, None]
    energy = np.vstack([np.zeros((1, both.shape[1])),
                        np.cumsum(0.5 * (both[1:] + both[:-1]) * dt, axis=0)])
    sim_t = run.stamps_s - run.offset_s
    motion = run.result.motion
    pos = np.column_stack([np.interp(sim_t, motion.t, motion.pos[:, j]) for j in range(len(axes))])
    vel = np.column_stack([np.interp(sim_t, motion.t, motion.vel[:, j]) for j in range(len(axes))])
    path.parent.mkdir(parents=True, exist_ok=True)
    with StreamBagWriter(path) as writer:
        writer.write_series(bagio.TOPIC_MEASURED_POWER, bagio.Series(
            t=run.stamps_s, names=tuple(axes) + ('total',), positions=energy, velocities=both))
        writer.write_series(bagio.TOPIC_MEASURED_KINEMATICS, bagio.Series(
            t=run.stamps_s, names=tuple(axes), positions=pos, velocities=vel))


def _manifest(config: RigConfig, axes: tuple[str, ...],
              runs: list[dict[str, Any]]) -> dict[str, Any]:
    columns = {a: {'power': {'column': f'{a}_power_kW', 'unit': 'kW'},
                   'position': {'column': f'{a}_position_mm', 'unit': 'mm'},
                   'velocity': {'column': f'{a}_velocity_mm_s', 'unit': 'mm/s'}}
               for a in axes}
    return {
        'name': 'virtual_rig',
        'description': (f'virtual test rig, seed {config.seed}: time_ms [ms], per axis '
                        '<A>_power_kW [kW] (50 ms interval average), <A>_position_mm [mm], '
                        '<A>_velocity_mm_s [mm/s]'),
        'machine': 'machine.yaml',
        'defaults': {'time': {'column': 'time_ms', 'unit': 'ms'}, 'axes': columns},
        'runs': [{'name': r['name'], 'notes': r['notes'], 'load_kg': r['load_kg'],
                  'motion': {'program': r['program']}, 'data': r['data'], 'role': r['role']}
                 for r in runs],
    }


def make_campaign(out: str | Path, config: RigConfig, *,
                  progress: Callable[[float], None] | None = None, force: bool = False,
                  option: str = '--out') -> Path:
    """Write a virtual campaign (manifest, machine, programs, CSVs, truth) into ``out``.

    ``out`` must not exist; with ``force`` an empty directory or an earlier rig output is
    replaced. All or nothing: the campaign is built in a hidden temporary directory and
    renamed into place when complete (:func:`.outputs.staged_directory`); ``option`` names
    ``out`` in error messages.

    Returns
    -------
    pathlib.Path
        The manifest file.
    """
    out = Path(out)
    machine = load_machine(config.machine)
    for spec in config.effects:
        get_effect(spec.id).resolve(spec.params)
    if config.outside is not None and config.outside not in OUTSIDE_KINDS:
        msg = f'unknown outside-catalog effect {config.outside!r}; ' \
              f'expected one of {", ".join(OUTSIDE_KINDS)}'
        raise ConfigError(msg, key='outside')
    if not config.loads_kg or not config.feeds_mm_s:
        raise ConfigError('the rig needs at least one load and one feed', key='loads/feeds')
    if any(not (math.isfinite(f) and f > 0.0) for f in config.feeds_mm_s):
        msg = f'feeds must be finite numbers > 0 mm/s, got {list(config.feeds_mm_s)}'
        raise ConfigError(msg, key='feeds')
    with staged_directory(out, option=option, force=force,
                          replaceable=marked_or_empty(MARKER)) as staged:
        _write_campaign(staged, config, machine, progress)
    return out / 'manifest.yaml'


def _write_campaign(out: Path, config: RigConfig, machine,
                    progress: Callable[[float], None] | None) -> None:
    """Write the campaign's files into ``out`` (a new directory)."""
    _prepare_out(out)
    shutil.copyfile(config.machine, out / 'machine.yaml')
    rng = np.random.default_rng(config.seed)
    runs: list[dict[str, Any]] = []
    axes: tuple[str, ...] = ()
    for i, feed in enumerate(config.feeds_mm_s):
        program_rel = f'programs/f{feed:g}.nc'
        text = (config.program(feed) if config.program is not None else
                stroke_program(feed, axis=machine.load_axis, stroke_mm=config.stroke_mm,
                               cycles=config.cycles, dwell_s=config.dwell_s))
        (out / program_rel).write_text(text, encoding='utf-8')
        for load in config.loads_kg:
            name = f'f{feed:g}_load{load:g}kg'
            offset = (float(rng.uniform(0.2, 0.8)) if config.offset_s is None
                      else float(config.offset_s))
            run = simulate_run(machine, text, load_kg=load, effects=config.effects,
                               instrument=config.instrument, offset_s=offset,
                               outside=config.outside, tail_s=config.tail_s, rng=rng,
                               file=program_rel)
            axes = run.result.power.axes
            run = _trim(run, config.record_window_s, name)
            data_rel = f'runs/{name}.csv'
            _write_csv(out / data_rel, run, axes)
            if config.bags:
                _write_bag(out / 'bags' / name, run, axes)
            if progress is not None:
                progress((len(runs) + 1) / (len(config.feeds_mm_s) * len(config.loads_kg)))
            runs.append({'name': name, 'load_kg': float(load), 'feed_mm_s': float(feed),
                         'offset_s': run.offset_s, 'program': program_rel, 'data': data_rel,
                         'role': 'calibrate' if i % 2 == 0 else 'validate',
                         'notes': f'feed {feed:g} mm/s, load {load:g} kg'})
    manifest = out / 'manifest.yaml'
    manifest.write_text(yaml.safe_dump(_manifest(config, axes, runs), sort_keys=False),
                        encoding='utf-8')
    truth = {
        'note': 'truth of the virtual rig: for tests only, an analyser must not read it',
        'machine': Path(config.machine).name, 'seed': config.seed,
        'effects': [{'id': s.id, 'params': get_effect(s.id).resolve(s.params)}
                    for s in config.effects],
        'outside': None if config.outside is None else {
            'kind': config.outside, 'params': OUTSIDE_KINDS[config.outside]},
        'instrument': asdict(config.instrument),
        'offset_convention': 'offset_s: how much later the record is than the simulation '
                             '(measured.align); file time 0 = first row',
        'clock_start_ms': CLOCK_START_MS,
        'runs': [{k: r[k] for k in ('name', 'load_kg', 'feed_mm_s', 'offset_s', 'program',
                                    'data', 'role')} for r in runs],
    }
    (out / 'truth.json').write_text(json.dumps(_jsonable(truth), indent=2, sort_keys=True)
                                    + '\n', encoding='utf-8')


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value
