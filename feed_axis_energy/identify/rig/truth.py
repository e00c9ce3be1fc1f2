"""Truth model and instrument of the virtual test rig (:mod:`.campaign`): one run, in memory.

Truth = the declared machine (its loss model, its braking rule) + catalog effects the
analysed model does not declare (:mod:`.effects`) + optionally one effect that is *not* in
the catalog (``outside``: a periodic disturbance at a frequency unrelated to the screw, or a
power step at a position), so that an analyser can be checked for honesty. Per axis::

    P_truth = P_declared + sum(effect.power_w(state, params)) [+ outside]

computed at the simulation rate (1 kHz) on the program's motion padded with rest before and
after. The instrument then

* stamps a sample every ``period_s`` (file time ``tau = 0, period, ...``) with the mean of
  ``P_truth`` over ``[tau - offset_s - window_s, tau - offset_s]`` (simulated time; the
  convention of :mod:`.measured.align`: ``offset_s`` is how much later the record is);
* applies a slow drift ``P·(1 + gain_drift·tau) + offset_drift·tau``;
* adds Gaussian noise (``noise_w``, independent per axis and sample);
* quantises to ``quantum_w``.

:mod:`.campaign` writes campaigns of such runs to disk.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
import math

import numpy as np

from ...effects import EffectState, get_effect
from ...physics import state_from_simulation
from ...errors import ConfigError
from ...gcode import parse_gcode
from ...machine import Machine
from ...measured import interval_average
from ...plan import Motion
from ...sim import simulate_motion, simulate_program, SimulationResult

__all__ = ['OUTSIDE_KINDS', 'EffectSpec', 'Instrument', 'RigRun', 'parse_effects',
           'outside_power_w', 'truth_power_w', 'instrument_record', 'simulate_run']

# Effects deliberately absent from the catalog, with their fixed parameters.
OUTSIDE_KINDS: dict[str, dict[str, float]] = {
    # e.g. a coolant pump on the same supply: 3.7 Hz has nothing to do with the screw.
    'periodic': {'amplitude_w': 20.0, 'frequency_hz': 3.7},
    # e.g. a cable chain that starts dragging beyond a position: a step, not a cosine.
    'position_step': {'step_w': 25.0, 'position_m': 0.25},
}


@dataclass(frozen=True)
class EffectSpec:
    """One truth effect: catalog id and parameter values (missing ones take defaults)."""

    id: str
    params: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Instrument:
    """The power meter: averaging window, report period, noise, quantisation, drift."""

    window_s: float = 0.05
    period_s: float = 0.05
    noise_w: float = 0.0
    quantum_w: float = 1.0
    gain_drift_per_s: float = 0.0
    offset_drift_w_per_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ('window_s', 'period_s'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                msg = f'{name} must be a finite number > 0, got {value!r}'
                raise ConfigError(msg, key=f'instrument.{name}')
        for name in ('noise_w', 'quantum_w'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                msg = f'{name} must be a finite number >= 0, got {value!r}'
                raise ConfigError(msg, key=f'instrument.{name}')


@dataclass(frozen=True)
class RigRun:
    """One virtual run: the truth at the simulation rate and what the instrument recorded.

    Attributes
    ----------
    result
        Simulation of the declared model on the padded motion.
    truth_w
        True power per axis [W], ``(n, k)`` on ``result.power.t``.
    stamps_s
        Instrument stamps [s] from the first sample, ``(m,)``.
    measured_w
        Recorded power per axis [W], ``(m, k)``.
    offset_s
        How much later the record is than the simulation [s].
    """

    result: SimulationResult
    truth_w: np.ndarray
    stamps_s: np.ndarray
    measured_w: np.ndarray
    offset_s: float


def parse_effects(text: str) -> tuple[EffectSpec, ...]:
    """Parse ``ID=PARAM:VALUE,PARAM:VALUE,ID2=...`` (or ``ID`` alone for example values).

    ``''`` or ``'none'`` gives no effect. An id without ``=`` takes every parameter's
    example value; with ``=``, unnamed parameters take their defaults.

    Raises
    ------
    ConfigError
        Unknown effect id or parameter (named), or a value that is not a number.
    """
    text = text.strip()
    if text in ('', 'none'):
        return ()
    out: list[tuple[str, dict[str, float]]] = []
    for item in (part.strip() for part in text.split(',')):
        if not item:
            continue
        if '=' in item or ':' not in item:
            effect_id, _, rest = item.partition('=')
            effect = get_effect(effect_id.strip())
            values = {} if '=' in item else {p.name: p.example for p in effect.params}
            out.append((effect.id, values))
            item = rest.strip()
            if not item:
                continue
        if not out:
            msg = f'{item!r} names no effect; expected ID=PARAM:VALUE'
            raise ConfigError(msg, key='effects')
        name, _, value = item.partition(':')
        effect_id, values = out[-1]
        try:
            number = float(value)
        except ValueError:
            msg = f'value of {effect_id}.{name.strip()} is not a number: {value!r}'
            raise ConfigError(msg, key='effects') from None
        values[name.strip()] = number
    specs = []
    for effect_id, values in out:
        get_effect(effect_id).resolve(values)
        specs.append(EffectSpec(effect_id, dict(values)))
    return tuple(specs)


def outside_power_w(kind: str, state: EffectState) -> np.ndarray:
    """Extra power of an effect outside the catalog [W], ``(n, k)`` (see OUTSIDE_KINDS)."""
    if kind not in OUTSIDE_KINDS:
        known = ', '.join(OUTSIDE_KINDS)
        msg = f'unknown outside-catalog effect {kind!r}; expected one of {known}'
        raise ConfigError(msg, key='outside')
    p = OUTSIDE_KINDS[kind]
    n, k = state.shape
    if kind == 'periodic':
        wave = p['amplitude_w'] * np.sin(2.0 * np.pi * p['frequency_hz'] * state.t)
        return np.broadcast_to(wave[:, None], (n, k)).copy()
    moving = state.velocity_m_s != 0.0
    return p['step_w'] * (moving & (state.position_m > p['position_m']))


def truth_power_w(result: SimulationResult, effects: Sequence[EffectSpec], *,
                  outside: str | None = None) -> np.ndarray:
    """Declared power after braking + truth effects (+ outside effect) per axis [W]."""
    state = state_from_simulation(result)
    total = np.array(result.power.power_w, dtype=float)
    for spec in effects:
        total += get_effect(spec.id).power_w(state, spec.params)
    if outside is not None:
        total += outside_power_w(outside, state)
    return total


def instrument_record(t: np.ndarray, power_w: np.ndarray, *, instrument: Instrument,
                      offset_s: float, end_s: float,
                      rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What the meter records of ``power_w`` (sampled at ``t``), see the module docstring.

    Parameters
    ----------
    t, power_w
        True power [W], ``(n,)`` or ``(n, k)``, at times ``t`` [s] (held outside).
    instrument
        The meter.
    offset_s
        How much later the record is than ``t``: the first stamp averages up to
        ``-offset_s`` of ``t``'s time.
    end_s
        Last time of ``t``'s scale to cover; stamps stop at or before it.
    rng
        Noise source (required when ``instrument.noise_w > 0``).

    Returns
    -------
    stamps, recorded
        File times from 0 [s] ``(m,)`` and recorded power [W], ``(m,)`` or ``(m, k)``.
    """
    count = int(math.floor((end_s + offset_s) / instrument.period_s + 1e-9)) + 1
    if count < 2:
        msg = f'record too short: end {end_s!r} s with offset {offset_s!r} s'
        raise ConfigError(msg, key='offset_s')
    stamps = np.arange(count) * instrument.period_s
    y = interval_average(t, power_w, stamps - offset_s, window_s=instrument.window_s)
    drift = stamps if y.ndim == 1 else stamps[:, None]
    y = y * (1.0 + instrument.gain_drift_per_s * drift) + instrument.offset_drift_w_per_s * drift
    if instrument.noise_w > 0.0:
        if rng is None:
            raise ConfigError('instrument noise needs a random generator', key='rng')
        y = y + rng.normal(0.0, instrument.noise_w, size=y.shape)
    if instrument.quantum_w > 0.0:
        y = np.round(y / instrument.quantum_w) * instrument.quantum_w
    return stamps, y


def _pad(motion: Motion, *, before_s: float, after_s: float, rate_hz: float) -> Motion:
    dt = 1.0 / rate_hz
    n_pre = int(math.ceil(before_s / dt))
    n_post = int(math.ceil(after_s / dt))
    t = np.concatenate([motion.t[0] - dt * np.arange(n_pre, 0, -1), motion.t,
                        motion.t[-1] + dt * np.arange(1, n_post + 1)])
    k = len(motion.axes)
    pos = np.vstack([np.repeat(motion.pos[:1], n_pre, axis=0), motion.pos,
                     np.repeat(motion.pos[-1:], n_post, axis=0)])
    rest = (np.zeros((n_pre, k)), np.zeros((n_post, k)))
    vel = np.vstack([rest[0], motion.vel, rest[1]])
    acc = np.vstack([rest[0], motion.acc, rest[1]])
    line = np.concatenate([np.zeros(n_pre, dtype=motion.line.dtype), motion.line,
                           np.zeros(n_post, dtype=motion.line.dtype)])
    return Motion(t=t, axes=motion.axes, pos=pos, vel=vel, acc=acc, line=line,
                  source=motion.source)


def simulate_run(machine: Machine, program_text: str, *, load_kg: float,
                 effects: Sequence[EffectSpec], instrument: Instrument, offset_s: float,
                 outside: str | None = None, tail_s: float = 1.0,
                 rng: np.random.Generator | None = None, file: str = '<rig>') -> RigRun:
    """Simulate one run of the truth model and record it with the instrument.

    The planned motion is padded with rest so that the first window (before the program
    starts when ``offset_s > 0``) and ``tail_s`` after its end are covered by the truth.
    """
    program = parse_gcode(program_text, file=file)
    options = machine.planner.options()
    planned = simulate_program(program, machine, load_kg=load_kg, options=options)
    margin = 3.0 / options.rate_hz
    motion = _pad(planned.motion, before_s=max(offset_s, 0.0) + instrument.window_s + margin,
                  after_s=tail_s + margin, rate_hz=options.rate_hz)
    result = simulate_motion(motion, machine, load_kg=load_kg)
    truth = truth_power_w(result, effects, outside=outside)
    stamps, measured = instrument_record(result.power.t, truth, instrument=instrument,
                                         offset_s=offset_s,
                                         end_s=float(planned.motion.t[-1]) + tail_s, rng=rng)
    return RigRun(result=result, truth_w=truth, stamps_s=stamps, measured_w=measured,
                  offset_s=float(offset_s))
