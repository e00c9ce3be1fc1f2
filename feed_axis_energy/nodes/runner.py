"""Start-up, spinning and shutdown shared by every node executable.

A node class raises :class:`StartupError` (or a core ``FeedAxisError``) from ``__init__`` when
its parameters are bad; :func:`run` logs one clear line and returns exit code 1 instead of a
traceback. A node asks to stop by setting ``exit_code``. A node with a ``poll(timeout_s)``
method takes its own messages (``mcap_recorder``): the loop alternates ``poll`` and one
non-blocking executor turn. SIGINT/SIGTERM set a flag (no exception in the middle of a bag
flush) and shut down cleanly (exit 0) after the node's ``close()`` (the recorder flushes its
bag there). A node started by ``feed-axis-energy launch`` (environment variable
``FAE_PARENT_PID``) gets SIGTERM when the launcher dies, even by SIGKILL
(:mod:`feed_axis_energy.lifeline`), and shuts down the same way.
"""
from __future__ import annotations

import inspect
import math
import os
import signal
import sys
from dataclasses import dataclass
from typing import Callable

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult

from feed_axis_energy import lifeline
from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.paths import config_dir

__all__ = ['StartupError', 'run', 'make_executor', 'declare', 'steady_timer', 'STARTUP_ERRORS',
           'LiveParameter', 'guard_parameters']


class StartupError(RuntimeError):
    """A node cannot start (bad parameter, missing file); the message says what and where."""


# Longest wait of one spin turn: how late a stop request (signal, parent death) is seen.
_TURN_S = 0.05

STARTUP_ERRORS = (StartupError, FeedAxisError, OSError, ParameterException, KeyError)


def declare(node, name: str, default, description: str):
    """Declare a parameter with a description and return its value.

    The name is remembered (``node._fae_declared``): :func:`guard_parameters` refuses run-time
    changes of these unless they are declared live.
    """
    value = node.declare_parameter(
        name, default, ParameterDescriptor(description=description)).value
    if not hasattr(node, '_fae_declared'):
        node._fae_declared = []
    node._fae_declared.append(name)
    return value


@dataclass(frozen=True)
class LiveParameter:
    """A parameter that may change while the node runs.

    Attributes
    ----------
    check
        Returns why a value is refused, or ``None`` to accept it.
    apply
        Takes the accepted value into use (called after rclpy has stored it).
    """

    check: Callable[[object], str | None]
    apply: Callable[[object], None]


def guard_parameters(node, live: dict[str, LiveParameter]) -> None:
    """Validate and apply run-time changes of ``live`` parameters; refuse the node's others.

    Call at the end of the node's ``__init__`` (after every :func:`declare`). A change of a
    parameter declared with :func:`declare` but not in ``live`` is refused with the reason
    that the node reads it at start-up; parameters the node did not declare itself
    (``use_sim_time``, QoS overrides ...) are left to rclpy.
    """
    static = set(getattr(node, '_fae_declared', ())) - set(live)

    def on_set(params) -> SetParametersResult:
        for param in params:
            if param.name in static:
                return SetParametersResult(successful=False, reason=(
                    f'{param.name} is read at start-up only; restart the node to change it '
                    f'(run-time changes: {", ".join(sorted(live)) or "none"})'))
            rule = live.get(param.name)
            problem = rule.check(param.value) if rule is not None else None
            if problem:
                return SetParametersResult(successful=False,
                                           reason=f'{param.name}: {problem}')
        return SetParametersResult(successful=True)

    def after_set(params) -> None:
        for param in params:
            rule = live.get(param.name)
            if rule is not None:
                rule.apply(param.value)
                node.get_logger().info(f'parameter {param.name} set to {param.value!r}')

    node.add_on_set_parameters_callback(on_set)
    node.add_post_set_parameters_callback(after_set)


def check_mass(value) -> str | None:
    """``None`` for a finite mass >= 0 kg, else why not."""
    if not isinstance(value, float) or not math.isfinite(value) or value < 0.0:
        return f'must be a finite mass >= 0 kg, got {value!r}'
    return None


def check_positive(value) -> str | None:
    """``None`` for a finite number > 0, else why not."""
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        return f'must be a finite number > 0, got {value!r}'
    return None


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


def node_help(factory: Callable[[], object], *, name: str) -> str:
    """Usage, the node module's docstring and its parameters from ``config/graph.yaml``."""
    module = sys.modules.get(getattr(factory, '__module__', ''), None)
    doc = inspect.cleandoc(module.__doc__ or '') if module is not None else ''
    params = []
    graph = config_dir() / 'graph.yaml'
    if graph.is_file():
        lines = graph.read_text(encoding='utf-8').splitlines()
        inside = False
        for line in lines:
            if line and not line.startswith(' '):
                inside = line.startswith(f'{name}:')
                continue
            if inside and line.startswith('    ') and not line.strip().startswith('#'):
                params.append('  ' + line.strip())
    text = [f'usage: ros2 run feed_axis_energy {name} [--ros-args -p NAME:=VALUE ...]',
            f'   or: python -m feed_axis_energy.nodes.{name} [--ros-args ...]', '', doc]
    if params:
        text += ['', f'parameters (defaults from {graph}):'] + params
    text += ['', 'Topics, QoS and flow control: docs/nodes.md. Exit code 1 on bad parameters.']
    return '\n'.join(text)


def run(factory: Callable[[], object], args: list[str] | None, *, name: str) -> int:
    """Create the node with ``factory`` and spin it until it exits; returns the exit code.

    ``-h``/``--help`` before any ``--ros-args`` prints :func:`node_help` and returns 0.
    """
    argv = list(sys.argv[1:] if args is None else args)
    own = argv[:argv.index('--ros-args')] if '--ros-args' in argv else argv
    if '-h' in own or '--help' in own:
        print(node_help(factory, name=name))
        return 0
    # SIGINT/SIGTERM only set a flag that the spin loop checks (every <= 0.05 s): an exception
    # raised wherever the signal lands (e.g. in the middle of a bag flush) could lose data.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, frame: stop.append(signum))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    armed = lifeline.arm_from_env()
    if armed is False:
        # The launcher died before this node armed its parent-death signal: do not run on
        # as an orphan (the node still starts and closes, so a recorder leaves a valid bag).
        stop.append(signal.SIGTERM)
    elif armed:
        # however the stop goes, the node ends at most EXIT_GRACE_S after its launcher
        lifeline.watch_parent()
    try:
        code = _spin(factory, name=name, stop=stop)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if lifeline.parent_gone():
        _exit_now(code)
    return code


def _exit_now(code: int) -> None:
    """The launcher died (parent-death signal) and the node's own data is safe: skip the
    executor's, rclpy's and the interpreter's teardown (each a second or more on a busy
    machine) so that no node outlives the launcher by more than moments. Nobody reads our
    output now; the DDS peers time the participant out."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


def _spin(factory: Callable[[], object], *, name: str, stop: list[int]) -> int:
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
    poll = getattr(node, 'poll', None)
    try:
        while code is None and rclpy.ok() and not stop:
            if poll is None:
                executor.spin_once(timeout_sec=_TURN_S)
            else:
                # The node takes its own messages in poll (which waits at most a few ms);
                # the executor only runs timers, services and the rest in between.
                poll(_TURN_S)
                executor.spin_once(timeout_sec=0.0)
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
        if lifeline.parent_gone():
            _exit_now(int(code or 0))       # the bag is closed: nothing else to keep
        executor.remove_node(node)
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()
    return int(code or 0)
