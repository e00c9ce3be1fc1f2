"""Thin rclpy shells around the core (one module per executable).

A node process started by ``feed-axis-energy launch`` (``FAE_PARENT_PID`` in its environment)
can be told to stop while it is still importing rclpy, numpy and rosbags, which takes seconds
on a busy machine: until :func:`runner.run` installs its own handlers, SIGINT and SIGTERM end
the process quietly with code 128 + signal (it has created nothing yet) instead of a
``KeyboardInterrupt`` traceback from the middle of an import. Other processes that import this
package (tests, ``ros2 run``) keep their signal handling.
"""
import os
import signal
import threading


def _quiet_exit(signum, frame) -> None:
    os._exit(128 + signum)


if os.environ.get('FAE_PARENT_PID') and threading.current_thread() is threading.main_thread():
    for _sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(_sig, _quiet_exit)
