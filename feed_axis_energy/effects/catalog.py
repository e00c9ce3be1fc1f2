"""Effect catalog machinery: parameters, the state effects are computed from, the registry.

An *effect* is a physical phenomenon the declared machine model may be missing. Each effect
adds an extra actual power ``power_w(state, params)`` [W], shape ``(n, k)``, on top of the
declared model's per-axis power. ``state`` is an :class:`EffectState` built from a simulation
of the declared model (:func:`effect_state`). Where the power is linear in the parameters,
``basis(state, params)`` returns ``(n, k, p)`` columns with
``power_w == sum_i basis[..., i] * value_i`` over the effect's *linear* parameters (in
declaration order); *shape* parameters (e.g. a Stribeck speed) are held fixed by ``params``
and searched for outside the regression.

Parameter values are floats, or arrays broadcastable to ``(k,)`` for one value per axis.
Every parameter has *physical bounds* (:attr:`Param.bounds`: a loss is never negative, a
share lies in [0, 1], ``|sin θ|`` at most 1): :meth:`Effect.resolve` refuses a value outside
them and an identification fits within them (:meth:`Effect.linear_bounds`).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
import math
from typing import Any, ClassVar, TypeVar

import numpy as np

from ..errors import ConfigError


__all__ = ['Param', 'NON_NEGATIVE', 'EffectState', 'Effect', 'EFFECTS', 'register_effect',
           'get_effect', 'effects_power_w', 'ParamValue']

ParamValue = float | np.ndarray


@dataclass(frozen=True)
class Param:
    """One named effect parameter.

    Attributes
    ----------
    name
        Name, carrying its unit where that helps (``f_pos_n``).
    unit
        SI unit as text (``'N'``, ``'W/(N*m)^2'``, ``'-'``).
    default
        Value meaning "effect absent" (or, for shape parameters, a typical value).
    low, high
        Plausible range (the grid of shape searches, the catalog table; not enforced).
    example
        A typical non-zero value, used when an effect is requested without values.
    description
        One line.
    linear
        ``True`` when the power is linear in this parameter (it gets a basis column).
    bounds
        Physical bounds ``(lower, upper)``, inclusive (``±inf``: none). A value outside them
        is impossible: refused in a config, never reported as found by a fit.
    """

    name: str
    unit: str
    default: float
    low: float
    high: float
    example: float
    description: str
    linear: bool = True
    bounds: tuple[float, float] = (-math.inf, math.inf)


NON_NEGATIVE = (0.0, math.inf)


@dataclass(frozen=True)
class EffectState:
    """What effects are computed from: one simulation of the declared model (SI units).

    Attributes
    ----------
    t
        Time since program start [s], ``(n,)``.
    axes
        Axis names (columns).
    position_m, velocity_m_s, acceleration_m_s2
        Carriage kinematics, ``(n, k)``.
    angle_rad, omega_rad_s
        Screw angle and angular velocity, ``(n, k)``.
    force_n, torque_nm
        Declared model's nut force and screw torque, ``(n, k)``.
    mass_kg
        Moved mass per axis (tables + load) [kg], ``(k,)``.
    load_kg
        Workpiece mass [kg].
    normal_force_n
        Guideway normal force ``m·g·|cos(incl)|`` per axis [N], ``(k,)``.
    lead_m
        Screw lead per axis [m], ``(k,)``.
    mechanical_w
        Declared ``M·omega`` per axis before the braking rule [W], ``(n, k)``.
    power_w
        Declared actual power per axis after the braking rule [W], ``(n, k)``.
    load_normal_force_n
        The clamped load's share of ``normal_force_n`` [N], ``(k,)``: zero on axes that do not
        carry the load. ``None`` means ``load_kg·g`` on every axis.
    """

    t: np.ndarray
    axes: tuple[str, ...]
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    angle_rad: np.ndarray
    omega_rad_s: np.ndarray
    force_n: np.ndarray
    torque_nm: np.ndarray
    mass_kg: np.ndarray
    load_kg: float
    normal_force_n: np.ndarray
    lead_m: np.ndarray
    mechanical_w: np.ndarray
    power_w: np.ndarray
    load_normal_force_n: np.ndarray | None = None

    SAMPLE_FIELDS: ClassVar[tuple[str, ...]] = (
        't', 'position_m', 'velocity_m_s', 'acceleration_m_s2', 'angle_rad', 'omega_rad_s',
        'force_n', 'torque_nm', 'mechanical_w', 'power_w')
    """The fields with one row per sample (the rest are per axis or scalars)."""

    @property
    def shape(self) -> tuple[int, int]:
        """``(n, k)``: samples and axes."""
        return (int(self.t.shape[0]), len(self.axes))

    def rows(self, start: int, stop: int) -> EffectState:
        """The samples ``start:stop`` (views; the per-axis fields as they are). A
        sample-local effect's power and basis on them are those rows of the whole state's."""
        return replace(self, **{name: getattr(self, name)[start:stop]
                                for name in self.SAMPLE_FIELDS})

    @staticmethod
    def joined(pieces: Sequence[EffectState]) -> EffectState:
        """Consecutive pieces of one run's state as one (:meth:`rows` undone): the per-sample
        fields concatenated, the rest the first piece's; one piece is returned as it is."""
        if not pieces:
            raise ValueError('a state needs at least one piece')
        if len(pieces) == 1:
            return pieces[0]
        joined: dict[str, Any] = {name: np.concatenate([getattr(p, name) for p in pieces])
                                  for name in EffectState.SAMPLE_FIELDS}
        return replace(pieces[0], **joined)


class Effect:
    """Base of every catalog effect; subclasses set the class attributes and ``_basis``.

    Class attributes
    ----------------
    id
        Registry name.
    description
        One line: the physics.
    formula
        The extra power as text (for the catalog table).
    params
        The parameters, linear ones first in basis order.
    exact_basis
        ``True`` when ``power_w == basis · linear values`` holds exactly; ``False`` when the
        basis is a first-order approximation (see ``time_offset``).
    machine_property
        ``True`` for a physical property of the machine, which belongs in an augmented
        machine config; ``False`` for an artefact of comparing two records (``time_offset``),
        which ``analyze`` reports but does not write into the machine.
    sample_local
        ``True`` when the power of a sample depends only on that sample's state, so the
        effect can be applied batch by batch in the node graph with offline-equal results.
    constant_at_rest
        ``True`` when the power at standstill (constant position, zero velocity and
        acceleration) does not change with time, so the samples of a dwell need not be
        computed one by one (:mod:`..standstill`). An effect whose power depends on ``t``
        sets it ``False`` unless that term vanishes at rest.
    """

    id: ClassVar[str] = ''
    description: ClassVar[str] = ''
    formula: ClassVar[str] = ''
    params: ClassVar[tuple[Param, ...]] = ()
    exact_basis: ClassVar[bool] = True
    machine_property: ClassVar[bool] = True
    sample_local: ClassVar[bool] = True
    constant_at_rest: ClassVar[bool] = True

    @classmethod
    def param_names(cls) -> tuple[str, ...]:
        """All parameter names."""
        return tuple(p.name for p in cls.params)

    @classmethod
    def linear_params(cls) -> tuple[str, ...]:
        """Names of the parameters with a basis column, in basis order."""
        return tuple(p.name for p in cls.params if p.linear)

    @classmethod
    def shape_params(cls) -> tuple[str, ...]:
        """Names of the parameters the power is non-linear in (found by a 1-D search)."""
        return tuple(p.name for p in cls.params if not p.linear)

    @classmethod
    def linear_bounds(cls) -> tuple[np.ndarray, np.ndarray]:
        """Physical ``(lower, upper)`` bounds of the linear parameters, in basis order."""
        lin = [p for p in cls.params if p.linear]
        return (np.array([p.bounds[0] for p in lin], dtype=float),
                np.array([p.bounds[1] for p in lin], dtype=float))

    @classmethod
    def resolve(cls, params: Mapping[str, ParamValue] | None = None) -> dict[str, ParamValue]:
        """Return every parameter's value: given ones, defaults for the rest.

        Raises
        ------
        ConfigError
            An unknown parameter name, a non-finite value or one outside the parameter's
            physical bounds, naming the effect.
        """
        out: dict[str, ParamValue] = {p.name: p.default for p in cls.params}
        for name, value in (params or {}).items():
            if name not in out:
                msg = (f'effect {cls.id!r} has no parameter {name!r}; '
                       f'expected one of {", ".join(out) or "(none)"}')
                raise ConfigError(msg, key=f'effects.{cls.id}.{name}')
            arr = np.asarray(value, dtype=float)
            if not np.all(np.isfinite(arr)):
                msg = (f'parameter {name!r} of effect {cls.id!r} must be finite, '
                       f'got {_short(value)}')
                raise ConfigError(msg, key=f'effects.{cls.id}.{name}')
            lo, hi = next(p.bounds for p in cls.params if p.name == name)
            if np.any(arr < lo) or np.any(arr > hi):
                msg = (f'parameter {name!r} of effect {cls.id!r} must lie in [{lo:g}, {hi:g}] '
                       f'(physical bounds), got {_short(value)}')
                raise ConfigError(msg, key=f'effects.{cls.id}.{name}')
            out[name] = float(arr) if arr.ndim == 0 else arr
        return out

    def basis(self, state: EffectState,
              params: Mapping[str, ParamValue] | None = None) -> np.ndarray:
        """Basis columns ``(n, k, p)`` of the linear parameters (shape ones from ``params``)."""
        values = self.resolve(params)
        cols = self._basis(state, values)
        n, k = state.shape
        return np.stack([np.broadcast_to(c, (n, k)) for c in cols], axis=-1)

    def power_w(self, state: EffectState,
                params: Mapping[str, ParamValue] | None = None) -> np.ndarray:
        """Extra actual power per axis [W], ``(n, k)``."""
        values = self.resolve(params)
        n, k = state.shape
        total = np.zeros((n, k))
        for col, name in zip(self._basis(state, values), self.linear_params()):
            total = total + np.asarray(col) * np.broadcast_to(values[name], (k,))
        return total

    def _basis(self, state: EffectState, values: dict[str, ParamValue]) -> list[np.ndarray]:
        raise NotImplementedError


def _short(value: object) -> str:
    """``repr`` of a value, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + '...'


EFFECTS: dict[str, type[Effect]] = {}

_EffectT = TypeVar('_EffectT', bound=type[Effect])


def register_effect(cls: _EffectT) -> _EffectT:
    """Class decorator: add ``cls`` to :data:`EFFECTS` under ``cls.id``."""
    if not cls.id or cls.id in EFFECTS:
        msg = f'effect id {cls.id!r} is empty or registered twice'
        raise ValueError(msg)
    names = [p.name for p in cls.params]
    linear = [p.linear for p in cls.params]
    # Linear parameters first keeps the basis order equal to the declaration order.
    if linear != sorted(linear, reverse=True) or len(set(names)) != len(names):
        msg = f'effect {cls.id!r}: parameters must be unique, linear ones first'
        raise ValueError(msg)
    EFFECTS[cls.id] = cls
    return cls


def get_effect(effect_id: str) -> Effect:
    """Return an instance of the registered effect ``effect_id``.

    Raises
    ------
    ConfigError
        Unknown id, naming it and the known ones.
    """
    if effect_id not in EFFECTS:
        msg = f'unknown effect {effect_id!r}; expected one of {", ".join(EFFECTS)}'
        raise ConfigError(msg, key='effects')
    return EFFECTS[effect_id]()


def effects_power_w(state: EffectState,
                    effects: Sequence[tuple[str, Mapping[str, ParamValue]]]) -> np.ndarray:
    """Sum of the extra power of several effects ``[(id, params), ...]`` [W], ``(n, k)``."""
    total = np.zeros(state.shape)
    for effect_id, params in effects:
        total = total + get_effect(effect_id).power_w(state, params)
    return total
