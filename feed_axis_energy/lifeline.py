"""Child processes that die with their parent (Linux ``prctl(PR_SET_PDEATHSIG)``).

``feed-axis-energy launch`` starts every node with :func:`preexec` (run in the child between
fork and exec) and puts the parent's pid in the environment variable :data:`ENV`; the node's
start-up (:func:`feed_axis_energy.nodes.runner.run`) calls :func:`arm_from_env` again, which
also catches a parent that died before the child armed the signal. When the launcher dies,
even by SIGKILL, the kernel sends every node SIGTERM, and the nodes shut down as on Ctrl-C
(the recorder writes its last chunk).

A node whose orderly stop does not end (a call that blocks in a DDS library, a close that
hangs) must still not outlive the launcher: :func:`watch_parent` gives it a bounded grace
after the parent has gone, then dumps every thread's Python stack to stderr and ends the
process (:func:`faulthandler.dump_traceback_later`, whose watchdog is a C thread that needs
no interpreter lock). What a recorder loses then is what it had not flushed: its bag stays
readable (:mod:`feed_axis_energy.record.crashsafe`).

The signal is tied to the *thread* that forked the child: the launcher starts its children
from its main thread, which lives as long as the launcher. Elsewhere than Linux these
functions do nothing and return ``False``.
"""
from __future__ import annotations

import ctypes
import faulthandler
import os
from pathlib import Path
import signal
import sys
import threading
from typing import Callable

__all__ = ['ENV', 'PR_SET_PDEATHSIG', 'set_parent_death_signal', 'preexec', 'arm_from_env',
           'parent_gone', 'watch_parent', 'EXIT_GRACE_S', 'child_processes', 'alive']

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


EXIT_GRACE_S = 1.0
"""How long a node may take to stop after its launcher has gone [s], then it is ended: the
test of the launcher's death allows 2 s (test/nodes/test_launcher_death.py)."""


def watch_parent(*, grace_s: float = EXIT_GRACE_S, poll_s: float = 0.05,
                 parent_pid: int | None = None) -> threading.Thread | None:
    """End this process ``grace_s`` after its parent has gone, whatever it is doing then.

    A daemon thread compares the parent pid every ``poll_s``; once the parent differs
    (``parent_pid``, by default :data:`ENV`'s), it arms
    :func:`faulthandler.dump_traceback_later` with ``exit=True``: if the process still runs
    ``grace_s`` later, every thread's stack goes to stderr and the process exits with code 1.
    An orderly stop (the parent-death SIGTERM) normally ends the process well before.
    Returns the thread, or ``None`` when there is no parent to watch (:data:`ENV` unset).
    """
    if parent_pid is None:
        text = os.environ.get(ENV, '')
        if not text.isdigit():
            return None
        parent_pid = int(text)
    expected = parent_pid

    def _watch() -> None:
        stop = threading.Event()
        while os.getppid() == expected:
            stop.wait(poll_s)
        faulthandler.dump_traceback_later(grace_s, exit=True)

    thread = threading.Thread(target=_watch, name='parent-watch', daemon=True)
    thread.start()
    return thread


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
