"""A fixed glibc mmap threshold, so that large short-lived arrays do not grow the heap for good.

glibc serves an allocation above its mmap threshold (128 KiB at start) with ``mmap`` and gives
it back with ``munmap``. Its threshold is *dynamic*: freeing such a block raises the threshold to
the block's size, so that later blocks of that size come from the heap (``brk``), which is
trimmed only above twice the threshold. The planner's chunks are arrays of 1.5 MiB (65 536
samples x 3 axes x 8 bytes, three of them per chunk), made and dropped all through a job: in
``gcode_trajectory`` the heap grew by 15-18 MiB during a 10-minute job and stayed there
(README, "Benchmarks"; tracemalloc: Python's own allocations flat). Setting the threshold once
(``mallopt(M_MMAP_THRESHOLD, ...)``) switches the dynamic rule off: every large array is
mapped and unmapped again, one system call per 1.5 MiB array.
"""
from __future__ import annotations

import ctypes
import os

__all__ = ['DEFAULT_MMAP_THRESHOLD', 'fix_mmap_threshold']

DEFAULT_MMAP_THRESHOLD = 128 * 1024
"""glibc's own starting threshold [bytes]."""
_M_MMAP_THRESHOLD = -3     # malloc.h
_ENV = 'MALLOC_MMAP_THRESHOLD_'


def fix_mmap_threshold(nbytes: int = DEFAULT_MMAP_THRESHOLD) -> bool:
    """Fix glibc's mmap threshold at ``nbytes``; True if set.

    False without glibc's ``mallopt`` (another C library), when it refuses, or when the
    environment sets ``MALLOC_MMAP_THRESHOLD_`` (the user's choice stands).
    """
    if _ENV in os.environ:
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, int(nbytes)) == 1)
