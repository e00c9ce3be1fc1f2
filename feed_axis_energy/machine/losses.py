"""Loss models: the passive resistance of screw, nut, bearings and guideways as a force.

The paper (section 2.1) lumps every passive resistance of the feed axis into one *loss
function* of the feed rate that enters the physical model "in the form of force acting
against the direction of movement". Each model here is one frozen dataclass with

* ``force_n(v_m_s, *, normal_force_n=0.0) -> ndarray``: the resistance force acting on the
  carriage at the nut [N]. It *opposes motion*: negative for ``v > 0``, positive for
  ``v < 0`` and exactly zero at ``v == 0``. The drive has to supply ``-force_n(v)``.
* ``power_w(v_m_s, *, normal_force_n=0.0) -> ndarray``: the loss power ``-force_n(v)·v`` [W],
  never negative.
* ``to_dict() -> dict``: the YAML form, ``{'model': <registry name>, ...params}``;
* ``param_units() -> dict``: the unit of every parameter, as a covariance of the parameters
  in a machine config (``loss_covariance``, :mod:`.covariance`) must state them;
* ``power_gradient_w(v_m_s, *, normal_force_n=0.0) -> dict``: the derivative of the loss
  power with respect to every parameter, ``d power_w / d param`` [W per unit of the
  parameter] (:mod:`.uncertainty` propagates the parameters' covariance to the energy).

Models are registered by name in :data:`LOSS_MODELS`; :func:`loss_from_dict` builds one from
a machine file.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
import math
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np

from ..errors import ConfigError, describe, shorten

__all__ = ['LossModel', 'LOSS_MODELS', 'PowerRegressionLoss', 'CoulombViscousLoss',
           'loss_from_dict', 'register_loss', 'X_UNITS', 'Y_UNITS']

# How many of the unit fit into 1 m/s: value_in_unit = v_m_s * X_UNITS[unit].
X_UNITS: dict[str, float] = {'mm/s': 1000.0, 'm/s': 1.0, 'mm/min': 60000.0, 'm/min': 60.0}
Y_UNITS: tuple[str, ...] = ('W/(mm/s)', 'W', 'N')


class LossModel(Protocol):
    """What :mod:`.dynamics` needs from a loss model."""

    model: ClassVar[str]

    def force_n(self, v_m_s: np.ndarray, *,
                normal_force_n: float | np.ndarray = 0.0) -> np.ndarray:
        """Resistance force at the nut [N], opposing motion."""

    def power_w(self, v_m_s: np.ndarray, *,
                normal_force_n: float | np.ndarray = 0.0) -> np.ndarray:
        """Loss power [W], never negative."""

    def to_dict(self) -> dict[str, Any]:
        """YAML form including ``model``."""

    def param_units(self) -> dict[str, str]:
        """Unit of every parameter, in the order of the YAML form."""

    def power_gradient_w(self, v_m_s: np.ndarray, *,
                         normal_force_n: float | np.ndarray = 0.0) -> dict[str, np.ndarray]:
        """``d power_w / d param`` for every parameter [W per unit of the parameter]."""


class _LossModelClass(Protocol):
    """A registered loss model class: its ``model`` name and its ``from_dict`` constructor."""

    model: str

    def from_dict(self, d: Mapping[str, Any], *, file: str, key: str) -> LossModel:
        """An instance from the YAML form (see :func:`loss_from_dict`)."""


LOSS_MODELS: dict[str, _LossModelClass] = {}

_LossClassT = TypeVar('_LossClassT', bound=_LossModelClass)


def register_loss(cls: _LossClassT) -> _LossClassT:
    """Class decorator: add ``cls`` to :data:`LOSS_MODELS` under ``cls.model``."""
    LOSS_MODELS[cls.model] = cls
    return cls


def _number(d: Mapping[str, Any], name: str, *, file: str, key: str, default: Any = None,
            minimum: float | None = None, strict: bool = False,
            maximum: float = 1.0e12) -> float:
    where = f'{key}.{name}' if key else name
    if name not in d:
        if default is None:
            msg = 'missing required value; expected a number'
            raise ConfigError(msg, file=file, key=where)
        return float(default)
    value = d[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        msg = f'expected a finite number, got {describe(value)}'
        raise ConfigError(msg, file=file, key=where)
    if minimum is not None and (value <= minimum if strict else value < minimum):
        relation = '>' if strict else '>='
        msg = f'expected a number {relation} {minimum}, got {describe(value)}'
        raise ConfigError(msg, file=file, key=where)
    if value > maximum:
        msg = f'expected a number <= {maximum:g}, got {describe(value)}'
        raise ConfigError(msg, file=file, key=where)
    return float(value)


def _check_keys(d: Mapping[str, Any], allowed: tuple[str, ...], *, file: str, key: str) -> None:
    for name in d:
        if name not in allowed:
            shown = shorten(str(name))
            where = f'{key}.{shown}' if key else shown
            msg = f'unknown key {shown!r}; expected one of {", ".join(allowed)}'
            raise ConfigError(msg, file=file, key=where)


_RUN_SHARE = 2     # at least 2 samples per run of equal values on average: power per run


def _power(x: np.ndarray, b: float) -> np.ndarray:
    """``np.power(x, b)``, evaluated once per run of equal values when runs are long.

    A power with a fractional exponent costs tens of nanoseconds per value, ten times a
    comparison; sampled motion repeats one speed for the whole cruise of a move, so the
    values are computed for the first sample of each run and repeated. A run is a stretch
    of bitwise equal values (``0.0`` and ``-0.0`` differ: ``(-0.0)**1`` is ``-0.0``), and
    equal inputs give equal outputs, so the result is the same to the bit.
    """
    flat = np.ascontiguousarray(x.ravel())
    n = flat.size
    if n < 2 * _RUN_SHARE or flat.dtype != np.float64:
        return np.power(x, b)
    bits = flat.view(np.uint64)
    change = np.flatnonzero(bits[1:] != bits[:-1])
    if (change.size + 1) * _RUN_SHARE > n:
        return np.power(x, b)
    first = np.empty(change.size + 1, dtype=np.intp)
    first[0] = 0
    np.add(change, 1, out=first[1:])
    counts = np.diff(first, append=n)
    return np.repeat(np.power(flat[first], b), counts).reshape(x.shape)


def _opposing(v: np.ndarray, magnitude: np.ndarray) -> np.ndarray:
    # np.sign(0) == 0 makes the force vanish at standstill whatever the magnitude.
    return -np.sign(v) * magnitude


@register_loss
@dataclass(frozen=True)
class PowerRegressionLoss:
    """The paper's power-regression loss function, eq. (3): ``y = a·x**b``.

    The paper leaves the units of ``x`` and ``y`` open. Our reading (the default) is
    ``x`` = feed rate in mm/s and ``y`` = the "loss coefficient" of section 2.1, i.e. the
    steady actual power divided by the feed, in W per mm/s. Hence the loss power is
    ``P_loss = y·x = a·x**(1 + b)`` [W] and the resistance force is ``F = P_loss / v``
    (``= 1000·y`` N for ``v`` in m/s). Why: section 2.1 obtains the coefficient by dividing
    the steady power by the feed and multiplies it by the feed again; and only this reading
    gives loss powers of about 124-1085 W at 100-500 mm/s, consistent with Table 1 (average
    differential errors of 24-46 W being 3-7 % implies actual powers of several hundred
    watts). Reading ``y`` as a force in N would give about 1 W.

    Other readings can be configured: ``x_unit`` in ``mm/s``, ``m/s``, ``mm/min``, ``m/min``;
    ``y_unit`` ``'W/(mm/s)'`` (power per mm/s of feed, as above), ``'W'`` (``y`` is the loss
    power itself, ``F = y/v``; note that this force grows without bound as ``v -> 0`` when
    ``b < 1``) or ``'N'`` (``y`` is the force itself).

    Parameters
    ----------
    a, b
        Coefficient and exponent of the regression (paper: 0.2505 and 0.3471); ``a >= 0``,
        ``b >= 0``.
    x_unit, y_unit
        Units of ``x`` and ``y`` as above.
    """

    a: float = 0.2505
    b: float = 0.3471
    x_unit: str = 'mm/s'
    y_unit: str = 'W/(mm/s)'

    model: ClassVar[str] = 'power_regression'

    def __post_init__(self) -> None:
        if self.x_unit not in X_UNITS:
            msg = f'PowerRegressionLoss.x_unit {self.x_unit!r} not one of {list(X_UNITS)}'
            raise ConfigError(msg, key='x_unit')
        if self.y_unit not in Y_UNITS:
            msg = f'PowerRegressionLoss.y_unit {self.y_unit!r} not one of {list(Y_UNITS)}'
            raise ConfigError(msg, key='y_unit')
        if not (math.isfinite(self.a) and self.a >= 0.0):
            msg = f'PowerRegressionLoss.a must be a finite number >= 0, got {self.a!r}'
            raise ConfigError(msg, key='a')
        if not (math.isfinite(self.b) and self.b >= 0.0):
            msg = f'PowerRegressionLoss.b must be a finite number >= 0, got {self.b!r}'
            raise ConfigError(msg, key='b')

    def y(self, v_m_s: np.ndarray) -> np.ndarray:
        """Value of the regression ``a·x**b`` for the speed ``|v|`` expressed in ``x_unit``."""
        x = np.abs(np.asarray(v_m_s, dtype=float)) * X_UNITS[self.x_unit]
        return self.a * _power(x, self.b)

    def force_n(self, v_m_s: np.ndarray, *,
                normal_force_n: float | np.ndarray = 0.0) -> np.ndarray:
        """Resistance force at the nut [N], opposing motion; ``normal_force_n`` is ignored.

        Parameters
        ----------
        v_m_s
            Carriage velocity [m/s], any shape.
        normal_force_n
            Unused by this model (the regression was measured at one load).

        Returns
        -------
        numpy.ndarray
            Force [N], same shape as ``v_m_s``; zero where ``v == 0``.
        """
        v = np.asarray(v_m_s, dtype=float)
        speed = np.abs(v)
        y = self.y(speed)
        if self.y_unit == 'N':
            magnitude = y
        elif self.y_unit == 'W/(mm/s)':
            # P = y [W/(mm/s)] * v [mm/s]  ->  F = P / v [m/s] = 1000 * y
            magnitude = y * 1000.0
        else:  # 'W': y is the loss power itself
            with np.errstate(divide='ignore', invalid='ignore'):
                magnitude = np.where(speed > 0.0, y / np.where(speed > 0.0, speed, 1.0), 0.0)
        return _opposing(v, magnitude)

    def power_w(self, v_m_s: np.ndarray, *,
                normal_force_n: float | np.ndarray = 0.0) -> np.ndarray:
        """Loss power ``-force_n(v)·v`` [W] (never negative)."""
        v = np.asarray(v_m_s, dtype=float)
        return -self.force_n(v, normal_force_n=normal_force_n) * v

    def param_units(self) -> dict[str, str]:
        """``a`` in ``y_unit`` per ``x_unit`` to the power ``b`` (``y = a·x**b``); ``b`` is
        a pure number."""
        return {'a': f'{self.y_unit}/({self.x_unit})^b', 'b': '1'}

    def power_gradient_w(self, v_m_s: np.ndarray, *,
                         normal_force_n: float | np.ndarray = 0.0) -> dict[str, np.ndarray]:
        """``d power_w / d a`` [W per unit of ``a``] and ``d power_w / d b`` [W].

        The loss power is ``a`` times a function of the speed, so ``dP/da`` is the power at
        ``a = 1`` and ``dP/db = P·ln x`` (``x`` the speed in ``x_unit``; 0 at standstill,
        where ``P = 0`` for every ``b``).

        Parameters
        ----------
        v_m_s
            Carriage velocity [m/s], any shape.
        normal_force_n
            Unused by this model.

        Returns
        -------
        dict
            ``{'a': ndarray, 'b': ndarray}``, each shaped as ``v_m_s``.
        """
        v = np.asarray(v_m_s, dtype=float)
        unit = PowerRegressionLoss(a=1.0, b=self.b, x_unit=self.x_unit, y_unit=self.y_unit)
        per_a = unit.power_w(v)
        x = np.abs(v) * X_UNITS[self.x_unit]
        with np.errstate(divide='ignore'):
            log_x = np.log(np.where(x > 0.0, x, 1.0))
        return {'a': per_a, 'b': self.a * per_a * log_x}

    def to_dict(self) -> dict[str, Any]:
        """YAML form: ``{'model': 'power_regression', 'a', 'b', 'x_unit', 'y_unit'}``."""
        return {'model': self.model, 'a': self.a, 'b': self.b,
                'x_unit': self.x_unit, 'y_unit': self.y_unit}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, file: str, key: str) -> 'PowerRegressionLoss':
        """Build from the YAML form (``model`` already checked); errors name ``key``."""
        _check_keys(d, ('model', 'a', 'b', 'x_unit', 'y_unit'), file=file, key=key)
        # bounded so that a * x**b stays finite for any feed the limits allow
        a = _number(d, 'a', file=file, key=key, minimum=0.0, maximum=1.0e6)
        b = _number(d, 'b', file=file, key=key, minimum=0.0, maximum=10.0)
        units = {}
        for name, allowed, default in (('x_unit', tuple(X_UNITS), 'mm/s'),
                                       ('y_unit', Y_UNITS, 'W/(mm/s)')):
            value = d.get(name, default)
            if not isinstance(value, str) or value not in allowed:
                msg = f'expected one of {", ".join(allowed)}, got {describe(value)}'
                raise ConfigError(msg, file=file, key=f'{key}.{name}')
            units[name] = value
        return cls(a=a, b=b, **units)


@register_loss
@dataclass(frozen=True)
class CoulombViscousLoss:
    """Constant (Coulomb) plus viscous resistance, optionally load dependent.

    ``|F| = coulomb_n + mu·|normal_force_n| + viscous_n_s_m·|v|`` for ``v != 0``, opposing
    motion, zero at standstill.

    Parameters
    ----------
    coulomb_n
        Constant friction force [N], ``>= 0``.
    viscous_n_s_m
        Viscous coefficient [N·s/m], ``>= 0``.
    mu
        Friction coefficient applied to the guideway normal force (default 0).
    """

    coulomb_n: float = 0.0
    viscous_n_s_m: float = 0.0
    mu: float = 0.0

    model: ClassVar[str] = 'coulomb_viscous'

    def force_n(self, v_m_s: np.ndarray, *,
                normal_force_n: float | np.ndarray = 0.0) -> np.ndarray:
        """Resistance force at the nut [N], opposing motion, zero where ``v == 0``.

        Parameters
        ----------
        v_m_s
            Carriage velocity [m/s], any shape.
        normal_force_n
            Force pressing the carriage onto its guideways [N] (scalar or broadcastable).

        Returns
        -------
        numpy.ndarray
            Force [N], broadcast shape of the inputs.
        """
        v = np.asarray(v_m_s, dtype=float)
        magnitude = (self.coulomb_n + self.mu * np.abs(np.asarray(normal_force_n, dtype=float))
                     + self.viscous_n_s_m * np.abs(v))
        return _opposing(v, magnitude)

    def power_w(self, v_m_s: np.ndarray, *,
                normal_force_n: float | np.ndarray = 0.0) -> np.ndarray:
        """Loss power ``-force_n(v)·v`` [W] (never negative)."""
        v = np.asarray(v_m_s, dtype=float)
        return -self.force_n(v, normal_force_n=normal_force_n) * v

    def param_units(self) -> dict[str, str]:
        """``coulomb_n`` [N], ``viscous_n_s_m`` [N·s/m], ``mu`` (a pure number)."""
        return {'coulomb_n': 'N', 'viscous_n_s_m': 'N*s/m', 'mu': '1'}

    def power_gradient_w(self, v_m_s: np.ndarray, *,
                         normal_force_n: float | np.ndarray = 0.0) -> dict[str, np.ndarray]:
        """``d power_w / d param``: ``|v|``, ``v²`` and ``|N|·|v|`` (the power is linear in
        every parameter).

        Parameters
        ----------
        v_m_s
            Carriage velocity [m/s], any shape.
        normal_force_n
            Guideway normal force [N] (scalar or broadcastable).

        Returns
        -------
        dict
            ``{'coulomb_n', 'viscous_n_s_m', 'mu'}`` -> ndarray of the broadcast shape.
        """
        speed = np.abs(np.asarray(v_m_s, dtype=float))
        normal = np.abs(np.asarray(normal_force_n, dtype=float))
        return {'coulomb_n': speed.copy(), 'viscous_n_s_m': speed * speed,
                'mu': np.broadcast_to(normal * speed, np.broadcast(normal, speed).shape).copy()}

    def to_dict(self) -> dict[str, Any]:
        """YAML form: ``{'model': 'coulomb_viscous', 'coulomb_n', 'viscous_n_s_m', 'mu'}``."""
        return {'model': self.model, 'coulomb_n': self.coulomb_n,
                'viscous_n_s_m': self.viscous_n_s_m, 'mu': self.mu}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, file: str, key: str) -> 'CoulombViscousLoss':
        """Build from the YAML form (``model`` already checked); errors name ``key``."""
        _check_keys(d, ('model', 'coulomb_n', 'viscous_n_s_m', 'mu'), file=file, key=key)
        return cls(coulomb_n=_number(d, 'coulomb_n', file=file, key=key, default=0.0,
                                     minimum=0.0),
                   viscous_n_s_m=_number(d, 'viscous_n_s_m', file=file, key=key, default=0.0,
                                         minimum=0.0),
                   mu=_number(d, 'mu', file=file, key=key, default=0.0, minimum=0.0))


def loss_from_dict(d: Any, *, file: str = '<dict>', key: str = 'loss') -> LossModel:
    """Build a loss model from its YAML form ``{'model': name, ...params}``.

    Parameters
    ----------
    d
        The mapping read from the machine file.
    file, key
        Where it came from (file name and dotted key), for error messages.

    Returns
    -------
    LossModel
        An instance of the registered class.

    Raises
    ------
    ConfigError
        Not a mapping, unknown ``model``, unknown keys or invalid values.
    """
    if not isinstance(d, Mapping):
        msg = f'expected a mapping with a "model" key, got {describe(d)}'
        raise ConfigError(msg, file=file, key=key)
    name = d.get('model')
    if not isinstance(name, str) or name not in LOSS_MODELS:
        msg = f'unknown loss model {describe(name)}; expected one of {", ".join(LOSS_MODELS)}'
        raise ConfigError(msg, file=file, key=f'{key}.model')
    return LOSS_MODELS[name].from_dict(d, file=file, key=key)
