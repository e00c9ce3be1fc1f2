"""A time series that keeps only its last ``span_s`` seconds, in one contiguous buffer."""
from __future__ import annotations

import numpy as np

__all__ = ['SampleRing']

_SLACK = 0.05   # samples leave in batches, once the span exceeds span_s by this fraction


class SampleRing:
    """Times ``(n,)`` and values ``(n, k)``, the oldest dropped beyond a time span or count.

    One buffer per array, filled at the end and compacted (the kept part moved to the
    front) when the end is reached, so :meth:`arrays` returns views without copying and an
    append costs amortised O(1). The buffer grows by doubling up to ``max_samples``.

    Parameters
    ----------
    k
        Values per sample.
    span_s
        Samples older than the newest minus ``span_s`` [s] leave (in batches, once the
        span held exceeds ``span_s`` by 5 %); ``inf``: only by :meth:`drop_before` or the
        count.
    max_samples
        Most samples held; beyond, the oldest leave whatever their age.
    """

    def __init__(self, k: int, *, span_s: float, max_samples: int):
        self.k = int(k)
        self.span_s = float(span_s)
        self.max_samples = int(max_samples)
        cap = min(1024, self.max_samples)
        self._t = np.empty(cap)
        self._y = np.empty((cap, self.k))
        self._a = 0
        self._b = 0

    @property
    def size(self) -> int:
        """Samples held."""
        return self._b - self._a

    @property
    def last_t(self) -> float | None:
        """Newest time held (None when empty)."""
        return float(self._t[self._b - 1]) if self._b > self._a else None

    def arrays(self, *, since: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Views of the times and values held (only those later than ``since``)."""
        a = self._a
        if since is not None:
            a += int(np.searchsorted(self._t[self._a:self._b], since, side='right'))
        return self._t[a:self._b], self._y[a:self._b]

    def window(self, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
        """Views of the samples within ``[lo, hi]`` plus one more on either side."""
        t = self._t[self._a:self._b]
        i = max(int(np.searchsorted(t, lo, side='left')) - 1, 0)
        j = min(int(np.searchsorted(t, hi, side='right')) + 1, t.size)
        return t[i:j], self._y[self._a + i:self._a + j]

    def extend(self, t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Append samples (later than the newest); return copies of those that left."""
        n = t.size
        if n == 0:
            return None
        if n > self.max_samples:
            t, y = t[-self.max_samples:], y[-self.max_samples:]
            n = t.size
        self._room(n)
        self._t[self._b:self._b + n] = t
        self._y[self._b:self._b + n] = y
        self._b += n
        held = self._t[self._a:self._b]
        if held[-1] - held[0] <= self.span_s * (1.0 + _SLACK) and self.size <= self.max_samples:
            return None
        drop = int(np.searchsorted(held, held[-1] - self.span_s, side='left'))
        drop = max(drop, self.size - self.max_samples)
        if drop <= 0:
            return None
        out = (self._t[self._a:self._a + drop].copy(), self._y[self._a:self._a + drop].copy())
        self._a += drop
        return out

    def drop_before(self, t: float) -> int:
        """Let the samples older than ``t`` go; return how many left."""
        held = self._t[self._a:self._b]
        drop = int(np.searchsorted(held, t, side='left'))
        self._a += drop
        return drop

    def _room(self, n: int) -> None:
        if self._b + n <= self._t.size:
            return
        size = self.size
        cap = self._t.size
        while size + n > cap // 2 and cap < 2 * self.max_samples:
            cap *= 2
        if cap != self._t.size:
            t, y = np.empty(cap), np.empty((cap, self.k))
        else:
            t, y = self._t, self._y
        t[:size] = self._t[self._a:self._b]
        y[:size] = self._y[self._a:self._b]
        self._t, self._y = t, y
        self._a, self._b = 0, size
