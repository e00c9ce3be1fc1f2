"""The campaign data model: measured runs, their columns and units, row filters, roles.

What :mod:`.manifest` reads from a manifest YAML (every path resolved, every unit checked) and
what the loaders (:mod:`.csvload`, :mod:`.bagload`), ``import``, ``compare`` and ``analyze``
work with.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path

from .quantity import quantity_of

__all__ = ['AXIS_QUANTITIES', 'KINEMATIC_QUANTITIES', 'FILTER_OPS', 'RECONSTRUCT', 'ROLES',
           'STAMPS',
           'Campaign', 'ColumnSpec', 'InstrumentSpec', 'RowFilter', 'RunSpec', 'TimeWindow',
           'default_instrument']

# manifest field -> physical quantity (a key of units.QUANTITIES)
AXIS_QUANTITIES: dict[str, str] = {
    'power': 'power',
    'position': 'length',
    'velocity': 'velocity',
    'acceleration': 'acceleration',
    'command_position': 'length',
    'command_velocity': 'velocity',
    'command_acceleration': 'acceleration',
    'current': 'current',
    'voltage': 'voltage',
    'torque': 'torque',
    'force': 'force',
}
KINEMATIC_QUANTITIES = (
    'position', 'velocity', 'acceleration',
    'command_position', 'command_velocity', 'command_acceleration',
)
FILTER_OPS = ('equal', 'not_equal', 'greater', 'less')
ROLES = ('calibrate', 'validate')
STAMPS = ('end', 'centre', 'start')
RECONSTRUCT = ('pulses', 'samples')


@dataclass(frozen=True)
class InstrumentSpec:
    """How the power meter turns the true signal into a sample (the manifest's ``instrument``).

    Attributes
    ----------
    window_s
        Averaging window [s]; ``0`` for point samples; ``None`` for one median sampling
        period of the run's stamps.
    stamp
        Where a sample's window lies relative to its stamp: ``'end'`` (``[t - w, t]``),
        ``'centre'`` or ``'start'``.
    declared
        ``False`` when the manifest says nothing and this is the default (see
        :func:`default_instrument`).
    measures
        What the meter measures (:data:`.quantity.MEASURES`): ``'shaft'`` (default: compared
        with the simulated shaft power ``M·omega`` after the braking rule, the paper's model whose
        loss function holds every loss) or the electrical power of the declared drives at
        ``'motor'`` (between converter and motor) or ``'supply'`` (an axis's drive input,
        without the cabinet); ``docs/electrical.md``. Or a drive quantity
        (:mod:`.quantity`): ``'current'`` [A], ``'torque'`` [N·m], ``'force'`` [N].
    kt_nm_a
        Torque constants declared in the manifest, ``((axis, kt [N·m/A]), ...)``; they win
        over the machine file's ``axes.<A>.drive.kt_nm_a`` (current traces).
    invert
        Axes whose trace counts the other way than the model: negated on loading.
    noise
        The instrument's noise level per sample, in the unit of what it measures (W, A,
        N·m or N), when the manifest declares it (``instrument.noise``); ``analyze`` then
        uses it for every test instead of its estimate from the data.
    filter_s
        Time constant [s] of the meter's own first-order smoothing before its window
        (``instrument.filter_s``; 0, the default: none). A filtered drive trace or power
        meter lags the true signal by about that much and rounds its edges;
        :func:`.align.first_order_lag`.
    """

    window_s: float | None = None
    stamp: str = 'end'
    declared: bool = True
    measures: str = 'shaft'
    kt_nm_a: tuple[tuple[str, float], ...] = ()
    invert: tuple[str, ...] = ()
    noise: float | None = None
    filter_s: float = 0.0

    @property
    def kt_by_axis(self) -> dict[str, float]:
        """``kt_nm_a`` as a mapping axis -> torque constant [N·m/A]."""
        return dict(self.kt_nm_a)

    def window_for(self, period_s: float) -> float:
        """The window [s] for a run whose median sampling period is ``period_s``."""
        return period_s if self.window_s is None else self.window_s

    def describe(self, period_s: float) -> str:
        """A few words, e.g. ``'50 ms window stamped at its end'`` or ``'point samples'``."""
        w = self.window_for(period_s)
        text = ('point samples' if w == 0.0
                else f'{1e3 * w:g} ms window stamped at its {self.stamp}')
        if self.filter_s:
            text = f'{text} after a {1e3 * self.filter_s:g} ms first-order filter'
        return text if self.declared else f'{text} (default)'


def default_instrument(motion_from_data: str | None, measures: str = 'shaft') -> InstrumentSpec:
    """The instrument assumed when the manifest declares none (``measures`` kept).

    Motion from an NC program: a window of one sampling period stamped at its end (a power
    analyser averaging over its period, as in the paper). Motion from the data: point
    samples, because the simulation then runs on the data's own stamps, where positions and
    power were read at the same instant; a trailing window would shift the simulation by
    half a sample and smear the rapid-move peaks (on the UMich validate runs it raised the
    RMSE from 0.53 to 0.63 W, see docs/measured.md). A drive trace (current, torque, force:
    values a controller samples at an instant, not a meter's averages) is point samples too.
    """
    if motion_from_data is not None or not quantity_of(measures).is_power:
        return InstrumentSpec(window_s=0.0, stamp='end', declared=False, measures=measures)
    return InstrumentSpec(window_s=None, stamp='end', declared=False, measures=measures)


@dataclass(frozen=True)
class ColumnSpec:
    """One data column and the unit its values are written in.

    Attributes
    ----------
    column
        Column name as written in the file's header.
    unit
        Unit of the values (see :mod:`feed_axis_energy.units`).
    """

    column: str
    unit: str


@dataclass(frozen=True)
class RowFilter:
    """Drop rows where ``column`` compares ``op`` to ``value``.

    Attributes
    ----------
    column
        Column to test.
    op
        ``'equal'``, ``'not_equal'``, ``'greater'`` or ``'less'``.
    value
        A number (compared numerically) or a string (compared as stripped text; only with
        ``equal`` / ``not_equal``).
    """

    column: str
    op: str
    value: float | str


@dataclass(frozen=True)
class TimeWindow:
    """The part of a record a run takes (the manifest's ``window``), from its first sample.

    Attributes
    ----------
    start, end
        Where the window begins and ends, in seconds from the record's first sample (after
        the row filter) or, with ``fraction``, as fractions of the record's duration;
        ``end`` ``None``: to the end. A sample at ``t`` is kept when ``start <= t < end``.
    fraction
        ``True`` when ``start`` and ``end`` are fractions in ``[0, 1]``.

    Two runs of one record, ``{end_fraction: 0.5}`` and ``{start_fraction: 0.5}``, share no
    sample and together hold all of them: a calibration on one half and a held-out check on
    the other.
    """

    start: float = 0.0
    end: float | None = None
    fraction: bool = False

    def bounds_s(self, duration_s: float) -> tuple[float, float]:
        """``(start, end)`` [s] from the first sample, for a record of ``duration_s``."""
        if self.fraction:
            end = 1.0 if self.end is None else self.end
            return self.start * duration_s, (end * duration_s if end < 1.0 else math.inf)
        return self.start, math.inf if self.end is None else self.end

    def describe(self) -> str:
        """A few words: ``'samples from 0 to 121.7 s'``, ``'the second half (0.5 to 1)'``."""
        unit = '' if self.fraction else ' s'
        end = 'the end' if self.end is None else f'{self.end:g}{unit}'
        what = 'fraction of the record ' if self.fraction else ''
        return f'{what}from {self.start:g}{unit} to {end}'


@dataclass(frozen=True)
class RunSpec:
    """One measured run of a campaign, with every path resolved and every unit checked.

    Attributes
    ----------
    name
        Unique name within the campaign.
    data
        Absolute path of the CSV file or rosbag2 directory.
    data_kind
        ``'csv'`` or ``'rosbag2'`` (a directory).
    load_kg
        Workpiece/fixture mass on the table [kg].
    axes
        Axis name -> {quantity -> :class:`ColumnSpec`}, in manifest order.
    motion_program
        NC program the run executed, or ``None`` when motion comes from the data.
    motion_from_data
        ``'commanded'`` or ``'actual'`` when motion comes from the data's columns, else None.
    period_s
        Sampling period when the file has no time column, else ``None``.
    time
        Time column, or ``None`` when ``period_s`` is used.
    exclude
        Row filters; a row matching any of them is dropped before validation.
    role
        ``'calibrate'``, ``'validate'`` or ``None``.
    min_duration_s
        Shortest acceptable run [s] (after filtering).
    allow_gaps
        Accept time steps above 1.5x the median period (e.g. rows removed by a filter).
    manifest
        The manifest file the run comes from (for messages).
    key
        The run's place in the manifest, e.g. ``'runs[2]'``.
    instrument
        The power meter (declared or :func:`default_instrument`).
    motion_reconstruct
        Motion from data sampled coarser than the simulation rate: ``'pulses'`` rebuilds
        it at that rate from positions, velocities and accelerations (:mod:`.motiondata`);
        ``'samples'`` takes the samples as they are.
    window
        The part of the record the run takes (:class:`TimeWindow`), ``None``: all of it.
    work_offset_m
        Declared work offset ``((axis, machine - program [m]), ...)`` of a run simulated
        from its program whose data has positions (:mod:`.spatial`); empty: estimated.
    motion_start_m
        Where the machine stood when the program started, ``(X, Y, Z)`` in machine
        coordinates [m] (``motion.start_m``; the program's first move starts there), or
        ``None``: at the origin.
    """

    name: str
    data: Path
    data_kind: str
    load_kg: float
    axes: dict[str, dict[str, ColumnSpec]]
    motion_program: Path | None = None
    motion_from_data: str | None = None
    period_s: float | None = None
    time: ColumnSpec | None = None
    exclude: tuple[RowFilter, ...] = ()
    role: str | None = None
    min_duration_s: float = 0.0
    allow_gaps: bool = False
    manifest: str = '<manifest>'
    key: str = ''
    instrument: InstrumentSpec = InstrumentSpec(declared=False)
    motion_reconstruct: str = 'pulses'
    window: TimeWindow | None = None
    work_offset_m: tuple[tuple[str, float], ...] = ()
    motion_start_m: tuple[float, float, float] | None = None

    @property
    def axis_names(self) -> tuple[str, ...]:
        """Axis names in manifest order."""
        return tuple(self.axes)

    @property
    def power_axes(self) -> tuple[str, ...]:
        """Axes that have a measured power column."""
        return tuple(a for a, cols in self.axes.items() if 'power' in cols)

    @property
    def measured_axes(self) -> tuple[str, ...]:
        """Axes with a column of the quantity the instrument measures (:mod:`.quantity`)."""
        column = quantity_of(self.instrument.measures).column
        return tuple(a for a, cols in self.axes.items() if column in cols)


@dataclass(frozen=True)
class Campaign:
    """A set of measured runs on one machine.

    Attributes
    ----------
    file
        The manifest file.
    name
        Campaign name (the manifest's ``name`` or the file stem).
    machine
        Absolute path of the machine config.
    runs
        The runs, in manifest order.
    description
        Free text from the manifest.
    """

    file: Path
    name: str
    machine: Path
    runs: tuple[RunSpec, ...]
    description: str = ''

    def run(self, name: str) -> RunSpec:
        """Return the run called ``name`` (``KeyError`` naming the known runs if absent)."""
        for spec in self.runs:
            if spec.name == name:
                return spec
        msg = f'no run {name!r} in {self.file}; runs are {", ".join(r.name for r in self.runs)}'
        raise KeyError(msg)

    def runs_with_role(self, role: str) -> tuple[RunSpec, ...]:
        """Runs marked ``role`` (``'calibrate'`` or ``'validate'``)."""
        return tuple(r for r in self.runs if r.role == role)
