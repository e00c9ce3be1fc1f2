"""QoS profiles of the graph (see docs/nodes.md).

* Streams (``setpoints``, ``axis_state``, ``power``, ``measured/*``, acknowledgements):
  reliable, keep last ``depth``, transient local. No sample is lost because the producer never
  has more than ``flow_window`` batches in flight (< ``depth``), see
  :class:`feed_axis_energy.graph.flow.FlowWindow`. Transient local because discovery is not
  symmetric: a reader
  can see its writer matched while the writer has not matched the reader yet, and a batch
  sent in between was never delivered to a volatile reader (the recorder then waited for it
  forever, 1 of 40 fast runs); the writer's history (at most ``flow_window`` unacknowledged
  batches at start) now reaches a reader that matches late. Volatile readers (tools) still
  match these writers.
* Data published once (``block_energy``, ``program/lines``, ``program/end``): reliable,
  keep last 1, transient local, so a late subscriber (a recorder started afterwards) gets it.
  Once per job in a job graph: the per-job recorder reads them with keep last
  :data:`JOB_DEPTH`, so a job's marker is not replaced by the next job's before it is taken.
* ``/clock``: reliable, keep last 1, volatile (only the newest time matters).
* Job commands and replies (``job/command``, ``job/reply``): reliable, keep last 10,
  volatile: a command is meant for the graph running now, never replayed to a node that
  starts later. A client waits until its writer is matched before it sends.
* Job reports between nodes (``job/energy``): reliable, keep last 10, transient local
  (asymmetric discovery, as for the streams); each names its job, stale ones are ignored.
* Live measured drive data (``measured/live``): reliable, keep last :data:`MEASURED_DEPTH`,
  volatile (the contract of the ``opcua_bridge`` writer and the ``measured_live`` reader).
* Job states and results (``job/state``, ``job/result``): reliable, keep last
  :data:`JOB_DEPTH`, transient local, writer and readers alike. Keep last 1 lost states
  under load: a job's ``ended`` was replaced in the writer's history by the next job's
  ``planning`` before a slow reader had it (1 in 3 node-test runs on a loaded machine). A
  late subscriber gets the last :data:`JOB_DEPTH` messages, the newest last.
* Live measured samples from the cell (``measured/live``, published by ``opcua_bridge`` for
  the samples its MQTT bridge accepts): reliable, keep last 1000, volatile: a live stream
  for the consumers running now; 1000 holds seconds of drive data for a slow reader.
"""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['STREAM_DEPTH', 'JOB_DEPTH', 'MEASURED_DEPTH', 'stream_qos', 'latched_qos',
           'clock_qos', 'command_qos', 'report_qos', 'job_qos', 'measured_live_qos']

STREAM_DEPTH = 100
JOB_DEPTH = 16
"""History of ``job/state`` and ``job/result``: every state of a few jobs in a row."""
MEASURED_DEPTH = 1000
"""History of ``measured/live`` (the cell's live drive data, one sample per message)."""


def stream_qos(depth: int = STREAM_DEPTH) -> QoSProfile:
    """Reliable, keep-last ``depth``, transient local: for batched time series."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


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


def command_qos() -> QoSProfile:
    """``job/command``, ``job/reply``: reliable, keep last 10, volatile."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def report_qos() -> QoSProfile:
    """``job/energy``: reliable, keep last 10, transient local."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def job_qos() -> QoSProfile:
    """``job/state``, ``job/result``: reliable, keep last :data:`JOB_DEPTH`, transient local."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=JOB_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def measured_live_qos() -> QoSProfile:
    """``measured/live``: reliable, keep last :data:`MEASURED_DEPTH`, volatile."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=MEASURED_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
