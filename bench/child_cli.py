"""One ``python -m feed_axis_energy`` command as a child process, timed with its own rusage.

The rate benchmarks (``bench_compare_rate.py``, ``bench_analyze_rate.py``) measure a command
end to end (process start included): wall time, CPU time and peak RSS of the child alone
(``os.wait4``'s ``ru_maxrss``), and its peak *anonymous* memory (``RssAnon`` of
``/proc/PID/status``, read every 50 ms while it runs: what must fit in RAM; ``ru_maxrss``
also counts the pages of memory-mapped files, which the kernel may drop and read again), with
a deadline after which the child is killed. Scripts
import it as ``from child_cli import run_cli`` (``bench/`` is ``sys.path[0]`` when a script
of it runs).
"""
from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

__all__ = ['ChildRun', 'run_cli']

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class ChildRun:
    """What a child run left: wall and CPU time [s], peak RSS and peak anonymous RSS
    [bytes] (the latter sampled, 0 where ``/proc`` is not readable), exit code, output."""

    wall_s: float
    cpu_s: float
    peak_rss_bytes: int
    peak_anon_bytes: int
    code: int
    stdout: bytes
    stderr: str


def run_cli(args: list[str], *, timeout_s: float) -> ChildRun:
    """``python -m feed_axis_energy ARGS`` from the repository (its code on ``PYTHONPATH``);
    killed after ``timeout_s`` (its wall time then exceeds it)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        proc = subprocess.Popen([sys.executable, '-m', 'feed_axis_energy', *args], cwd=ROOT,
                                env=env, stdout=out, stderr=err)
        deadline = t0 + timeout_s
        anon = 0
        while True:
            anon = max(anon, _anon_bytes(proc.pid))
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                proc.kill()
                _, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        wall = time.perf_counter() - t0
        out.seek(0)
        err.seek(0)
        text, errors = out.read(), err.read().decode(errors='replace')
    return ChildRun(wall_s=wall, cpu_s=usage.ru_utime + usage.ru_stime,
                    peak_rss_bytes=usage.ru_maxrss * 1024, peak_anon_bytes=anon,
                    code=os.waitstatus_to_exitcode(status), stdout=text, stderr=errors)


def _anon_bytes(pid: int) -> int:
    """``RssAnon`` of a running process [bytes]; 0 when it cannot be read."""
    try:
        with open(f'/proc/{pid}/status', encoding='ascii') as fh:
            for line in fh:
                if line.startswith('RssAnon:'):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 0
