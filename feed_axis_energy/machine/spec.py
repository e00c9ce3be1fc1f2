"""Machine model: ball-screw feed axes as frozen dataclasses (the values, not the file).

:mod:`.file` reads and writes them as YAML, validating every value on the way in; other
packages import them from :mod:`feed_axis_energy.machine`.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any

from .calibrated import CalibratedRange
from .drives import DriveSpec, SupplySpec
from .covariance import LossCovariance
from .losses import LossModel
from .declared import DeclaredEffect
from ..gcode import GcodeSettings
from ..units import GRAVITY_M_S2
from .limits import AxisLimits, PlannerOptions

__all__ = ['ScrewSpec', 'InertiaSpec', 'LimitSpec', 'PlannerSettings', 'AxisSpec', 'Machine',
           'RotarySpec', 'AXIS_NAMES', 'LINEAR_AXIS_NAMES', 'ROTARY_AXIS_NAMES',
           'BRAKING_MODES', 'PROFILES', 'STEEL_DENSITY_KG_M3', 'DIRECT_SCREW', 'TRANSMISSIONS']


LINEAR_AXIS_NAMES = ('X', 'Y', 'Z')
ROTARY_AXIS_NAMES = ('A', 'B', 'C')
AXIS_NAMES = LINEAR_AXIS_NAMES + ROTARY_AXIS_NAMES
BRAKING_MODES = ('regenerative', 'dissipated')
PROFILES = ('jerk', 'trapezoid')
STEEL_DENSITY_KG_M3 = 7850.0


@dataclass(frozen=True)
class ScrewSpec:
    """Ball screw of one axis.

    Attributes
    ----------
    diameter_m
        Nominal diameter [m].
    lead_m
        Advance of the nut per screw revolution [m] (= starts x thread pitch).
    length_m
        Length of the screw [m] (for its inertia).
    starts
        Number of thread starts (informational; ``lead_m`` already includes it).
    efficiency
        Mechanical efficiency of screw and nut, ``0 < eta <= 1``. The demonstrator uses 1.0
        because the paper puts every passive resistance into the loss function.
    density_kg_m3
        Density of the screw material [kg/m^3] (steel 7850).
    """

    diameter_m: float
    lead_m: float
    length_m: float
    starts: int = 1
    efficiency: float = 1.0
    density_kg_m3: float = STEEL_DENSITY_KG_M3

    @property
    def pitch_m(self) -> float:
        """Thread pitch [m]: lead divided by the number of starts."""
        return self.lead_m / self.starts

    @property
    def solid_inertia_kg_m2(self) -> float:
        """Inertia of the screw as a solid cylinder, ``pi/32·rho·L·d**4`` [kg·m^2]."""
        return math.pi / 32.0 * self.density_kg_m3 * self.length_m * self.diameter_m ** 4


@dataclass(frozen=True)
class InertiaSpec:
    """Rotary inertias on the screw axis [kg·m^2] (motor coupled directly, no gearbox).

    ``screw_kg_m2`` is ``None`` when the file leaves it out: then the solid-cylinder value
    of :class:`ScrewSpec` is used.
    """

    motor_kg_m2: float
    coupling_kg_m2: float = 0.0
    screw_kg_m2: float | None = None


@dataclass(frozen=True)
class LimitSpec:
    """Kinematic limits of one axis, used by the planner."""

    velocity_m_s: float
    acceleration_m_s2: float
    jerk_m_s3: float


@dataclass(frozen=True)
class PlannerSettings:
    """Default planner settings of the machine (see :class:`.trajectory.PlannerOptions`)."""

    profile: str = 'jerk'
    corner_tolerance_m: float = 1.0e-4
    rate_hz: float = 1000.0
    cycle_s: float = 1.0e-3

    def options(self) -> PlannerOptions:
        """Return these settings as a :class:`.trajectory.PlannerOptions`."""
        return PlannerOptions(rate_hz=self.rate_hz, profile=self.profile,
                              corner_tolerance_m=self.corner_tolerance_m, cycle_s=self.cycle_s)


@dataclass(frozen=True)
class RotarySpec:
    """What a rotary axis (A, B, C: rotary table or swivel head) declares beyond its motor.

    The dynamics treat a rotary axis as a feed axis whose "carriage" is the table: position
    [rad], speed [rad/s], "force" the torque at the table [N·m], "mass" its moment of
    inertia [kg·m^2], and the "lead" ``2·pi / gear_ratio`` (one motor revolution turns the
    table ``1 / gear_ratio``), so ``M = J_motor·alpha_motor + M_table / (gear_ratio·eta)``
    with ``M_table = (J_table + J_load)·alpha_table + M_friction`` (:mod:`.rotary`).

    Attributes
    ----------
    gear_ratio
        Motor revolutions per table revolution (1: direct drive; a worm gear 30..180).
    table_inertia_kg_m2
        Moment of inertia of the table (or head) about its axis [kg·m^2].
    load_inertia_kg_m2
        Moment of inertia of the clamped workpiece and fixture about the axis [kg·m^2].
    mass_kg
        Mass of the whole rotary unit that the axis it rides on moves with it [kg].
    travel_deg
        ``(min, max)`` travel [deg], or ``None`` (endless).
    limits_deg
        Speed, acceleration and jerk limits as the file gives them [deg/s, deg/s^2,
        deg/s^3] (the axis's ``limits`` hold them in rad).
    """

    gear_ratio: float
    table_inertia_kg_m2: float
    load_inertia_kg_m2: float = 0.0
    mass_kg: float = 0.0
    travel_deg: tuple[float, float] | None = None
    limits_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def inertia_kg_m2(self) -> float:
        """Table + load inertia about the axis [kg·m^2]."""
        return self.table_inertia_kg_m2 + self.load_inertia_kg_m2


DIRECT_SCREW = ScrewSpec(diameter_m=0.0, lead_m=2.0 * math.pi, length_m=0.0, starts=1,
                         efficiency=1.0, density_kg_m3=0.0)
"""Transmission of a direct linear axis: 1 m per rad, no loss, no inertia (force = torque)."""
TRANSMISSIONS = ('screw', 'direct')
"""Values of ``axes.<A>.transmission``."""


@dataclass(frozen=True)
class AxisSpec:
    """One ball-screw feed axis.

    Attributes
    ----------
    name
        ``'X'``, ``'Y'`` or ``'Z'``.
    table_mass_kg
        Mass moved by this axis alone (table, nut, carriages, vice) [kg].
    screw, inertias, limits
        See :class:`ScrewSpec`, :class:`InertiaSpec`, :class:`LimitSpec`.
    loss
        Loss model (see :mod:`.losses`).
    rides_on
        Name of the axis that carries this one (its whole moved mass), or ``None``.
    inclination_deg
        Angle of the positive direction above the horizontal [deg]; 90 is vertical upward.
    travel_m
        ``(min, max)`` travel limits in machine coordinates [m], or ``None`` (unknown).
    loss_calibrated
        Speeds and loads the loss function was fitted on, or ``None`` (not recorded).
    drive
        Motor and drive from data-sheet values (:mod:`.drives`), or ``None``.
    loss_covariance
        Covariance of the loss parameters, or ``None`` (not known).
    standstill_hold_n
        Force the drive keeps holding after a stop, in the last direction of motion [N]
        (:mod:`feed_axis_energy.physics.standstill`): friction kept by the position loop.
        Seen only in current, torque and force traces (no power at rest); 0: none.
    direct
        ``True`` for a direct linear drive without a screw (``transmission: direct``: a
        linear motor, or a test stand whose trace is the actuator force): ``screw`` is then
        the identity transmission :data:`DIRECT_SCREW` (lead ``2·pi`` m, efficiency 1, no
        inertia), so the "screw torque" [N·m] equals the axis force [N] and the "screw
        speed" [rad/s] the carriage speed [m/s], and ``inertias`` are 0 (the moving part of
        the motor belongs in ``table_mass_kg``).
    counterbalance_n
        Weight compensation of an inclined axis [N] (counterweight, gas or hydraulic
        cylinder): a constant force against the weight along the axis, ``>= 0``; the drive
        carries ``m·g·sin(incl) - sgn(sin(incl))·counterbalance_n`` (:meth:`weight_force_n`).
        0 on a horizontal axis.
    rotary
        ``None`` for a linear (ball-screw) axis. For a rotary axis (A, B, C) its
        :class:`RotarySpec`; the other fields then hold the equivalent feed axis (SI with
        rad for m: ``table_mass_kg`` the table inertia [kg·m^2], ``screw.lead_m``
        ``2·pi/gear_ratio``, ``limits`` in rad/s, rad/s^2, rad/s^3, ``loss`` the friction
        torque [N·m] at the table).
    """

    name: str
    table_mass_kg: float
    screw: ScrewSpec
    inertias: InertiaSpec
    limits: LimitSpec
    loss: LossModel
    rides_on: str | None = None
    inclination_deg: float = 0.0
    travel_m: tuple[float, float] | None = None
    loss_calibrated: CalibratedRange | None = None
    loss_covariance: LossCovariance | None = None
    drive: DriveSpec | None = None
    standstill_hold_n: float = 0.0
    rotary: RotarySpec | None = None
    direct: bool = False
    counterbalance_n: float = 0.0

    def weight_force_n(self, mass_kg: float) -> float:
        """Force the drive carries against gravity along the axis [N] for a moved mass [kg].

        ``m·g·sin(incl)`` less the counterbalance, which acts against the weight:
        ``m·g·sin(incl) - sgn(sin(incl))·counterbalance_n``.
        """
        s = math.sin(math.radians(self.inclination_deg))
        return mass_kg * GRAVITY_M_S2 * s - math.copysign(self.counterbalance_n, s) * (s != 0.0)

    @property
    def is_rotary(self) -> bool:
        """True for a rotary axis (positions in rad)."""
        return self.rotary is not None

    @property
    def carried_mass_kg(self) -> float:
        """Mass [kg] an axis carrying this one moves with it (a rotary unit's ``mass_kg``)."""
        return self.table_mass_kg if self.rotary is None else self.rotary.mass_kg

    @property
    def screw_inertia_kg_m2(self) -> float:
        """Screw inertia: the configured value, else the solid cylinder [kg·m^2]."""
        given = self.inertias.screw_kg_m2
        return self.screw.solid_inertia_kg_m2 if given is None else given

    @property
    def rotary_inertia_kg_m2(self) -> float:
        """Motor + coupling + screw inertia [kg·m^2]."""
        return self.inertias.motor_kg_m2 + self.inertias.coupling_kg_m2 + self.screw_inertia_kg_m2


@dataclass(frozen=True)
class Machine:
    """A machine: its axes (in order) and how it handles braking energy.

    Attributes
    ----------
    name
        Free text.
    axes
        The axes, in the order of the columns of every per-axis array.
    braking
        ``'regenerative'``: braking power goes back to the DC link and counts negative (the
        demonstrator's Beckhoff converters); ``'dissipated'``: negative axis power is burned in
        a brake resistor and counts as zero draw.
    load_axis
        Name of the axis whose table carries the clamped workpiece.
    planner
        Default planner settings.
    effects
        Catalog effects added on top of the power (empty for the paper's model).
    home_m
        The reference point G28 moves to, ``((axis, position [m]), ...)`` in machine
        coordinates: the initial ``#5161..#5163`` of a program run (empty: 0, as in
        LinuxCNC's fresh parameter file).
    gcode
        Dialect and tool table of the G-code front end (:mod:`feed_axis_energy.gcode.settings`).
    supply
        Cabinet standby and the meter's point (:mod:`.drives`), or ``None``.
    """

    name: str
    axes: tuple[AxisSpec, ...]
    braking: str = 'regenerative'
    load_axis: str = 'X'
    planner: PlannerSettings = PlannerSettings()
    effects: tuple[DeclaredEffect, ...] = ()
    home_m: tuple[tuple[str, float], ...] = ()
    gcode: GcodeSettings = GcodeSettings()
    supply: SupplySpec | None = None

    @property
    def electrical(self) -> bool:
        """True when the axes declare motor and drive (:mod:`.electrical` applies)."""
        return any(a.drive is not None for a in self.axes)

    def home_point(self) -> tuple[float, float, float] | None:
        """The G28 reference point as program ``(X, Y, Z)`` [m] (0 for other axes), or None."""
        if not self.home_m:
            return None
        home = dict(self.home_m)
        return (home.get('X', 0.0), home.get('Y', 0.0), home.get('Z', 0.0))

    def gcode_keywords(self) -> dict[str, Any]:
        """Keywords for :func:`.gcode.load_gcode` from this machine: G28 position, tool
        table, dialect, subroutine path, ``strict_tools``, ``allow_no_feed`` and the work
        offsets (``gcode.work_offsets_m``).

        ``load_gcode(path, **machine.gcode_keywords())`` runs a program on this machine.
        """
        g = self.gcode
        kw: dict[str, Any] = {'home': self.home_point(), 'tools': g.tools, 'dialect': g.dialect,
                              'search_path': g.subroutine_path, 'strict_tools': g.strict_tools,
                              'allow_no_feed': g.allow_no_feed}
        rotary = self.rotary_axes
        if rotary:
            kw['rotary_axes'] = rotary
        if g.work_offsets_m:
            kw['work_offsets'] = dict(g.work_offsets_m)
        return kw

    @property
    def rotary_axes(self) -> tuple[str, ...]:
        """Names of the rotary axes (A, B, C) the machine has, in order."""
        return tuple(a.name for a in self.axes if a.rotary is not None)

    @property
    def axis_names(self) -> tuple[str, ...]:
        """Names of the axes, in order."""
        return tuple(a.name for a in self.axes)

    def axis(self, name: str) -> AxisSpec:
        """Return the axis called ``name`` (``KeyError`` if the machine has none)."""
        for spec in self.axes:
            if spec.name == name:
                return spec
        msg = f'machine {self.name!r} has no axis {name!r} (axes: {self.axis_names})'
        raise KeyError(msg)

    def limits(self) -> dict[str, AxisLimits]:
        """Return the kinematic limits as ``{name: trajectory.AxisLimits}``."""
        return {a.name: AxisLimits(velocity_m_s=a.limits.velocity_m_s,
                                   acceleration_m_s2=a.limits.acceleration_m_s2,
                                   jerk_m_s3=a.limits.jerk_m_s3) for a in self.axes}
