"""Start-up, spinning and shutdown shared by every node executable.

A node class raises :class:`StartupError` (or a core ``FeedAxisError``) from ``__init__`` when
its parameters are bad; :func:`run` logs one clear line and returns exit code 1 instead of a
traceback. A node asks to stop by setting ``exit_code``. SIGINT/SIGTERM shut down cleanly
(exit 0) after the node's ``close()`` (the recorder flushes its bag there).
"""
from __future__ import annotations

from typing import Callable

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rcl_interfaces.msg import ParameterDescriptor

from feed_axis_energy.core.errors import FeedAxisError

__all__ = ['StartupError', 'run', 'make_executor', 'declare', 'steady_timer', 'STARTUP_ERRORS']


class StartupError(RuntimeError):
    """A node cannot start (bad parameter, missing file); the message says what and where."""


STARTUP_ERRORS = (StartupError, FeedAxisError, OSError, ParameterException, KeyError)


def declare(node, name: str, default, description: str):
    """Declare a parameter with a description and return its value."""
    value = node.declare_parameter(
        name, default, ParameterDescriptor(description=description)).value
    return value


def steady_timer(node, period_s: float, callback):
    """A timer on the steady clock: it keeps running with ``use_sim_time`` after /clock stops."""
    from rclpy.clock import Clock, ClockType
    return node.create_timer(period_s, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))


def make_executor(*, context=None):
    """rclpy's C++ ``EventsExecutor`` where the wheels have it, else ``SingleThreadedExecutor``.

    The events executor dispatches a ready message with a few microseconds of overhead where
    the Python wait-set executor spends a few hundred (measured in docs/nodes.md); that is what
    lets the recorder take tens of thousands of messages per second.
    """
    try:
        from rclpy.experimental.events_executor import EventsExecutor
    except ImportError:
        return SingleThreadedExecutor(context=context)
    return EventsExecutor(context=context)


def run(factory: Callable[[], object], args: list[str] | None, *, name: str) -> int:
    """Create the node with ``factory`` and spin it until it exits; returns the exit code."""
    rclpy.init(args=args)
    logger = rclpy.logging.get_logger(name)
    try:
        node = factory()
    except STARTUP_ERRORS as err:
        logger.error(f'cannot start: {err}')
        rclpy.try_shutdown()
        return 1
    code = getattr(node, 'exit_code', None)
    executor = make_executor()
    executor.add_node(node)
    try:
        while code is None and rclpy.ok():
            executor.spin_once(timeout_sec=0.2)
            code = getattr(node, 'exit_code', None)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 0
    finally:
        try:
            close = getattr(node, 'close', None)
            if close is not None:
                close()
        except Exception as err:  # noqa: B902 - a failed close must still shut down
            logger.error(f'error while closing: {err}')
            code = 1
        executor.remove_node(node)
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()
    return int(code or 0)
