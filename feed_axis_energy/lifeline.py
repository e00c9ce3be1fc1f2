"""Child processes that die with their parent (Linux ``prctl(PR_SET_PDEATHSIG)``).

``feed-axis-energy launch`` starts every node with :func:`preexec` (run in the child between
fork and exec) and puts the parent's pid in the environment variable :data:`ENV`; the node's
start-up (:func:`feed_axis_energy.nodes.runner.run`) calls :func:`arm_from_env` again, which
also catches a parent that died before the child armed the signal. When the launcher dies,
even by SIGKILL, the kernel sends every node SIGTERM, and the nodes shut down as on Ctrl-C
(the recorder writes its last chunk).

The signal is tied to the *thread* that forked the child: the launcher starts its children
from its main thread, which lives as long as the launcher. Elsewhere than Linux these
functions do nothing and return ``False``.
"""
from __future__ import annotations

import ctypes
import os
from pathlib import Path
import signal
import sys
from typing import Callable

__all__ = ['ENV', 'PR_SET_PDEATHSIG', 'set_parent_death_signal', 'preexec', 'arm_from_env',
           'parent_gone', 'child_processes', 'alive']

ENV = 'FAE_PARENT_PID'
PR_SET_PDEATHSIG = 1   # <linux/prctl.h>


def _prctl():
    if not sys.platform.startswith('linux'):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.prctl
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong,
                   ctypes.c_ulong]
    fn.restype = ctypes.c_int
    return fn


def set_parent_death_signal(sig: int = signal.SIGTERM) -> bool:
    """Ask the kernel to send ``sig`` to this process when its parent thread dies."""
    fn = _prctl()
    return fn is not None and fn(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0


def preexec(parent_pid: int, *, sig: int = signal.SIGTERM) -> Callable[[], None]:
    """A ``subprocess.Popen(preexec_fn=...)`` that arms the parent-death signal in the child.

    The libc function is looked up here, in the parent, so that the child (between fork and
    exec) only makes the system call. If the parent died before the call, the child exits at
    once instead of running as an orphan. Start every child before starting threads in the
    parent: ``preexec_fn`` is not safe while other threads run.
    """
    fn = _prctl()

    def _arm() -> None:
        if fn is not None:
            fn(PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
        if os.getppid() != parent_pid:
            os._exit(1)
    return _arm


def arm_from_env(*, sig: int = signal.SIGTERM) -> bool | None:
    """Arm the parent-death signal if :data:`ENV` names the expected parent.

    Returns ``None`` if the variable is not set (a node started by hand, ``ros2 run``: its
    life is not tied to the shell's), ``True`` when armed and the parent is alive, ``False``
    when the parent is already gone (the caller should stop).
    """
    text = os.environ.get(ENV, '')
    if not text.isdigit():
        return None
    set_parent_death_signal(sig)
    return os.getppid() == int(text)


def parent_gone() -> bool:
    """True if :data:`ENV` names a parent that is no longer this process's parent."""
    text = os.environ.get(ENV, '')
    return text.isdigit() and os.getppid() != int(text)


# -- watching from outside (tests, bench/fault_injection.py): who outlives the launcher ------
def child_processes(pid: int) -> list[tuple[int, str]]:
    """``[(pid, cmdline)]`` of the processes whose parent is ``pid`` (Linux ``/proc``)."""
    kids = []
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / 'stat').read_text()
                cmd = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode()
            except OSError:
                continue
            if int(stat.rsplit(')', 1)[1].split()[1]) == pid:
                kids.append((int(entry.name), cmd))
    return kids


def alive(pid: int) -> bool:
    """Running: a zombie waiting for its new parent to reap it counts as dead."""
    try:
        state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
    except OSError:
        return False
    return state != 'Z'
