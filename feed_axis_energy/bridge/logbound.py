"""Logging that a hostile or broken peer cannot flood: each kind of trouble logged 1, 2, 4, 8...

A bridge meets the same fault again and again (a service that raises on every poll, a client
that sends the same bad message ten thousand times a second). :class:`BoundedLog` counts each
kind and writes the 1st, 2nd, 4th, 8th... occurrence, with the count, so a log shows that it
happens and how often without growing with it.
"""
from __future__ import annotations

import logging

__all__ = ['BoundedLog']


class BoundedLog:
    """Counts troubles by kind and logs the power-of-two occurrences.

    Parameters
    ----------
    logger
        Where the lines go.
    """

    def __init__(self, logger: logging.Logger):
        self._logger = logger
        self.counts: dict[str, int] = {}
        """Occurrences so far, by kind (the kinds a caller uses; bounded by them)."""

    def log(self, level: int, kind: str, message: str, *, exc_info: bool = False) -> None:
        """Count one ``kind``; log ``message`` when the count is a power of two."""
        count = self.counts[kind] = self.counts.get(kind, 0) + 1
        if count & (count - 1) == 0:
            self._logger.log(level, '%s (%s, %d so far)', message, kind, count,
                             exc_info=exc_info)
