"""Progress indication on stderr for long jobs (quiet for short ones and under ``--quiet``)."""
from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ['Progress']


class Progress:
    """Callable that reports a fraction in [0, 1] of a named stage.

    Nothing is printed during the first ``delay_s`` seconds, so short jobs stay silent;
    after that an updating line on a terminal, or a line per 25 % in a log.
    """

    def __init__(self, label: str, *, enabled: bool = True, delay_s: float = 0.5,
                 stream: TextIO | None = None):
        self.label = label
        self.enabled = enabled
        self.delay_s = delay_s
        self.stream = stream if stream is not None else sys.stderr
        self._t0 = time.monotonic()
        self._last_step = -1
        self._shown = False

    def __call__(self, fraction: float) -> None:
        """Report progress ``fraction`` (0..1)."""
        if not self.enabled or time.monotonic() - self._t0 < self.delay_s:
            return
        tty = self.stream.isatty()
        # An updating line on a terminal; a line per quarter in logs, which keep every line.
        per = 10 if tty else 4
        step = int(max(0.0, min(1.0, fraction)) * per)
        if step == self._last_step:
            return
        self._last_step = step
        end = '' if tty and step < per else '\n'
        prefix = '\r' if tty else ''
        self.stream.write(f'{prefix}[{self.label}] {step * 100 // per:3d} %{end}')
        self.stream.flush()
        self._shown = True

    def done(self) -> None:
        """Finish the line if anything was shown."""
        if self._shown:
            self(1.0)
