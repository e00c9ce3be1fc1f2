"""gcode_trajectory fixes glibc's mmap threshold: a large array freed and made again is mapped."""
import os
from pathlib import Path
import platform
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]

glibc = pytest.mark.skipif(platform.system() != 'Linux' or platform.libc_ver()[0] != 'glibc',
                           reason='mallopt/mallinfo2 are glibc')

CHILD = r'''
import ctypes, sys
import numpy as np
from feed_axis_energy.heap import fix_mmap_threshold

class MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ('arena', 'ordblks', 'smblks', 'hblks', 'hblkhd',
                                               'usmblks', 'fsmblks', 'uordblks', 'fordblks',
                                               'keepcost')]

libc = ctypes.CDLL(None)
libc.mallinfo2.restype = MallInfo2
fixed = fix_mmap_threshold() if sys.argv[1] == 'fixed' else None
n = 65536 * 3                       # one of the planner's chunk arrays: 1.5 MiB
a = np.ones(n)
del a                               # glibc's dynamic rule raises its threshold here
before = libc.mallinfo2().hblks
b = np.ones(n)
print(fixed, libc.mallinfo2().hblks - before)
'''


def _child(mode, **env):
    full = {k: v for k, v in os.environ.items() if k != 'MALLOC_MMAP_THRESHOLD_'}
    full.update(PYTHONPATH=str(ROOT), **env)
    proc = subprocess.run([sys.executable, '-c', CHILD, mode], env=full, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    fixed, mapped = proc.stdout.split()
    return fixed, int(mapped)


@glibc
def test_a_freed_chunk_array_is_mapped_again_only_with_the_fixed_threshold():
    try:
        _child('dynamic')
    except AssertionError as err:
        if 'mallinfo2' in str(err):
            pytest.skip('glibc older than 2.33: no mallinfo2')
        raise
    assert _child('dynamic') == ('None', 0)     # from the heap, which then stays grown
    assert _child('fixed') == ('True', 1)       # mapped, unmapped again when freed


@glibc
def test_the_users_own_threshold_stands():
    fixed, _ = _child('fixed', MALLOC_MMAP_THRESHOLD_='65536')
    assert fixed == 'False'


def test_the_node_fixes_it_before_it_runs():
    source = (ROOT / 'feed_axis_energy' / 'nodes' / 'gcode_trajectory.py').read_text()
    main = source[source.index('def main('):]
    assert main.index('fix_mmap_threshold()') < main.index('run(GcodeTrajectory')
