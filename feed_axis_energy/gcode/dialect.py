"""Dialect profiles: where the controls that programs are written for differ.

The interpreter follows LinuxCNC 2.9 (RS274NGC) everywhere; a :class:`Dialect` changes only
the rules below, each copied from the control named in its profile. Choose one with
``--dialect`` (``simulate``), ``gcode.dialect`` in the machine config, or
``parse_gcode(dialect=...)``; the default is ``linuxcnc``.

=============  ============  ===========  ================  ========  ===========  ===========
dialect        G4 P          G4 X         ``K0``, G17 arc   M98/M99   Macro B (1)  M100-M199
=============  ============  ===========  ================  ========  ===========  ===========
``linuxcnc``   seconds       (axis word)  error (LinuxCNC)  yes       no           warning (2)
``fanuc``      milliseconds  seconds      ignored, warning  yes       yes          error
``haas``       see below     (axis word)  ignored, warning  yes       yes (+ M97)  error
``grbl``       seconds       (axis word)  ignored, warning  no        no           error
``mach3``      seconds       (axis word)  ignored, warning  yes       no           error
``sinumerik``  (3)           (axis word)  ignored, warning  no (3)    no (3)       error
=============  ============  ===========  ================  ========  ===========  ===========

(1) Fanuc Custom Macro B: ``WHILE``/``DO``/``END``, ``IF``/``GOTO``/``THEN``, ``G65``
macro calls (and Haas ``M97`` local subprograms), read by the front (:mod:`.flow`), and
the read-only system variables ``#4001..#4130`` and ``#5001..#5083`` from the modal state
(:mod:`feed_axis_energy.gcode.interp.sysvars`; in LinuxCNC they are ordinary parameters).

(2) User M codes: LinuxCNC runs the executable ``M100``..``M199`` of its ``USER_M_PATH``
with the line's P and Q as its two arguments and waits for it to end; such a program moves
no axis through the interpreter, so the code is accepted as no motion, with one warning per
code (its run time is not counted). The other controls give these numbers other meanings,
which may move the axes, so there they are errors naming the dialect: Fanuc calls a custom
macro for an M code registered in its parameters (6080-6089), Mach3 runs the VB macro
``Mnnn.m1s``, which may command motion, Haas has its own M100+ machine functions
(probe arm, tailstock, spindle speed variation) and grbl knows no M code above M56.

* No feed rate: a G1/G2/G3 (or a G5 spline) in G94 with no F since the start is refused
  in every dialect (LinuxCNC "Cannot do G1 with zero feed rate", Fanuc alarm PS0011, grbl
  error 22), naming the line and column; ``allow_no_feed`` (``--allow-no-feed``,
  ``gcode.allow_no_feed``) previews it at the machine's axis limits with one warning, as
  LinuxCNC's preview does (it starts with a feed rate of 1). An F0 in force is refused
  always (the preview refuses it too); G93 needs F on every feed line, G95 an F and an S.

(3) Sinumerik (840D sl, milling) is Siemens' own NC language, read by its own front
(:mod:`feed_axis_energy.gcode.siemens`: ``G4 F`` seconds / ``G4 S`` spindle revolutions,
subprograms by name, ``R`` parameters and ``DEF`` variables, ``IF``/``GOTOF``/``WHILE``/
``FOR``/``REPEAT``/``LOOP``, frames ``TRANS``/``ROT``/``SCALE``/``MIRROR`` (+ ``A..``),
``G54``-``G57``/``G505``-``G599``, ``G70``/``G71``/``G700``/``G710``, polar ``G110``-``G112``
``AP=``/``RP=``, ``CR=``/``CIP``/``CT`` arcs, ``AC()``/``IC()``, drilling cycles
``CYCLE81``/``82``/``83``/``85``/``89`` with ``MCALL`` and ``HOLES1``/``HOLES2``), which hands
each block on to the interpreter as RS274NGC words in machine coordinates. Chosen with
``--dialect sinumerik`` or from the file: a ``.MPF``/``.SPF`` name, a ``%_N_NAME_MPF``
header or ``G710``/``G700`` among the first lines select it where the dialect would
otherwise be ``linuxcnc`` (the default), with one warning saying why. Cycles that cannot be
simulated (pockets, ``CYCLE800`` swivelling, thread cycles, ...) are refused by name.
Harmless M codes add clamping M10/M11 and gear stages M40-M45; ``M17`` returns from a
subprogram.

* G4 P: LinuxCNC, grbl and Mach3 (its default configuration) read seconds. Fanuc (Series
  0i/30i: ``G04 P`` in milliseconds without a decimal point, ``G04 X`` in seconds) reads
  milliseconds; Haas mills read ``P`` with a decimal point as seconds and without one as
  milliseconds (``G04 P2.5`` and ``G04 P2500`` both dwell 2.5 s).
* An in-plane-normal centre word of zero (``K0`` in G17, ``J0`` in G18, ``I0`` in G19, as
  FreeCAD's post-processors write it) is an error in LinuxCNC; other controls ignore it, so
  there it is accepted with one warning. A non-zero one is always an error.
* Harmless M codes: machine functions that do not move the feed axes are accepted and
  ignored. Every dialect: M0-M9, M30 (and M48-M53 overrides, M19 spindle orientation,
  M61 Q set current tool, M62-M68 digital/analog I/O, as LinuxCNC implements them); Fanuc
  and Haas add their machine M codes (brakes M10-M13, chip conveyor M31-M33, coolant
  variants M34/M35/M88/M89, gear range M40-M42, user relays M51-M59/M61-M69, air blast
  M73-M76/M83/M84, tool clamp M82/M86); Mach3 adds M40/M41. Any other M code is an error
  naming the dialect.
* grbl ``$`` lines and ``%`` lines with text are handled by the reader for every dialect
  (skipped, with a warning for ``$``).
* G5, G5.1, G5.2/G5.3 are LinuxCNC's splines (:mod:`.splines`) in the ``linuxcnc`` dialect
  only; grbl and Mach3 refuse them with the line and column.
* The ``D`` word: LinuxCNC accepts it only beside G41/G42 (the tool whose radius they use);
  Fanuc and Haas read a ``D`` on any line as the choice of the radius offset that the next
  G41/G42 without a ``D`` uses (``T11 D11 M06``), and so do these dialects (the offset is
  looked up in the tool table by its number, as LinuxCNC looks up D).
* Contouring modes of the control (:data:`CONTROL_MODE_CODES`): Fanuc ``G05 P10000`` /
  ``G05 P0`` (high-speed machining, HPCC), ``G05.1 Q1`` / ``Q0`` (AI contour control) and
  ``G08 P1`` / ``P0`` (look-ahead control); Haas ``G187`` (smoothness and accuracy, ``P1-3``
  and ``E``) and ``G103`` (block look-ahead limit). CAM post-processors for these controls
  write them around every toolpath. They change how the control itself smooths and
  accelerates, which the planner takes from the machine config, so they are accepted with
  one warning each and their ``P``/``Q``/``E``/``L`` words ignored.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError

__all__ = ['Dialect', 'DIALECTS', 'dialect_by_name', 'DEFAULT_DIALECT', 'CONTROL_MODE_CODES',
           'USER_M_CODES']

USER_M_CODES = (100, 199)
"""First and last user M code (LinuxCNC's ``M100``-``M199``; :attr:`Dialect.user_m`)."""

# 10 x G code -> what it selects on the control (see the module docstring).
CONTROL_MODE_CODES: dict[int, str] = {
    50: 'G05 high-speed machining mode (Fanuc HPCC)',
    51: 'G05.1 AI contour control (Fanuc)',
    80: 'G08 look-ahead control (Fanuc)',
    1870: 'G187 smoothness and accuracy setting (Haas)',
    1030: 'G103 block look-ahead limit (Haas)',
}

_LINUXCNC_M = frozenset({19, 48, 49, 50, 51, 52, 53, 61, 62, 63, 64, 65, 66, 67, 68})
_FANUC_M = frozenset({10, 11, 12, 13, 16, 17, 19, 21, 22, 23, 24, 25, 26, 27, 28, 31, 32,
                      33, 34, 35, 36, 39, 40, 41, 42, 46, 48, 49, 50, 51, 52, 53, 54, 55,
                      56, 57, 58, 59, 62, 63, 64, 65, 66, 67, 68, 69, 73, 74, 75, 76, 83,
                      84, 82, 86, 88, 89})

# Sinumerik machine M codes without axis motion: clamping (M10/M11), gear stages (M40-M45).
_SIEMENS_M = frozenset({10, 11, 40, 41, 42, 43, 44, 45})


@dataclass(frozen=True)
class Dialect:
    """The rules in which a control differs from LinuxCNC (see the module table).

    Attributes
    ----------
    name
        Registry name.
    control
        The control whose behaviour the profile copies.
    dwell_p
        ``'seconds'``, ``'milliseconds'`` or ``'haas'`` (decimal point: seconds, else ms).
    dwell_x_seconds
        ``G4 X`` is a dwell in seconds (Fanuc) instead of an axis word.
    normal_centre_zero
        ``'error'`` or ``'warn'``: a zero centre word along the plane normal.
    harmless_m
        M codes accepted and ignored besides M0-M9 and M30.
    fanuc_subprograms
        ``O1234`` blocks with ``M98 P.. L..`` / ``M99`` are subprograms (read by the front).
    fanuc_macro
        Fanuc Custom Macro B (``WHILE``/``DO``/``END``, ``IF``/``GOTO``/``THEN``, ``G65``,
        Haas ``M97``), read by the front.
    g5_splines
        G5/G5.1/G5.2/G5.3 are LinuxCNC's splines (else they are refused).
    control_modes
        G codes (10 x code, keys of :data:`CONTROL_MODE_CODES`) that select the control's
        own contouring mode: accepted with a warning, their P/Q/E/L words ignored.
    modal_d
        A ``D`` word on any line selects the cutter radius offset that later G41/G42 use
        (Fanuc, Haas: ``T11 D11 M06``); LinuxCNC allows D only with G41/G42.
    user_m
        M100-M199 are the user's own M codes (LinuxCNC runs an external program): accepted
        as no motion with one warning per code, their P and Q words its arguments.
    siemens
        The program is in Siemens' NC language, read by its own front
        (:mod:`feed_axis_energy.gcode.siemens`), which hands RS274NGC words on.
    """

    name: str
    control: str
    dwell_p: str = 'seconds'
    dwell_x_seconds: bool = False
    normal_centre_zero: str = 'warn'
    harmless_m: frozenset[int] = _LINUXCNC_M
    fanuc_subprograms: bool = True
    fanuc_macro: bool = False
    g5_splines: bool = False
    control_modes: frozenset[int] = frozenset()
    modal_d: bool = False
    user_m: bool = False
    siemens: bool = False


DIALECTS: dict[str, Dialect] = {
    'linuxcnc': Dialect('linuxcnc', 'LinuxCNC 2.9 (RS274NGC)', normal_centre_zero='error',
                        g5_splines=True, user_m=True),
    'fanuc': Dialect('fanuc', 'Fanuc Series 0i-MF / 30i (milling)', dwell_p='milliseconds',
                     dwell_x_seconds=True, harmless_m=_LINUXCNC_M | _FANUC_M,
                     fanuc_macro=True, control_modes=frozenset({50, 51, 80}), modal_d=True),
    'haas': Dialect('haas', 'Haas mill (NGC control)', dwell_p='haas',
                    harmless_m=_LINUXCNC_M | _FANUC_M, fanuc_macro=True,
                    control_modes=frozenset({1870, 1030}), modal_d=True),
    'grbl': Dialect('grbl', 'grbl 1.1', fanuc_subprograms=False),
    'mach3': Dialect('mach3', 'Mach3 Mill (default configuration)',
                     harmless_m=_LINUXCNC_M | {40, 41}),
    'sinumerik': Dialect('sinumerik', 'Siemens Sinumerik 840D sl (milling)',
                         harmless_m=_LINUXCNC_M | _SIEMENS_M, fanuc_subprograms=False,
                         siemens=True),
}
DEFAULT_DIALECT = DIALECTS['linuxcnc']


def dialect_by_name(name: str | Dialect | None) -> Dialect:
    """The profile called ``name`` (case-insensitive); ``None`` gives ``linuxcnc``.

    Raises
    ------
    ConfigError
        For an unknown name (the message lists the known ones).
    """
    if name is None:
        return DEFAULT_DIALECT
    if isinstance(name, Dialect):
        return name
    key = str(name).strip().lower()
    if key not in DIALECTS:
        shown = str(name)[:60]
        msg = f'unknown G-code dialect {shown!r}; known: {", ".join(DIALECTS)}'
        raise ConfigError(msg, key='gcode.dialect')
    return DIALECTS[key]
