"""Parameters of an RS274NGC program: numbered ``#1..#5601`` and named ``#<name>``.

LinuxCNC's rules (G-code overview, "Parameters"; ``interp_read.cc``):

* Numbered parameters are ``#1`` to ``#5601``; any other number is an error. An unset
  numbered parameter reads 0. ``#1..#30`` are the arguments of an ``o... call`` and are
  local to the call (restored on return); those without an argument are 0 in the call
  (LinuxCNC 2.9's code, ``interp_o_word.cc``, zeroes them; its manual says they keep the
  caller's values); all others are global. ``#5021..#5029``,
  ``#5400..#5413`` and ``#5420..#5428`` are read-only.
* Named parameters are case-insensitive and blanks inside the name do not count (the line
  is read with blanks removed). A name beginning with ``_`` is global; any other is local
  to the subroutine call that set it (or to the main program). Reading a named parameter
  that was never set is an error.
* Live system values (current position ``#5420..#5428``, tool ``#5400``, ``#<_x>``,
  ``#<_metric>``, ...) come from a ``provider`` the interpreter installs: it is asked first
  for every read, and answers ``None`` for anything it does not supply.
* Predefined named parameters (LinuxCNC's read-only list, :data:`READ_ONLY_NAMES`) cannot
  be assigned by a program. The table itself supplies those that belong to the reading
  half: ``#<_value>`` and ``#<_value_returned>`` (set by ``endsub``/``return``),
  ``#<_call_level>``, ``#<_vmajor>`` = 2 and ``#<_vminor>`` = 9 (LinuxCNC 2.9), and
  ``#<_task>`` = 1: the program runs on the machine (LinuxCNC's preview reads 0; a program
  that skips work in the preview is simulated as it runs).
"""
from __future__ import annotations

from typing import Callable, Union

__all__ = ['Parameters', 'Provider', 'MAX_PARAMETER', 'N_CALL_ARGUMENTS',
           'READ_ONLY_PARAMETERS', 'READ_ONLY_NAMES', 'ParameterError', 'normalize_name']

MAX_PARAMETER = 5601
"""Highest numbered parameter (LinuxCNC's ``RS274NGC_MAX_PARAMETERS`` - 1)."""

N_CALL_ARGUMENTS = 30
"""``#1..#30`` hold the arguments of a call and are local to it."""

READ_ONLY_PARAMETERS = frozenset([*range(5021, 5030), *range(5400, 5414),
                                  *range(5420, 5429)])
"""Numbered parameters a program may read but not assign (LinuxCNC's list)."""

READ_ONLY_NAMES = frozenset(
    ['_line', '_motion_mode', '_plane', '_ccomp', '_metric', '_imperial', '_absolute',
     '_incremental', '_inverse_time', '_units_per_minute', '_units_per_rev', '_coord_system',
     '_tool_offset', '_retract_r_plane', '_retract_old_z', '_spindle_rpm_mode',
     '_spindle_css_mode', '_ijk_absolute_mode', '_lathe_diameter_mode', '_lathe_radius_mode',
     '_spindle_on', '_spindle_cw', '_mist', '_flood', '_speed_override', '_feed_override',
     '_adaptive_feed', '_feed_hold', '_feed', '_rpm', '_current_tool', '_current_pocket',
     '_selected_pocket', '_selected_tool', '_value', '_value_returned', '_task',
     '_call_level', '_remap_level', '_vmajor', '_vminor', '_metric_machine',
     *(f'_{a}' for a in 'xyzabcuvw'), *(f'_abs_{a}' for a in 'xyzabcuvw')])
"""Predefined named parameters a program may read but not assign (LinuxCNC 2.9's list)."""

Provider = Callable[[Union[int, str]], Union[float, None]]
"""``provider(key)``: a live system value for a parameter number or a normalised name."""


class ParameterError(ValueError):
    """A parameter access that LinuxCNC refuses; the reader adds the place.

    Not one of the project's public error types: :mod:`.expr` turns it into a
    :class:`~..errors.GcodeError` at the column of the offending parameter.
    """


def normalize_name(name: str) -> str:
    """Return the key of a named parameter: lower case, blanks removed."""
    return ''.join(name.split()).lower()


class Parameters:
    """The parameter table of one program run, with subroutine scopes.

    Parameters
    ----------
    provider
        Live system values, asked first on every read (see the module docstring).
    """

    __slots__ = ('numbered', 'globals', 'scopes', 'provider', 'read_only')

    def __init__(self, *, provider: Provider | None = None):
        self.numbered = [0.0] * (MAX_PARAMETER + 1)
        self.globals: dict[str, float] = {'_value': 0.0, '_value_returned': 0.0,
                                          '_vmajor': 2.0, '_vminor': 9.0, '_task': 1.0}
        # One dict of local named parameters per call level; [0] is the main program's.
        self.scopes: list[dict[str, float]] = [{}]
        self.provider = provider
        # Numbers a dialect adds to the read-only ones (Fanuc system variables).
        self.read_only: frozenset[int] = frozenset()

    # -- numbered --------------------------------------------------------------------------
    def get(self, n: int) -> float:
        """Value of ``#n`` (0 if never set).

        Raises
        ------
        ParameterError
            If ``n`` is outside ``1..MAX_PARAMETER``.
        """
        if not 1 <= n <= MAX_PARAMETER:
            msg = f'parameter number #{n} out of range (1 to {MAX_PARAMETER})'
            raise ParameterError(msg)
        if self.provider is not None:
            value = self.provider(n)
            if value is not None:
                return float(value)
        return self.numbered[n]

    def check_settable(self, n: int) -> None:
        """Refuse an assignment to ``#n`` before it is queued.

        Raises
        ------
        ParameterError
            Out of range or read-only.
        """
        if not 1 <= n <= MAX_PARAMETER:
            msg = f'parameter number #{n} out of range (1 to {MAX_PARAMETER})'
            raise ParameterError(msg)
        if n in READ_ONLY_PARAMETERS:
            raise ParameterError(f'parameter #{n} is read-only')
        if n in self.read_only:
            raise ParameterError(f'#{n} is a read-only system variable in this dialect')

    def set(self, n: int, value: float) -> None:
        """Assign ``#n`` (the interpreter also uses this for persistent system values)."""
        if not 1 <= n <= MAX_PARAMETER:
            msg = f'parameter number #{n} out of range (1 to {MAX_PARAMETER})'
            raise ParameterError(msg)
        self.numbered[n] = float(value)

    # -- named -----------------------------------------------------------------------------
    def get_named(self, name: str) -> float:
        """Value of ``#<name>``.

        Raises
        ------
        ParameterError
            If it was never set (and the provider does not supply it).
        """
        key = normalize_name(name)
        if self.provider is not None:
            value = self.provider(key)
            if value is not None:
                return float(value)
        if key == '_call_level':
            return float(len(self.scopes) - 1)
        table = self.globals if key.startswith('_') else self.scopes[-1]
        try:
            return table[key]
        except KeyError:
            raise ParameterError(f'named parameter #<{key}> is not defined') from None

    def exists_named(self, name: str) -> bool:
        """Whether ``#<name>`` can be read (LinuxCNC's ``EXISTS[#<name>]``)."""
        key = normalize_name(name)
        if self.provider is not None and self.provider(key) is not None:
            return True
        if key == '_call_level':
            return True
        table = self.globals if key.startswith('_') else self.scopes[-1]
        return key in table

    def check_settable_named(self, name: str) -> None:
        """Refuse an assignment to a predefined named parameter.

        Raises
        ------
        ParameterError
            If the name is in :data:`READ_ONLY_NAMES`.
        """
        key = normalize_name(name)
        if key in READ_ONLY_NAMES:
            raise ParameterError(f'named parameter #<{key}> is read-only')

    def set_named(self, name: str, value: float) -> None:
        """Assign ``#<name>`` (global if the name begins with ``_``, else local).

        No read-only check: the reader calls :meth:`check_settable_named` for a program's
        assignments; the flow and the interpreter set predefined values here.
        """
        key = normalize_name(name)
        table = self.globals if key.startswith('_') else self.scopes[-1]
        table[key] = float(value)

    # -- subroutine scopes -----------------------------------------------------------------
    def enter_call(self, args: list[float] | None) -> list[float]:
        """Open the scope of a call.

        Parameters
        ----------
        args
            The call's arguments for ``#1..#len(args)``, the rest of ``#1..#30`` set to 0
            (``o... call``), or ``None`` for a Fanuc ``M98`` call, whose ``#1..#30`` stay
            global.

        Returns
        -------
        list[float]
            The saved ``#1..#30`` to hand back to :meth:`leave_call` (empty for ``M98``).
        """
        self.scopes.append({})
        if args is None:
            return []
        saved = self.numbered[1:N_CALL_ARGUMENTS + 1]
        values = [float(v) for v in args[:N_CALL_ARGUMENTS]]
        self.numbered[1:N_CALL_ARGUMENTS + 1] = values + [0.0] * (N_CALL_ARGUMENTS - len(values))
        return saved

    def leave_call(self, saved: list[float]) -> None:
        """Close the innermost call scope, restoring ``#1..#30`` if they were saved."""
        if len(self.scopes) > 1:
            self.scopes.pop()
        if saved:
            self.numbered[1:N_CALL_ARGUMENTS + 1] = saved
