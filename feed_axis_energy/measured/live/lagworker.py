"""Where the live comparison's lag estimates run: at once, or on one worker thread.

A lag estimate (``estimate_offset`` on up to ``ring_s`` of both streams) costs tens to
hundreds of milliseconds; run in the thread that delivers the samples, it holds them up for
as long. :class:`LiveComparison <.compare.LiveComparison>` therefore hands each estimate over
as a :class:`LagRequest` (copies of the summed streams: the worker shares no state with the
comparison) and takes the finished :class:`LagOutcome` back on a later sample, in its own
thread. Two runners:

* :class:`InlineLag` runs each request at once in the caller's thread (no thread: the
  default of the core, so that the core is tested without threads and its results are the
  same as they always were);
* :class:`ThreadedLag` runs requests on one worker thread, one at a time: while one runs,
  the newest request waits and a newer one replaces it (latest data wins; ``superseded``
  counts those replaced); of the finished outcomes only the newest is kept for the
  comparison to take. Memory: one running and one waiting request, one outcome.

The estimate itself is :func:`estimate_lag`, a pure function; a runner takes another (a test's
estimator that blocks on an event, say) through ``estimate``.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import threading
from typing import Protocol

import numpy as np

from ...errors import DataError
from ..align import estimate_offset, OffsetResult

__all__ = ['estimate_lag', 'InlineLag', 'LagOutcome', 'LagRequest', 'LagRunner',
           'ThreadedLag']


@dataclass(frozen=True)
class LagRequest:
    """One lag estimate to make: the summed measured and predicted power, and the options.

    Attributes
    ----------
    seq
        The requester's number for it (increasing).
    t_meas, p_meas, t_pred, p_pred
        Times [s] and summed power [W] of both streams (the runner's own copies).
    max_lag_s, window_s, stamp, min_correlation
        ``estimate_offset``'s options.
    """

    seq: int
    t_meas: np.ndarray
    p_meas: np.ndarray
    t_pred: np.ndarray
    p_pred: np.ndarray
    max_lag_s: float
    window_s: float
    stamp: str
    min_correlation: float


@dataclass(frozen=True)
class LagOutcome:
    """A finished estimate: ``found`` (None when it failed, then ``reason`` says why)."""

    seq: int
    found: OffsetResult | None
    reason: str = ''


Estimator = Callable[[LagRequest], LagOutcome]


def estimate_lag(request: LagRequest) -> LagOutcome:
    """``estimate_offset`` on the request's streams; a :class:`DataError` becomes a reason."""
    try:
        found = estimate_offset(request.t_meas, request.p_meas, request.t_pred, request.p_pred,
                                max_lag_s=request.max_lag_s, window_s=request.window_s,
                                stamp=request.stamp, min_correlation=request.min_correlation)
    except DataError as err:
        return LagOutcome(request.seq, None, err.reason)
    return LagOutcome(request.seq, found)


class LagRunner(Protocol):
    """What :class:`~.compare.LiveComparison` needs of a runner."""

    submitted: int
    superseded: int

    def submit(self, request: LagRequest) -> None:
        """Start (or queue) an estimate; never waits for one."""

    def take(self) -> LagOutcome | None:
        """The newest finished outcome not taken yet (None if none)."""

    def run_now(self, request: LagRequest) -> LagOutcome:
        """An estimate in the caller's thread (the last one, at the end of a stream)."""

    def close(self) -> None:
        """No more requests: outcomes still to come are dropped; never waits."""


class InlineLag:
    """Runs each request at once, in the caller's thread (module docstring)."""

    def __init__(self, estimate: Estimator = estimate_lag):
        self._estimate = estimate
        self._out: LagOutcome | None = None
        self.submitted = 0
        self.superseded = 0

    def submit(self, request: LagRequest) -> None:
        """Run the estimate now; :meth:`take` returns it."""
        self.submitted += 1
        self._out = self._estimate(request)

    def take(self) -> LagOutcome | None:
        """The outcome of the last :meth:`submit`, once."""
        out, self._out = self._out, None
        return out

    def run_now(self, request: LagRequest) -> LagOutcome:
        """The estimate, in the caller's thread."""
        return self._estimate(request)

    def close(self) -> None:
        """Nothing to stop."""
        self._out = None


class ThreadedLag:
    """One worker thread, one estimate at a time, the newest request wins (module docstring).

    The thread starts with the first request and ends after :meth:`close` (it finishes the
    estimate it is running, whose outcome is dropped); it is a daemon, so a process never
    waits for it on exit.
    """

    def __init__(self, estimate: Estimator = estimate_lag, *, name: str = 'lag-estimate'):
        self._estimate = estimate
        self._name = name
        self._cond = threading.Condition()
        self._waiting: LagRequest | None = None
        self._out: LagOutcome | None = None
        self._running = False
        self._closed = False
        self._thread: threading.Thread | None = None
        self.submitted = 0
        self.superseded = 0
        self.finished = 0
        self.failed = 0

    def submit(self, request: LagRequest) -> None:
        """Queue the request (replacing one still waiting); never waits for the worker."""
        with self._cond:
            if self._closed:
                return
            self.submitted += 1
            if self._waiting is not None:
                self.superseded += 1
            self._waiting = request
            if self._thread is None:
                self._thread = threading.Thread(target=self._work, name=self._name,
                                                daemon=True)
                self._thread.start()
            self._cond.notify_all()

    def take(self) -> LagOutcome | None:
        """The newest finished outcome not taken yet (None if none)."""
        with self._cond:
            out, self._out = self._out, None
            return out

    @property
    def busy(self) -> bool:
        """Whether an estimate runs or waits."""
        with self._cond:
            return self._running or self._waiting is not None

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Wait until no estimate runs or waits (tests, benches); False on timeout."""
        with self._cond:
            return self._cond.wait_for(lambda: not (self._running or self._waiting),
                                       timeout=timeout)

    def run_now(self, request: LagRequest) -> LagOutcome:
        """The estimate, in the caller's thread (the worker may be running another)."""
        return self._estimate(request)

    def close(self) -> None:
        """Stop taking requests; the worker ends after its current estimate; never waits."""
        with self._cond:
            self._closed = True
            self._waiting = None
            self._out = None
            self._cond.notify_all()

    def _work(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._closed or self._waiting is not None)
                if self._closed:
                    self._running = False
                    self._cond.notify_all()
                    return
                request, self._waiting = self._waiting, None
                if request is None:
                    continue
                self._running = True
            try:
                out = self._estimate(request)
            except Exception as err:    # noqa: BLE001 - a worker must outlive a bad estimate
                out = LagOutcome(request.seq, None, f'estimate failed: {err}')
                self.failed += 1
            with self._cond:
                self._running = False
                self.finished += 1
                if not self._closed:
                    self._out = out
                self._cond.notify_all()
