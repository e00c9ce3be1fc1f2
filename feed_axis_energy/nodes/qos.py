"""QoS profiles of the graph (see docs/nodes.md).

* Streams (``setpoints``, ``axis_state``, ``power``, ``measured/*``, acknowledgements):
  reliable, keep last ``depth``, volatile. No sample is lost because the producer never has
  more than ``flow_window`` batches in flight (< ``depth``), see :class:`core.graph.FlowWindow`.
* Data published once (``block_energy``, ``program/lines``, ``program/end``): reliable,
  keep last 1, transient local, so a late subscriber (a recorder started afterwards) gets it.
* ``/clock``: reliable, keep last 1, volatile (only the newest time matters).
"""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['STREAM_DEPTH', 'stream_qos', 'latched_qos', 'clock_qos']

STREAM_DEPTH = 100


def stream_qos(depth: int = STREAM_DEPTH) -> QoSProfile:
    """Reliable, keep-last ``depth``, volatile: for batched time series."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def latched_qos(depth: int = 1) -> QoSProfile:
    """Reliable, keep-last, transient local: for data published once."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def clock_qos() -> QoSProfile:
    """``/clock``: reliable, keep last 1."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
