"""Moved masses of stacked feed axes: which axes an axis carries and the mass it moves."""
from __future__ import annotations

from .spec import Machine

__all__ = ['carried_axes', 'moved_mass_kg']


def carried_axes(machine: Machine, axis: str) -> tuple[str, ...]:
    """Return ``axis`` and every axis riding on it, directly or through others.

    Parameters
    ----------
    machine
        The machine.
    axis
        Axis name.

    Returns
    -------
    tuple of str
        Names in machine order.
    """
    machine.axis(axis)
    out = []
    for spec in machine.axes:
        current: str | None = spec.name
        seen = set()
        while current is not None and current not in seen:
            if current == axis:
                out.append(spec.name)
                break
            seen.add(current)
            current = machine.axis(current).rides_on
    return tuple(out)


def moved_mass_kg(machine: Machine, axis: str, load_kg: float = 0.0) -> float:
    """Return the translational mass moved by ``axis`` [kg].

    Its own table, plus the table of every axis riding on it (recursively; a rotary unit by
    its ``mass_kg``), plus ``load_kg`` if it is, or carries, the machine's ``load_axis``.
    For a rotary axis: the moment of inertia of its table and load about the axis
    [kg·m^2] (the equivalent mass of :mod:`.rotary`; ``load_kg`` does not enter it).

    Parameters
    ----------
    machine
        The machine.
    axis
        Axis name.
    load_kg
        Mass of the clamped workpiece (and fixtures not in the table mass) [kg].

    Returns
    -------
    float
        Moved mass [kg].
    """
    spec = machine.axis(axis)
    if spec.rotary is not None:
        # the table's "mass" is its inertia about the axis [kg m^2] (machine/rotary.py)
        return float(spec.rotary.inertia_kg_m2)
    names = carried_axes(machine, axis)
    mass = sum(machine.axis(n).carried_mass_kg for n in names)
    if machine.load_axis in names:
        mass += load_kg
    return float(mass)
