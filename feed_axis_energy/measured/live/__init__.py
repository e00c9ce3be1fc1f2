"""Live comparison of measured drive data with the prediction, while the machine runs.

The ROS-free core of the ``measured_live`` node (docs/nodes.md, "measured_live"):
:mod:`.rows` puts single samples together into rows in stamp order and counts late,
duplicate, out-of-order and missing ones; :mod:`.ring` keeps the last seconds of a stream;
:mod:`.compare` aligns the measured power to the prediction with ``compare``'s rules,
incrementally, and keeps energies to date, residuals and the alarm; :mod:`.lagworker` runs its
lag estimates at once or on a worker thread; :mod:`.motion` predicts
from the stream's own kinematics (runs without an NC program); :mod:`.monitor` joins them;
:mod:`.message` is the JSON of the node's topics.
"""
from .compare import BAND_SOURCES, LagState, LiveComparison, LiveSettings
from .lagworker import (estimate_lag, InlineLag, LagOutcome, LagRequest, LagRunner,
                        ThreadedLag)
from .message import (ALARM_KEYS, alarm_text, COMPARISON_KEYS, comparison_text, JobLive,
                      LiveSample, MAX_BATCH, MAX_TEXT_CHARS, parse_job_live, parse_live,
                      REJECTS)
from .monitor import LIVE_QUANTITIES, LiveMonitor, SOURCES
from .motion import KINEMATICS, LiveMotionPredictor
from .ring import SampleRing
from .rows import COUNTER_KEYS, Row, RowAssembler, StreamCounters

__all__ = [
    'ALARM_KEYS', 'alarm_text', 'BAND_SOURCES', 'COMPARISON_KEYS', 'comparison_text',
    'COUNTER_KEYS', 'estimate_lag', 'InlineLag', 'JobLive', 'LagOutcome', 'LagRequest',
    'LagRunner', 'KINEMATICS', 'LagState', 'LIVE_QUANTITIES', 'LiveComparison',
    'LiveMonitor', 'LiveMotionPredictor', 'LiveSample', 'LiveSettings', 'MAX_BATCH',
    'MAX_TEXT_CHARS', 'parse_job_live', 'parse_live', 'REJECTS', 'Row', 'RowAssembler',
    'SampleRing', 'SOURCES', 'StreamCounters', 'ThreadedLag',
]
