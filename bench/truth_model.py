"""An independent truth model of one ball-screw feed axis, for ``bench/truth_targets.py``.

Nothing here calls the project's planner, dynamics, loss models, effect catalog or rig: the
physics is written out again from the machine file's numbers, so that a campaign made here
checks ``analyze`` against a model it did not build. Only the file formats (CSV columns and
manifest keys of ``docs/measured.md``) are shared, because ``analyze`` has to read them.

Physics, per sample (SI units, one axis, screw efficiency 1 as in the demonstrator)::

    motion   rest-to-rest seven-phase constant-jerk strokes (limits of the machine file)
    m        table + load [kg];  J = motor + coupling + screw (solid cylinder) [kg m^2]
    F        m a + F_loss(v) + m g sin(theta) + sum of the extra forces at the nut [N]
    M        J alpha + F lead / (2 pi)        (alpha = 2 pi a / lead, omega = 2 pi v / lead)
    P        M omega + copper k M^2 + iron + standby + outside drive powers [W]

with the declared loss function read as the demonstrator's comment says: loss power
``a x^(1 + b)`` W at ``x = |v|`` in mm/s, opposing the motion. The meter averages ``P``
over 50 ms windows stamped at their end, adds 1.5 W Gaussian noise and quantises to 1 W;
its clock may run fast (``drift_ppm``) and may start seconds before or after the program.

Effects (``CATALOG``: what each catalog effect *is* physically, written independently of
``effects``; ``OUTSIDE``: effects the catalog does not hold) are given as a force at
the nut or as a power at the drive, each scaled by one amplitude so that the study can set
the RMS of its extra power.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path

import numpy as np
from scipy.signal import lfilter
import yaml

G = 9.80665
RATE_HZ = 2000.0          # truth sample rate: 0.5 ms, finer than the planner's 1 ms


@dataclass(frozen=True)
class AxisData:
    """The numbers of one axis, read from a machine file (not through our loader)."""

    table_kg: float
    lead_m: float
    inertia_kg_m2: float
    v_max: float
    a_max: float
    j_max: float
    loss_a: float
    loss_b: float
    sin_theta: float


def read_axis(path: Path) -> AxisData:
    """Read the load axis of a single-axis machine file with ``power_regression`` loss."""
    doc = yaml.safe_load(Path(path).read_text(encoding='utf-8'))
    ax = doc['axes'][doc['load_axis']]
    screw = ax['screw']
    inert = ax['inertias']
    j_screw = inert.get('screw_kg_m2')
    if j_screw is None:
        # solid steel cylinder: J = pi/32 rho L d^4
        j_screw = math.pi / 32.0 * screw['density_kg_m3'] * screw['length_m'] \
            * screw['diameter_m'] ** 4
    loss = ax['loss']
    if loss['model'] != 'power_regression' or loss['x_unit'] != 'mm/s' \
            or loss['y_unit'] != 'W/(mm/s)' or screw.get('efficiency', 1.0) != 1.0:
        raise ValueError('the truth model reads only the demonstrator-like file')
    lim = ax['limits']
    return AxisData(table_kg=float(ax['table_mass_kg']),
                    lead_m=float(screw['lead_m']) * int(screw.get('starts', 1)),
                    inertia_kg_m2=float(inert['motor_kg_m2'] + inert['coupling_kg_m2']
                                        + j_screw),
                    v_max=float(lim['velocity_m_s']), a_max=float(lim['acceleration_m_s2']),
                    j_max=float(lim['jerk_m_s3']), loss_a=float(loss['a']),
                    loss_b=float(loss['b']),
                    sin_theta=math.sin(math.radians(float(ax.get('inclination_deg', 0.0)))))


def _accel_time(v: float, a: float, j: float) -> float:
    """Time to go from rest to ``v`` with acceleration ``<= a`` and jerk ``j`` [s]."""
    return v / a + a / j if v >= a * a / j else 2.0 * math.sqrt(v / j)


def scurve(distance: float, *, v: float, a: float, j: float) -> list[tuple[float, float]]:
    """Jerk phases ``[(duration_s, jerk), ...]`` of a rest-to-rest move of ``distance`` > 0.

    Symmetric seven-phase profile: jerk up, constant acceleration, jerk down, cruise, and
    the mirror image. When the distance is too short to reach ``v``, the peak speed is
    lowered (bisection) until acceleration and braking just meet.
    """
    if distance * 1.0 < v * _accel_time(v, a, j):
        lo, hi = 0.0, v
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if mid * _accel_time(mid, a, j) < distance else (lo, mid)
        v = lo
    if v >= a * a / j:
        tj, ta, ap = a / j, v / a - a / j, a
    else:
        tj, ta, ap = math.sqrt(v / j), 0.0, math.sqrt(v * j)
    jj = ap / tj
    cruise = distance / v - _accel_time(v, a, j)
    return [(tj, jj), (ta, 0.0), (tj, -jj), (max(cruise, 0.0), 0.0),
            (tj, -jj), (ta, 0.0), (tj, jj)]


@dataclass
class Timeline:
    """Piecewise constant-jerk motion from rest at position 0: phases and their start states."""

    phases: list[tuple[float, float]] = field(default_factory=list)

    def dwell(self, duration: float) -> None:
        """Stand still for ``duration`` seconds."""
        self.phases.append((duration, 0.0))

    def move(self, distance: float, *, v: float, axis: AxisData) -> None:
        """A rest-to-rest move of signed ``distance`` [m] at feed ``v`` [m/s]."""
        sign = 1.0 if distance > 0 else -1.0
        for dur, jerk in scurve(abs(distance), v=min(v, axis.v_max), a=axis.a_max,
                                j=axis.j_max):
            self.phases.append((dur, sign * jerk))

    @property
    def duration(self) -> float:
        """Total time [s]."""
        return float(sum(d for d, _ in self.phases))

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration at times ``t`` (rest outside the timeline)."""
        x = np.zeros_like(t)
        v = np.zeros_like(t)
        acc = np.zeros_like(t)
        t0, x0, v0, a0 = 0.0, 0.0, 0.0, 0.0
        x[t >= 0.0] = 0.0
        for dur, jerk in self.phases:
            sel = (t >= t0) & (t < t0 + dur)
            h = t[sel] - t0
            acc[sel] = a0 + jerk * h
            v[sel] = v0 + a0 * h + 0.5 * jerk * h * h
            x[sel] = x0 + v0 * h + 0.5 * a0 * h * h + jerk * h ** 3 / 6.0
            x0 += v0 * dur + 0.5 * a0 * dur * dur + jerk * dur ** 3 / 6.0
            v0 += a0 * dur + 0.5 * jerk * dur * dur
            a0 += jerk * dur
            t0 += dur
            # rounding: a rest-to-rest move ends at rest exactly
            if abs(a0) < 1e-9:
                a0 = 0.0
            if abs(v0) < 1e-9:
                v0 = 0.0
        x[t >= t0] = x0
        return x, v, acc


def stroke_timeline(feed_m_s: float, *, axis: AxisData, stroke_m: float, cycles: int,
                    dwell_s: float) -> Timeline:
    """The reciprocating program of ``rig.stroke_program``: dwell, then forward/back cycles."""
    line = Timeline()
    line.dwell(dwell_s)
    for _ in range(cycles):
        line.move(stroke_m, v=feed_m_s, axis=axis)
        line.dwell(dwell_s)
        line.move(-stroke_m, v=feed_m_s, axis=axis)
        line.dwell(dwell_s)
    return line


@dataclass(frozen=True)
class State:
    """Truth state on the fine grid (SI units)."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    mass_kg: float
    load_kg: float
    run_index: int
    reversal_s: np.ndarray    # travel since the last change of direction [m]


def _travel_since_reversal(x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Distance travelled since the latest start of a move in a new direction [m]."""
    out = np.full(x.shape, np.inf)
    direction = np.sign(v)
    last_dir, start_x = 0.0, 0.0
    starts = np.flatnonzero((direction != 0) & (np.concatenate([[0.0], direction[:-1]])
                                                != direction))
    for k in starts:
        if direction[k] != last_dir:
            start_x = x[k]
            last_dir = direction[k]
        end = np.flatnonzero(direction[k:] != direction[k])
        stop = k + (end[0] if end.size else x.size - k)
        out[k:stop] = np.abs(x[k:stop] - start_x)
    return out


# Catalog effects as physics: ('force', f(state) -> N at the nut) or ('power', W at the drive)
# or ('torque2', copper coefficient: k M^2), each for unit amplitude.
def _cat_standby(s: State) -> np.ndarray:
    return np.ones_like(s.t)


def _cat_coulomb(s: State) -> np.ndarray:
    # direction-dependent dry friction, stronger forward than back (asymmetric)
    return np.where(s.v > 0, 1.0, np.where(s.v < 0, -0.5, 0.0))


def _cat_viscous(s: State) -> np.ndarray:
    return s.v                        # force c v: power c v^2


def _cat_load_friction(s: State) -> np.ndarray:
    return s.mass_kg * G * np.sign(s.v)


def _cat_clamped(s: State) -> np.ndarray:
    return s.load_kg * G * np.sign(s.v)


def _cat_stribeck(s: State, v_s: float = 0.02) -> np.ndarray:
    return np.exp(-(s.v / v_s) ** 2) * np.sign(s.v)


def _cat_position(s: State, x0: float = 0.15, width: float = 0.015) -> np.ndarray:
    # a rough spot on the rail, 30 mm wide (2 sigma), 150 mm from the start
    return np.exp(-0.5 * ((s.x - x0) / width) ** 2) * np.sign(s.v)


def _cat_thermal(s: State, tau: float = 15.0) -> np.ndarray:
    # exponential warm-up of the friction from program start
    return (1.0 - np.exp(-np.maximum(s.t, 0.0) / tau)) * np.sign(s.v)


def _cat_gravity(s: State) -> np.ndarray:
    return s.mass_kg * G * np.ones_like(s.t)


def _cat_iron(s: State, lead: float = 0.01) -> np.ndarray:
    w = np.abs(2.0 * math.pi * s.v / lead)
    return w + 0.002 * w * w          # hysteresis + eddy with a fixed ratio [W per unit]


def _cat_offset(s: State) -> np.ndarray:
    # a cable carrier pulling towards -: the same force at every load, moving or not
    return np.ones_like(s.t)


def _cat_viscous_asymmetry(s: State) -> np.ndarray:
    # the direction-odd part of a viscous drag that differs by direction: force d |v|
    return np.abs(s.v)


def _cat_stribeck_exp(s: State, v_s: float = 0.005) -> np.ndarray:
    # the Stribeck excess with an exponential decay (not the catalog's default Gaussian)
    return np.exp(-np.abs(s.v) / v_s) * np.sign(s.v)


def _cat_mass(s: State) -> np.ndarray:
    return s.a                        # forgotten mass: force dm a


def _cat_ripple(s: State, lead: float = 0.01) -> np.ndarray:
    # torque ripple once per screw revolution, as power omega * sin(phi)
    return 2.0 * math.pi * s.v / lead * np.sin(2.0 * math.pi * s.x / lead + 0.3)


CATALOG = {
    'offset_force': ('force', _cat_offset),
    'viscous_asymmetry': ('force', _cat_viscous_asymmetry),
    'stribeck_exp': ('force', _cat_stribeck_exp),
    'mass_error': ('force', _cat_mass),
    'torque_ripple': ('power', _cat_ripple),
    'braking_loss': ('braking', None),
    'standby': ('power', _cat_standby),
    'coulomb': ('force', _cat_coulomb),
    'viscous': ('force', _cat_viscous),
    'load_friction': ('force', _cat_load_friction),
    'clamped_load_friction': ('force', _cat_clamped),
    'stribeck': ('force', _cat_stribeck),
    'position_friction': ('force', _cat_position),
    'thermal_drift': ('force', _cat_thermal),
    'gravity': ('force', _cat_gravity),
    'iron': ('power', _cat_iron),
    'copper': ('torque2', None),
}


# Outside the catalog.
def _out_backlash(s: State) -> np.ndarray:
    # reversal spike: the nut's preload/backlash takes up over the first 6 mm of a new
    # direction (a decaying force pulse after every reversal)
    return np.exp(-s.reversal_s / 0.006) * np.sign(s.v)


def _out_cogging(s: State) -> np.ndarray:
    # force ripple periodic in position with a 24 mm pitch (conservative: zero mean)
    return np.sin(2.0 * math.pi * s.x / 0.024)


def _out_pump(s: State) -> np.ndarray:
    # a coolant pump on the same supply at 2.3 Hz, phase fixed by the run
    return np.sin(2.0 * math.pi * 2.3 * s.t + 0.7 * s.run_index)


def _out_load_viscous(s: State) -> np.ndarray:
    # viscous drag growing with the clamped load (grease squeezed by the weight)
    return s.load_kg * s.v * np.abs(s.v)


OUTSIDE = {
    'backlash': ('force', _out_backlash),
    'cogging': ('force', _out_cogging),
    'pump': ('power', _out_pump),
    'load_viscous': ('force', _out_load_viscous),
    'meter_gain': ('gain', None),        # the meter reads (1 + amplitude) x the power
    'meter_lag': ('lag', None),          # first-order lag of the meter, amplitude = tau [s]
}


def fine_state(line: Timeline, *, axis: AxisData, load_kg: float, run_index: int,
               before_s: float, after_s: float) -> State:
    """Truth state from ``-before_s`` to the timeline's end + ``after_s``."""
    t = np.arange(-before_s, line.duration + after_s, 1.0 / RATE_HZ)
    x, v, a = line.sample(t)
    return State(t=t, x=x, v=v, a=a, mass_kg=axis.table_kg + load_kg, load_kg=load_kg,
                 run_index=run_index, reversal_s=_travel_since_reversal(x, v))


def true_power(s: State, axis: AxisData, effects: dict[str, float]) -> np.ndarray:
    """Electrical-side power of the axis [W] with ``effects`` ``{name: amplitude}``.

    ``meter_gain`` and ``meter_lag`` belong to the meter (:func:`record`) and are ignored.
    """
    speed_mm_s = np.abs(s.v) * 1000.0
    loss_force = np.zeros_like(s.v)
    moving = speed_mm_s > 0.0
    # loss power a x^(1+b) [W] with x in mm/s, as a force opposing the motion
    loss_force[moving] = axis.loss_a * speed_mm_s[moving] ** (1.0 + axis.loss_b) \
        / np.abs(s.v[moving]) * np.sign(s.v[moving])
    force = s.mass_kg * s.a + loss_force + s.mass_kg * G * axis.sin_theta
    drive = np.zeros_like(s.v)
    copper = braking = 0.0
    for name, amp in effects.items():
        kind, fn = CATALOG.get(name) or OUTSIDE[name]
        if kind == 'force':
            force = force + amp * fn(s)
        elif kind == 'power':
            drive = drive + amp * fn(s)
        elif kind == 'torque2':
            copper = amp
        elif kind == 'braking':
            braking = amp
    k = 2.0 * math.pi / axis.lead_m
    torque = axis.inertia_kg_m2 * k * s.a + force / k
    mech = torque * k * s.v
    # a share of the braking power is burned in the chopper instead of returned
    return mech + braking * np.maximum(-mech, 0.0) + copper * torque * torque + drive


@dataclass(frozen=True)
class Meter:
    """The power meter."""

    period_s: float = 0.05
    noise_w: float = 1.5
    quantum_w: float = 1.0
    drift_ppm: float = 0.0
    gain: float = 0.0
    lag_s: float = 0.0


def _lowpass(t: np.ndarray, p: np.ndarray, tau: float) -> np.ndarray:
    """First-order lag with time constant ``tau`` (exact for piecewise-constant input)."""
    if tau <= 0.0:
        return p
    alpha = 1.0 - math.exp(-(t[1] - t[0]) / tau)
    # acc_i = acc_(i-1) + alpha (p_i - acc_(i-1)) from acc_(-1) = p_0, as one recursive filter
    out, _ = lfilter([alpha], [1.0, alpha - 1.0], p, zi=[(1.0 - alpha) * p[0]])
    return out


def record(s: State, p: np.ndarray, *, meter: Meter, offset_s: float, end_s: float,
           rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Meter samples: file times [s] and readings [W].

    A sample stamped ``tau`` (meter clock, from the first sample) is the mean of the power
    over the 50 ms before ``tau / (1 + drift)`` on the true clock, minus ``offset_s``
    (how much later the record is than the program), then noise and quantisation.
    """
    p = _lowpass(s.t, p * (1.0 + meter.gain), meter.lag_s)
    scale = 1.0 + 1e-6 * meter.drift_ppm
    count = int(math.floor((end_s + offset_s) * scale / meter.period_s)) + 1
    stamps = np.arange(count) * meter.period_s
    true_end = stamps / scale - offset_s
    window = meter.period_s / scale
    # mean over [end - window, end] from the cumulative integral (rectangle rule on 0.5 ms)
    dt = 1.0 / RATE_HZ
    cum = np.concatenate([[0.0], np.cumsum(p) * dt])
    grid = np.concatenate([s.t, [s.t[-1] + dt]])

    def integral(tt: np.ndarray) -> np.ndarray:
        return np.interp(tt, grid, cum)

    if true_end[0] - window < s.t[0] or true_end[-1] > s.t[-1]:
        raise ValueError('the truth does not cover the record')
    y = (integral(true_end) - integral(true_end - window)) / window
    y = y + rng.normal(0.0, meter.noise_w, size=y.shape)
    if meter.quantum_w > 0:
        y = np.round(y / meter.quantum_w) * meter.quantum_w
    return stamps, y


def write_record_csv(out: Path, name: str, state: State, stamps: np.ndarray, y: np.ndarray,
                     t_true: np.ndarray) -> str:
    """Write one metered run as ``out/runs/<name>.csv`` (time [ms] from 60 s, power [kW],
    the carriage position [mm] and velocity [mm/s] at the true times ``t_true`` [s]);
    returns the file's path relative to ``out``."""
    x = np.interp(t_true, state.t, state.x)
    v = np.interp(t_true, state.t, state.v)
    rows = ['time_ms,X_power_kW,X_position_mm,X_velocity_mm_s']
    rows += [f'{60000.0 + 1000.0 * a:.3f},{b / 1000.0:.12g},{c * 1000.0:.4f},'
             f'{d * 1000.0:.4f}' for a, b, c, d in zip(stamps, y, x, v)]
    data = f'runs/{name}.csv'
    (out / data).write_text('\n'.join(rows) + '\n', encoding='utf-8')
    return data
