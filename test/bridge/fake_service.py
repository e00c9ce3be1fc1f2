"""A test double of the job service: jobs that "run" by emitting a few power samples.

Not a model of anything: each axis's power is a fixed sine wave, and the energy figures are
integrated from those samples (rectangle rule, the same rule for the live values and the
result, so they agree). It follows the :class:`feed_axis_energy.bridge.JobService` protocol
the way the real job service promises to: refuses a program outside ``program_root``, a
second job while one plans or runs, and reports its states in order.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
import threading
import time
from typing import Any, Callable, Mapping, Sequence

from feed_axis_energy.bridge import AxisPower, Listener, LiveSample, StateChange


class FakeJobService:
    """A job service double: ``samples`` samples, ``period_s`` apart, per job."""

    def __init__(self, program_root: Path, *, axes: Sequence[str] = ('X', 'Y', 'Z'),
                 samples: int = 20, period_s: float = 0.01, keep: int = 5,
                 amplitude_w: float = 100.0):
        self.program_root = Path(program_root).resolve()
        self._axes = tuple(axes)
        self.samples = samples
        self.period_s = period_s
        self.amplitude_w = amplitude_w
        self._keep = keep
        self._lock = threading.Lock()
        self._listeners: list[Listener] = []
        self._state = 'idle'
        self._job = ''
        self._line = 0
        self._progress = 0.0
        self._results: dict[str, dict[str, Any]] = {}
        self._last: dict[str, Any] | None = None
        self._abort = threading.Event()
        self._thread: threading.Thread | None = None
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.hold = threading.Event()
        """Cleared: a job waits in ``running`` before its last sample until it is set."""
        self.hold.set()

    # -- the protocol --------------------------------------------------------------------

    def axes(self) -> Sequence[str]:
        return self._axes

    def subscribe(self, listener: Listener) -> Callable[[], None]:
        with self._lock:
            self._listeners.append(listener)

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)
        return unsubscribe

    def state(self) -> str:
        return self._state

    def active_job(self) -> str:
        return self._job

    def active_line(self) -> int:
        return self._line

    def progress(self) -> float:
        return self._progress

    def last_result(self) -> Mapping[str, Any] | None:
        return self._last

    def result(self, job_id: str) -> Mapping[str, Any] | None:
        return self._results.get(job_id)

    def start_job(self, job_id: str, program: str, load_kg: float) -> tuple[bool, str]:
        self.calls.append(('start_job', (job_id, program, load_kg)))
        with self._lock:
            if self._state in ('planning', 'running'):
                return False, (f'job {self._job!r} is {self._state}; abort it or wait for its '
                               f'end before starting {job_id!r}')
            path = Path(program)
            path = path if path.is_absolute() else self.program_root / path
            real = Path(os.path.realpath(path))
            if not real.is_relative_to(self.program_root):
                return False, f'program {program!r} lies outside the program root'
            if not real.is_file():
                return False, f'program {program!r} is not a file under the program root'
            self._job, self._state, self._line, self._progress = job_id, 'planning', 0, 0.0
            self._abort.clear()
        self._emit(StateChange(job_id=job_id, state='planning', stamp_ns=time.time_ns()))
        self._thread = threading.Thread(target=self._run, args=(job_id, str(real), load_kg),
                                        daemon=True)
        self._thread.start()
        return True, f'job {job_id!r} started'

    def abort_job(self, job_id: str) -> tuple[bool, str]:
        self.calls.append(('abort_job', (job_id,)))
        if self._state not in ('planning', 'running') or job_id != self._job:
            return False, f'job {job_id!r} is not running (state {self._state})'
        self._abort.set()
        self.hold.set()
        return True, f'job {job_id!r} is being aborted'

    # -- test helpers ---------------------------------------------------------------------

    def wait(self, timeout: float = 10.0) -> None:
        """Wait until the running job's thread ends."""
        if self._thread is not None:
            self._thread.join(timeout)

    def inject_result(self, result: dict[str, Any]) -> None:
        """Make ``result`` the last one and announce its end, as a faulty service would."""
        with self._lock:
            self._results[result['job_id']] = result
            self._last = result
            self._state = result['status']
        self._emit(StateChange(job_id=result['job_id'], state=result['status'],
                               stamp_ns=time.time_ns()))

    def power_w(self, axis_index: int, k: int) -> float:
        """The fake's power of axis ``axis_index`` at sample ``k`` [W]."""
        return self.amplitude_w * (axis_index + 1) * math.sin(0.7 * k + axis_index)

    # -- the job --------------------------------------------------------------------------

    def _emit(self, event: Any) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for listener in listeners:
            listener(event)

    def _run(self, job_id: str, program: str, load_kg: float) -> None:
        start = time.monotonic()
        self._state = 'running'
        self._emit(StateChange(job_id=job_id, state='running', stamp_ns=time.time_ns()))
        n_axes = len(self._axes)
        imp = [0.0] * n_axes
        exp = [0.0] * n_axes
        peak = 0.0
        status = 'ended'
        done = 0
        for k in range(self.samples):
            if k == self.samples - 1:
                self.hold.wait()
            if self._abort.is_set():
                status = 'aborted'
                break
            powers = [self.power_w(i, k) for i in range(n_axes)]
            for i, p in enumerate(powers):
                imp[i] += max(p, 0.0) * self.period_s
                exp[i] += max(-p, 0.0) * self.period_s
            total = sum(powers)
            peak = max(peak, total)
            self._line = k + 1
            self._progress = (k + 1) / self.samples
            axes = {a: AxisPower(powers[i], imp[i], exp[i]) for i, a in enumerate(self._axes)}
            self._emit(LiveSample(job_id=job_id, stamp_ns=time.time_ns(), axes=axes,
                                  total=AxisPower(total, sum(imp), sum(exp))))
            done += 1
            time.sleep(self.period_s)
        result = {'job_id': job_id, 'status': status, 'program': program, 'load_kg': load_kg,
                  'energy_j': sum(imp) - sum(exp), 'duration_s': time.monotonic() - start,
                  'peak_power_w': peak, 'samples': done,
                  'energy_by_axis_j': {a: imp[i] - exp[i] for i, a in enumerate(self._axes)}}
        with self._lock:
            self._results[job_id] = result
            while len(self._results) > self._keep:
                self._results.pop(next(iter(self._results)))
            self._last = result
            self._state = status
        self._emit(StateChange(job_id=job_id, state=status, stamp_ns=time.time_ns()))
