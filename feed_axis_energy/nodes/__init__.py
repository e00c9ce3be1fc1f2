"""Thin rclpy shells around the core (one module per executable).

A node process started by ``feed-axis-energy launch`` (``FAE_PARENT_PID`` in its environment)
can be told to stop while it is still importing rclpy, numpy and rosbags, which takes seconds
on a busy machine: until :func:`runner.run` installs its own handlers, SIGINT and SIGTERM end
the process quietly with code 128 + signal (it has created nothing yet) instead of a
``KeyboardInterrupt`` traceback from the middle of an import. Other processes that import this
package (tests, ``ros2 run``) keep their signal handling.

Without rclpy (``pip install .`` without the ``ros`` extra and no ROS 2 sourced), a node
executable prints what to install and exits 1 instead of an import traceback; an import of
the package from other code raises :class:`ImportError` with the same text.
"""
import importlib.util
import os
from pathlib import Path
import signal
import sys
import threading

EXECUTABLES = ('gcode_trajectory', 'axis_dynamics', 'energy_estimator', 'measured_replay',
               'mcap_recorder', 'opcua_bridge')
NO_RCLPY = ('the feed_axis_energy nodes need rclpy and the ROS 2 message packages: source a '
            "ROS 2 installation, or pip install 'feed_axis_energy[ros]' (the ros-* wheels; "
            'pins in constraints.txt)')


def _quiet_exit(signum, frame) -> None:
    os._exit(128 + signum)


if os.environ.get('FAE_PARENT_PID') and threading.current_thread() is threading.main_thread():
    for _sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(_sig, _quiet_exit)


def _node_executable() -> bool:
    """This process is a node: its console script, or ``python -m feed_axis_energy.nodes.X``."""
    if sys.argv and Path(sys.argv[0]).stem in EXECUTABLES:
        return True
    argv = list(getattr(sys, 'orig_argv', []))
    return '-m' in argv[:-1] and argv[argv.index('-m') + 1].startswith(__name__ + '.')


if importlib.util.find_spec('rclpy') is None:
    if _node_executable():
        print(f'error: {NO_RCLPY}', file=sys.stderr)
        sys.exit(1)
    raise ImportError(NO_RCLPY)
