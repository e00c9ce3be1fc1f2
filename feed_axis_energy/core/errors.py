"""Every error type the core raises; each message names the place and what was expected."""
from __future__ import annotations

__all__ = ['FeedAxisError', 'GcodeError', 'ConfigError', 'DataError', 'PlanningError']


class FeedAxisError(ValueError):
    """Base of all domain errors of the package (a ``ValueError``)."""


class GcodeError(FeedAxisError):
    """An NC program that cannot be simulated.

    Parameters
    ----------
    message
        What is wrong and what was expected.
    file, line, column
        The place: file name, 1-based line and 1-based column of the offending text.
    text
        The offending text itself (a word such as ``G5`` or the whole line).
    """

    def __init__(self, message: str, *, file: str, line: int, column: int, text: str = ''):
        self.file = file
        self.line = line
        self.column = column
        self.text = text
        self.reason = message
        shown = f' near {text!r}' if text else ''
        super().__init__(f'{file}:{line}:{column}: {message}{shown}')


class ConfigError(FeedAxisError):
    """A machine, manifest or node parameter file with a missing or invalid value.

    ``key`` is the dotted path of the value (``axes.X.screw.lead_m``).
    """

    def __init__(self, message: str, *, file: str = '<config>', key: str = ''):
        self.file = file
        self.key = key
        self.reason = message
        where = f'{file}: {key}: ' if key else f'{file}: '
        super().__init__(f'{where}{message}')


class DataError(FeedAxisError):
    """Measured data that cannot be used; names file, column and (1-based data) row."""

    def __init__(self, message: str, *, file: str, column: str = '', row: int | None = None):
        self.file = file
        self.column = column
        self.row = row
        self.reason = message
        parts = [file]
        if column:
            parts.append(f'column {column!r}')
        if row is not None:
            parts.append(f'row {row}')
        super().__init__(f'{", ".join(parts)}: {message}')


class PlanningError(FeedAxisError):
    """A program the planner cannot turn into motion (e.g. a move on an axis the machine lacks)."""

    def __init__(self, message: str, *, file: str = '<program>', line: int = 0):
        self.file = file
        self.line = line
        self.reason = message
        super().__init__(f'{file}:{line}: {message}' if line else f'{file}: {message}')
