"""SIGTERM and SIGINT as an exception, so that ``finally`` blocks remove partial outputs.

The command line wraps every subcommand in :func:`terminate_on_signals`; the staged writers
of :mod:`.outputs` then remove their temporaries when a signal arrives. SIGKILL cannot be
caught: what it may leave is described in :mod:`.outputs`.
"""
from __future__ import annotations

from collections.abc import Iterator
import contextlib
import signal
import threading

__all__ = ['Terminated', 'terminate_on_signals']


class Terminated(KeyboardInterrupt):
    """Raised in the main thread on SIGTERM or SIGINT so that cleanup code runs.

    A ``KeyboardInterrupt`` so that ``except Exception`` blocks do not swallow it.

    Parameters
    ----------
    signum
        The signal received.
    """

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        """The shell's convention: 128 + signal number."""
        return 128 + self.signum


@contextlib.contextmanager
def terminate_on_signals(signals: tuple[int, ...] = (signal.SIGTERM, signal.SIGINT)
                         ) -> Iterator[None]:
    """Raise :class:`Terminated` in the main thread on SIGTERM or SIGINT while the block runs.

    ``finally`` blocks and the staged writers of :mod:`.outputs` then remove their
    temporaries. Only the first signal raises: a second one while cleanup runs is ignored, so
    that cleanup is not cut short. The previous handlers are restored on exit. Only in the
    main thread (signals are delivered there); elsewhere a no-op.

    Parameters
    ----------
    signals
        The signals turned into :class:`Terminated`.

    Yields
    ------
    None
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    state = {'raised': False}

    def handler(signum, frame):
        if state['raised']:
            return
        state['raised'] = True
        raise Terminated(signum)

    previous = {s: signal.signal(s, handler) for s in signals}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
