"""Sinumerik frames: the programmable frame on top of the settable work offset.

A point ``p`` of the program (workpiece coordinates, mm) reaches the machine as
``m = o + A p + b``: ``o`` is the settable work offset (``G54``..``G57``, ``G505``..``G599``;
their values are machine data, not in the program, and are taken as zero unless given), and
``(A, b)`` the programmable frame. As the programming manual describes, an absolute frame
instruction (``TRANS``, ``ROT``, ``SCALE``, ``MIRROR``) replaces the programmable frame with
its one component, and an additive one (``ATRANS``, ``AROT``, ``ASCALE``, ``AMIRROR``) is
chained after the frame in force: it acts in the coordinates that frame defines, so an
``ATRANS`` after a ``ROT`` moves along the rotated axes, and a later translation is scaled by
an earlier ``SCALE``. The instruction alone (``TRANS``) clears the programmable frame.
``ROT`` with several axes turns about Z, then the new Y, then the newest X (Siemens' RPY
convention); ``RPL=`` turns in the working plane. ``G53``/``G153``/``SUPA`` leave out both
frame and work offset for their block; ``G500`` deselects the settable offset.
"""
from __future__ import annotations

import math

__all__ = ['Frame', 'Vec3', 'Mat3', 'IDENTITY', 'rotation', 'plane_axes']

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]

IDENTITY: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
_AXIS = {'X': 0, 'Y': 1, 'Z': 2}


def plane_axes(plane: int) -> tuple[int, int, int]:
    """The (first, second, normal) axis indices of G17, G18 or G19 (G18 is Z-X, as the
    controls define its arc sense)."""
    if plane == 18:
        return 2, 0, 1
    if plane == 19:
        return 1, 2, 0
    return 0, 1, 2


def _mul(a: Mat3, b: Mat3) -> Mat3:
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3))
                 for i in range(3))     # type: ignore[return-value]


def _apply(a: Mat3, v: Vec3) -> Vec3:
    return (a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2],
            a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
            a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2])


def _det(a: Mat3) -> float:
    return (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]))


def _inverse(a: Mat3) -> Mat3:
    d = _det(a)
    c = [[0.0] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(3):
            r = [k for k in range(3) if k != j]
            s = [k for k in range(3) if k != i]
            minor = a[r[0]][s[0]] * a[r[1]][s[1]] - a[r[0]][s[1]] * a[r[1]][s[0]]
            c[i][j] = (-1) ** (i + j) * minor / d
    return tuple(tuple(row) for row in c)      # type: ignore[return-value]


def rotation(axis: int, deg: float) -> Mat3:
    """The rotation by ``deg`` degrees about axis 0, 1 or 2 (counter-clockwise seen from
    the positive axis)."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    if abs(c) < 1e-15:
        c = 0.0
    if abs(s) < 1e-15:
        s = 0.0
    if axis == 0:
        return ((1.0, 0.0, 0.0), (0.0, c, -s), (0.0, s, c))
    if axis == 1:
        return ((c, 0.0, s), (0.0, 1.0, 0.0), (-s, 0.0, c))
    return ((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0))


class Frame:
    """The chain from program to machine coordinates (see the module docstring)."""

    __slots__ = ('matrix', 'shift', 'offset', '_inv')

    def __init__(self) -> None:
        self.matrix: Mat3 = IDENTITY
        self.shift: Vec3 = (0.0, 0.0, 0.0)
        self.offset: Vec3 = (0.0, 0.0, 0.0)    # the settable work offset [mm]
        self._inv: Mat3 | None = IDENTITY

    def clear(self) -> None:
        """Clear the programmable frame (``TRANS`` alone)."""
        self.matrix = IDENTITY
        self.shift = (0.0, 0.0, 0.0)
        self._inv = IDENTITY

    def chain(self, matrix: Mat3 = IDENTITY, shift: Vec3 = (0.0, 0.0, 0.0), *,
              absolute: bool) -> None:
        """Add ``p -> matrix p + shift`` after the frame in force (``absolute``: instead of
        it)."""
        if absolute:
            self.clear()
        moved = _apply(self.matrix, shift)
        self.shift = (self.shift[0] + moved[0], self.shift[1] + moved[1],
                      self.shift[2] + moved[2])
        self.matrix = _mul(self.matrix, matrix)
        self._inv = None

    def forget_inverse(self) -> None:
        """After the matrix was set from outside: compute the inverse again when needed."""
        self._inv = None

    def to_machine(self, p: Vec3, *, suppress: bool = False) -> Vec3:
        """Machine coordinates [mm] of program point ``p`` (``suppress``: G53/SUPA)."""
        if suppress:
            return p
        q = _apply(self.matrix, p)
        return (q[0] + self.shift[0] + self.offset[0], q[1] + self.shift[1] + self.offset[1],
                q[2] + self.shift[2] + self.offset[2])

    def to_program(self, m: Vec3, *, suppress: bool = False) -> Vec3:
        """Program coordinates of machine point ``m`` (the inverse of :meth:`to_machine`)."""
        if suppress:
            return m
        if self._inv is None:
            self._inv = _inverse(self.matrix)
        d = (m[0] - self.shift[0] - self.offset[0], m[1] - self.shift[1] - self.offset[1],
             m[2] - self.shift[2] - self.offset[2])
        return _apply(self._inv, d)

    def direction(self, v: Vec3) -> Vec3:
        """A program direction (or difference) in machine coordinates."""
        return _apply(self.matrix, v)

    def singular(self) -> bool:
        """True when the frame flattens space (a scale factor of zero)."""
        return abs(_det(self.matrix)) < 1e-12

    def arc_sense(self, plane: int) -> int | None:
        """How an arc in ``plane`` maps: +1 same sense, -1 reversed (a mirror), ``None``
        when the frame does not map the plane onto itself as a circle (a rotation out of
        the plane, or unequal scale factors in it)."""
        a, b, n = plane_axes(plane)
        m = self.matrix
        col_a = (m[0][a], m[1][a], m[2][a])
        col_b = (m[0][b], m[1][b], m[2][b])
        col_n = (m[0][n], m[1][n], m[2][n])
        scale = math.hypot(*col_a)
        tol = 1e-9 * max(1.0, scale)
        if (abs(col_a[n]) > tol or abs(col_b[n]) > tol or abs(col_n[a]) > tol
                or abs(col_n[b]) > tol):
            return None
        if abs(math.hypot(*col_b) - scale) > tol or abs(
                col_a[a] * col_b[a] + col_a[b] * col_b[b]) > tol * scale:
            return None
        det2 = col_a[a] * col_b[b] - col_a[b] * col_b[a]
        return 1 if det2 > 0 else -1

    def mirrored(self) -> bool:
        """True when the frame reverses orientation (an odd number of mirrored axes)."""
        return _det(self.matrix) < 0


def axis_index(letter: str) -> int:
    """0, 1 or 2 for X, Y, Z."""
    return _AXIS[letter]
