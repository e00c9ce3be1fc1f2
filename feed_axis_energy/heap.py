"""glibc's heap policy for this package's processes: two opposite needs, one place.

glibc serves an allocation above its mmap threshold (128 KiB at start) with ``mmap`` and gives
it back with ``munmap``. Its threshold is *dynamic*: freeing such a block raises the threshold
to the block's size, so that later blocks of that size come from the heap (``brk``), which is
trimmed only above twice the threshold.

* A **long-running node** must not grow for good: the planner's chunks are arrays of 1.5 MiB
  (65 536 samples x 3 axes x 8 bytes, three of them per chunk), made and dropped all through
  a job; in ``gcode_trajectory`` the heap grew by 15-18 MiB during a 10-minute job and stayed
  there (README, "Benchmarks"; tracemalloc: Python's own allocations flat).
  :func:`fix_mmap_threshold` sets the threshold once, which switches the dynamic rule off:
  every large array is mapped and unmapped again, one system call per array.
* A **batch worker** wants speed: the energy by phase makes arrays of a few MB per window
  and frees them, many times a second, and every mapped array costs its pages' faults again:
  in a sweep bundle (:mod:`.sim.bundle`) a third of the CPU time (10 load variants of a
  1-hour contour: 10.7 s, 7.0 s with the memory kept). :func:`keep_freed_memory` raises the
  mmap threshold and the trim threshold so that freed blocks stay in the heap for the next
  array; the process keeps at most ``trim_bytes`` it does not use.

Both leave the heap alone without glibc's ``mallopt`` (another C library) and where the
environment sets ``MALLOC_MMAP_THRESHOLD_`` (the user's choice stands).
"""
from __future__ import annotations

import ctypes
import os
from typing import Any

__all__ = ['DEFAULT_MMAP_THRESHOLD', 'fix_mmap_threshold', 'keep_freed_memory']

DEFAULT_MMAP_THRESHOLD = 128 * 1024
"""glibc's own starting threshold [bytes]."""
_M_TRIM_THRESHOLD = -1          # mallopt parameters of glibc's <malloc.h>
_M_MMAP_THRESHOLD = -3
_ENV = 'MALLOC_MMAP_THRESHOLD_'
_kept: bool | None = None


def _mallopt() -> Any:
    """glibc's ``mallopt``, or None (another C library, or the user's environment)."""
    if _ENV in os.environ:
        return None
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return None
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return mallopt


def fix_mmap_threshold(nbytes: int = DEFAULT_MMAP_THRESHOLD) -> bool:
    """Fix glibc's mmap threshold at ``nbytes`` (a long-running node); True if set."""
    mallopt = _mallopt()
    return mallopt is not None and bool(mallopt(_M_MMAP_THRESHOLD, int(nbytes)) == 1)


def keep_freed_memory(*, mmap_bytes: int = 32 << 20, trim_bytes: int = 64 << 20) -> bool:
    """Serve blocks up to ``mmap_bytes`` from the heap and keep up to ``trim_bytes`` of freed
    heap (a batch worker); True when glibc took both settings (once per process: later
    calls return the first answer)."""
    global _kept
    if _kept is None:
        mallopt = _mallopt()
        _kept = (mallopt is not None and mallopt(_M_MMAP_THRESHOLD, int(mmap_bytes)) == 1
                 and mallopt(_M_TRIM_THRESHOLD, int(trim_bytes)) == 1)
    return _kept
