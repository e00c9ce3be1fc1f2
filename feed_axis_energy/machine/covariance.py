"""The covariance of a loss function's parameters: ``loss_covariance`` in a machine config.

``fit-loss --out-machine`` writes, beside each fitted ``loss``, the axis key::

    loss_covariance:
      params: [a, b]
      units: [W/(mm/s)/(mm/s)^b, '1']
      matrix: [[2.0e-05, -6.1e-05], [-6.1e-05, 2.3e-04]]

``params`` names parameters of the axis's loss model (any of them, each once), ``units``
states their units exactly as the model gives them (:meth:`.losses.PowerRegressionLoss.
param_units`; a covariance for other units is refused, not converted), and ``matrix`` is
their covariance in those units (entry ``[i][j]`` in ``units[i]·units[j]``): square, finite,
symmetric and positive semi-definite. :mod:`.uncertainty` propagates it to the energy.

This module imports no other part of the machine model, so :mod:`.machine` can use it.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..configcheck import check_mapping, is_finite_number
from ..errors import ConfigError, describe, shorten

__all__ = ['LossCovariance', 'covariance_from_value', 'MAX_ENTRY']

MAX_ENTRY = 1.0e12
"""Largest magnitude of an entry: keeps every propagated figure finite."""

_SYMMETRY_RTOL = 1.0e-9     # relative to the largest entry: YAML keeps 17 digits
_PSD_RTOL = 1.0e-9          # a negative eigenvalue smaller than this is rounding


@dataclass(frozen=True)
class LossCovariance:
    """Covariance of some parameters of one axis's loss model.

    Attributes
    ----------
    params
        Parameter names of the loss model, each once.
    units
        Their units (as :meth:`param_units` of the model gives them).
    matrix
        Covariance, ``len(params)`` rows of ``len(params)`` numbers, symmetric positive
        semi-definite; entry ``[i][j]`` in ``units[i]·units[j]``.
    """

    params: tuple[str, ...]
    units: tuple[str, ...]
    matrix: tuple[tuple[float, ...], ...]

    def array(self) -> np.ndarray:
        """The matrix as a ``(p, p)`` array."""
        return np.array(self.matrix, dtype=float).reshape(len(self.params), len(self.params))

    def standard_errors(self) -> dict[str, float]:
        """Square roots of the diagonal, per parameter (in its unit)."""
        return {p: float(np.sqrt(max(self.matrix[i][i], 0.0)))
                for i, p in enumerate(self.params)}

    def to_dict(self) -> dict[str, Any]:
        """YAML form."""
        return {'params': list(self.params), 'units': list(self.units),
                'matrix': [[float(v) for v in row] for row in self.matrix]}

    @classmethod
    def of(cls, params: Sequence[str], units: Sequence[str],
           matrix: Any) -> 'LossCovariance':
        """Build from any array-like matrix (symmetrised; not validated: see
        :func:`covariance_from_value` for input from outside)."""
        m = np.asarray(matrix, dtype=float)
        m = 0.5 * (m + m.T)
        return cls(tuple(params), tuple(units), tuple(tuple(float(v) for v in row) for row in m))


def _names(value: Any, *, file: str, key: str, allowed: Sequence[str]) -> tuple[str, ...]:
    if (not isinstance(value, list) or not value
            or not all(isinstance(v, str) for v in value)):
        msg = f'expected a list of parameter names ({", ".join(allowed)}), got {describe(value)}'
        raise ConfigError(msg, file=file, key=key)
    for i, name in enumerate(value):
        if name not in allowed:
            msg = (f'{shorten(name)!r} is not a parameter of this loss model; expected '
                   f'{", ".join(allowed)}')
            raise ConfigError(msg, file=file, key=f'{key}[{i}]')
        if name in value[:i]:
            msg = f'parameter {name!r} named twice'
            raise ConfigError(msg, file=file, key=f'{key}[{i}]')
    return tuple(value)


def _matrix(value: Any, p: int, *, file: str, key: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != p:
        msg = f'expected a list of {p} rows (one per parameter), got {describe(value)}'
        raise ConfigError(msg, file=file, key=key)
    for i, row in enumerate(value):
        if not isinstance(row, list) or len(row) != p:
            msg = f'expected a row of {p} numbers, got {describe(row)}'
            raise ConfigError(msg, file=file, key=f'{key}[{i}]')
        for j, v in enumerate(row):
            if not is_finite_number(v) or abs(float(v)) > MAX_ENTRY:
                msg = f'expected a finite number of magnitude <= {MAX_ENTRY:g}, got {describe(v)}'
                raise ConfigError(msg, file=file, key=f'{key}[{i}][{j}]')
    m = np.array(value, dtype=float)
    scale = float(np.max(np.abs(m)))
    for i in range(p):
        if m[i, i] < 0.0:
            msg = f'a variance must be >= 0, got {m[i, i]:.6g}'
            raise ConfigError(msg, file=file, key=f'{key}[{i}][{i}]')
        for j in range(i + 1, p):
            if abs(m[i, j] - m[j, i]) > _SYMMETRY_RTOL * scale:
                msg = (f'not symmetric: [{i}][{j}] = {m[i, j]:.6g} but [{j}][{i}] = '
                       f'{m[j, i]:.6g}')
                raise ConfigError(msg, file=file, key=f'{key}[{i}][{j}]')
    m = 0.5 * (m + m.T)
    if scale > 0.0:
        low = float(np.linalg.eigvalsh(m).min())
        if low < -_PSD_RTOL * scale:
            msg = (f'not positive semi-definite (smallest eigenvalue {low:.6g}): a covariance '
                   'cannot give a negative variance to any combination of the parameters')
            raise ConfigError(msg, file=file, key=key)
    return m


def covariance_from_value(value: Any, *, loss: Any, file: str,
                          key: str) -> LossCovariance | None:
    """Validate an axis's ``loss_covariance`` against its loss model (``None`` when absent).

    Parameters
    ----------
    value
        The mapping read from the machine file, or ``None``.
    loss
        The axis's loss model (its :meth:`param_units`).
    file, key
        Where it came from (errors name ``key.params[i]``, ``key.matrix[i][j]``, ...).

    Returns
    -------
    LossCovariance or None

    Raises
    ------
    ConfigError
        Unknown keys, parameters the model does not have, units other than the model's,
        a matrix that is not square, finite, symmetric and positive semi-definite.
    """
    if value is None:
        return None
    d = check_mapping(value, file=file, key=key, allowed=('params', 'units', 'matrix'))
    for name in ('params', 'units', 'matrix'):
        if name not in d:
            msg = 'missing required value'
            raise ConfigError(msg, file=file, key=f'{key}.{name}')
    known = loss.param_units() if hasattr(loss, 'param_units') else {}
    params = _names(d['params'], file=file, key=f'{key}.params', allowed=tuple(known))
    units = d['units']
    if not isinstance(units, list) or len(units) != len(params):
        msg = f'expected a list of {len(params)} units (one per parameter), got {describe(units)}'
        raise ConfigError(msg, file=file, key=f'{key}.units')
    for i, (name, unit) in enumerate(zip(params, units)):
        if unit != known[name]:
            msg = (f'the loss model gives {name} in {known[name]!r}, not {describe(unit)}; the '
                   'covariance must be in the units of the loss model as configured')
            raise ConfigError(msg, file=file, key=f'{key}.units[{i}]')
    m = _matrix(d['matrix'], len(params), file=file, key=f'{key}.matrix')
    return LossCovariance.of(params, [known[p] for p in params], m)
