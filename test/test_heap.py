"""The C heap setting of batch workers (feed_axis_energy.heap)."""
import ctypes
import subprocess
import sys


def test_glibc_takes_the_setting_once_per_process():
    # in a child: the setting is process-wide and must not leak into the test session
    code = ('from feed_axis_energy.heap import keep_freed_memory as k\n'
            'import feed_axis_energy.heap as h\n'
            'first = k(); again = k(mmap_bytes=1)\n'
            'print(first, again, h._kept)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True).stdout.split()
    try:
        ctypes.CDLL('libc.so.6').mallopt
        glibc = True
    except (OSError, AttributeError):
        glibc = False
    assert out == [str(glibc)] * 3
