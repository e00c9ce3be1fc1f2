"""G-code (RS-274 / ISO 6983 milling dialects) -> canonical moves in SI units.

Owns the text of NC programs and everything that reads it: the source and its encodings
(:mod:`.read`), the modal interpreter with its coordinate systems and tool table
(:mod:`.interp`), canned cycles, cutter compensation and splines expanded into primitives
(:mod:`.expand`), the machine-side G-code settings (:mod:`.settings`), the checks and statistics
of a program (:mod:`.check`, :mod:`.stats`). The one way out is the canonical :class:`Move`
(:mod:`.program`): :func:`iter_moves` streams them, :func:`load_gcode` collects a
:class:`Program`. ``docs/gcode-design.md`` maps each G-code feature to its module.
"""
from .check import (check_limits, checked_warning_texts, CheckLimits, DEFAULT_MAX_DWELL_S,
                    MAX_ERRORS, MoveChecker, problem_from_error, problems_from_warnings,
                    program_problems, sanity_checker, warning_texts)
from .dialect import Dialect, dialect_by_name
from .load import DEFAULT_ARC_TOLERANCE_M, iter_moves, load_gcode, MoveStream, parse_gcode
from .program import Move, MoveKind, Program, PROGRAM_AXES, ROTARY_AXES
from .settings import (check_subroutine_dir, DIALECTS, gcode_from_dict, gcode_to_dict,
                       GcodeSettings, MAX_SUBROUTINE_DIRS, parse_tool_option, ToolSpec,
                       travel_from_value, with_program_options, with_tools)

__all__ = [
    'check_limits', 'check_subroutine_dir', 'checked_warning_texts', 'CheckLimits',
    'DEFAULT_ARC_TOLERANCE_M', 'DEFAULT_MAX_DWELL_S', 'Dialect', 'dialect_by_name', 'DIALECTS',
    'gcode_from_dict', 'gcode_to_dict', 'GcodeSettings', 'iter_moves', 'load_gcode',
    'MAX_ERRORS', 'MAX_SUBROUTINE_DIRS', 'Move', 'MoveChecker', 'MoveKind', 'MoveStream',
    'parse_gcode', 'parse_tool_option', 'problem_from_error', 'problems_from_warnings',
    'Program', 'PROGRAM_AXES', 'program_problems', 'ROTARY_AXES', 'sanity_checker',
    'ToolSpec',
    'travel_from_value', 'warning_texts', 'with_program_options', 'with_tools',
]
