"""Pure helpers of the node graph (no rclpy): what the nodes compute between messages.

Batching, flow control and pacing (:mod:`.flow`), the setpoint source (:mod:`.source`), the
end-of-program marker (:mod:`.end`), the plot topics from the graph's streams
(:mod:`.plots`), the job a stream message belongs to (:mod:`.jobs`) and one recording per
job (:mod:`.jobrecord`).
"""
from .end import EndTracker, ProgramEnd, restamp_end_marker
from .flow import (FlowWindow, header_stamp_ns, lines_at, NS_PER_S, pacing_delay_s,
                   recording_gaps, seconds_to_ns, StreamingPower)
from .jobrecord import (BagSink, JOB_KEY, JobRecorder, JobRecording, read_back,
                        RECORDING_STATUSES, sink_gaps)
from .jobs import header_frame_id, JobRouter, live_payload, LIVE_CLOCKS, parse_state_text
from .plots import GraphPlotter, PLOT_SOURCES
from .source import SetpointSource

__all__ = [
    'BagSink', 'EndTracker', 'FlowWindow', 'GraphPlotter', 'header_frame_id', 'header_stamp_ns',
    'JOB_KEY', 'JobRecorder', 'JobRecording', 'JobRouter', 'lines_at', 'live_payload',
    'LIVE_CLOCKS', 'NS_PER_S', 'pacing_delay_s', 'parse_state_text', 'PLOT_SOURCES',
    'ProgramEnd', 'read_back', 'RECORDING_STATUSES', 'recording_gaps', 'restamp_end_marker',
    'seconds_to_ns', 'SetpointSource', 'sink_gaps', 'StreamingPower',
]
