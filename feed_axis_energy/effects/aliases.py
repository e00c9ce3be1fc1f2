"""Alias groups of the catalog: forms whose power is the same shape, and when they separate.

``analyze`` finds equivalent forms from the data (``identify/ambiguity.py``); this module
states the aliases the catalog has by construction, so that they are checked (tests) and
explained where they are reported. Two kinds:

* **conditional**: the same power shape unless something varies between runs. A constant
  force ``offset_force`` (``F0·v``) and an undeclared incline ``gravity`` (``m·g·sin θ·v``)
  are one shape when every run moves the same mass ``m`` on that axis; with loads that
  differ the force of ``gravity`` follows the mass and the two separate.
* **exact**: one effect is a combination of others for every motion. ``coulomb`` with
  ``F+`` and ``F-`` is symmetric friction ``Fc = (F+ + F-)/2`` plus a constant force
  ``F0 = (F+ - F-)/2`` (:func:`split_coulomb`): power data cannot say which, a force or
  torque trace at rest can (the constant force acts at rest, friction does not).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .catalog import ParamValue

__all__ = ['Alias', 'ALIASES', 'aliases_of', 'split_coulomb', 'join_coulomb',
           'masses_vary']


@dataclass(frozen=True)
class Alias:
    """Effects that share a power shape.

    Attributes
    ----------
    members
        Effect ids.
    relation
        The identity, in words and symbols.
    separates_when
        What in a campaign tells them apart (``''``: nothing does, the identity is exact).
    """

    members: tuple[str, ...]
    relation: str
    separates_when: str


ALIASES: tuple[Alias, ...] = (
    Alias(('offset_force', 'gravity'),
          'F0 · v = m · g · sin(theta) · v with sin(theta) = F0 / (m · g)',
          'the moved mass of the axis differs between runs (different loads on it)'),
    Alias(('coulomb', 'offset_force'),
          'F+ · max(v,0) + F- · max(-v,0) = Fc · |v| + F0 · v, Fc = (F+ + F-)/2, '
          'F0 = (F+ - F-)/2',
          ''),
)
"""The catalog's aliases by construction (``docs/effects.md``)."""


def aliases_of(effect_id: str) -> tuple[Alias, ...]:
    """The aliases that name ``effect_id``."""
    return tuple(a for a in ALIASES if effect_id in a.members)


def split_coulomb(f_pos_n: ParamValue, f_neg_n: ParamValue) -> tuple[ParamValue, ParamValue]:
    """``coulomb``'s ``(F+, F-)`` as symmetric friction and constant force ``(Fc, F0)`` [N]."""
    pos = np.asarray(f_pos_n, dtype=float)
    neg = np.asarray(f_neg_n, dtype=float)
    fc, f0 = 0.5 * (pos + neg), 0.5 * (pos - neg)
    if fc.ndim == 0:
        return float(fc), float(f0)
    return fc, f0


def join_coulomb(fc_n: ParamValue, f0_n: ParamValue) -> tuple[ParamValue, ParamValue]:
    """Symmetric friction ``Fc`` and constant force ``F0`` as ``coulomb``'s ``(F+, F-)`` [N]."""
    fc = np.asarray(fc_n, dtype=float)
    f0 = np.asarray(f0_n, dtype=float)
    pos, neg = fc + f0, fc - f0
    if pos.ndim == 0:
        return float(pos), float(neg)
    return pos, neg


def masses_vary(masses_kg: np.ndarray, *, rtol: float = 1e-6) -> bool:
    """``True`` when the moved masses of the runs on one axis differ (``offset_force`` and
    ``gravity`` then separate)."""
    m = np.asarray(masses_kg, dtype=float)
    if m.size < 2:
        return False
    return bool(np.ptp(m) > rtol * max(float(np.max(np.abs(m))), 1e-12))
