"""The C heap of a worker process: keep freed memory for the next allocation.

The energy by phase makes numpy arrays of a few MB per window and frees them again, many
times a second. glibc serves blocks above its mmap threshold with ``mmap`` and returns them
with ``munmap`` when freed, so every such array costs its pages' faults again: in a sweep
bundle (:mod:`.sim.bundle`) that was a third of the CPU time (10 load variants of a 1-hour
contour: 10.7 s, 7.0 s with the memory kept). :func:`keep_freed_memory` raises the mmap
threshold and the trim threshold (``mallopt``) so that freed blocks stay in the heap for
the next array; the process keeps at most ``trim_bytes`` it does not use.

Linux with glibc only; elsewhere (or where ``mallopt`` is missing) nothing changes.
"""
from __future__ import annotations

import ctypes
import sys

__all__ = ['keep_freed_memory']

_M_TRIM_THRESHOLD = -1          # mallopt parameters of glibc's <malloc.h>
_M_MMAP_THRESHOLD = -3
_applied: bool | None = None


def keep_freed_memory(*, mmap_bytes: int = 32 << 20, trim_bytes: int = 64 << 20) -> bool:
    """Serve blocks up to ``mmap_bytes`` from the heap and keep up to ``trim_bytes`` of freed
    heap; True when glibc took both settings (once per process: later calls return the
    first answer)."""
    global _applied
    if _applied is not None:
        return _applied
    _applied = False
    if not sys.platform.startswith('linux'):
        return False
    try:
        mallopt = ctypes.CDLL('libc.so.6').mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    _applied = (mallopt(_M_MMAP_THRESHOLD, int(mmap_bytes)) == 1
                and mallopt(_M_TRIM_THRESHOLD, int(trim_bytes)) == 1)
    return _applied
