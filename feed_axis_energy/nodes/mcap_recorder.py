"""``mcap_recorder``: records the graph's topics into a crash-safe rosbag2/MCAP directory.

Subscribes serialized; the log time of every message is its own header stamp (simulation
time), never the receive time. The subscriptions are not handed to the executor: :meth:`poll`
(called by :func:`runner.run` between executor turns) waits on an rclpy wait set and drains
every ready subscription with repeated ``take_message`` calls, so a message costs one take
and one list append instead of an executor dispatch and a Python callback. Messages are
flushed as complete MCAP files with a refreshed ``metadata.yaml``
(:class:`feed_axis_energy.record.crashsafe.ChunkedBagWriter`; the bag is readable from
start-up) after
``chunk_messages`` messages and once ``chunk_period_s`` has passed (checked on every poll), so
SIGKILL loses only what was taken in the last ``chunk_period_s`` + 0.1 s, fewer than
``chunk_messages`` + ``ack_every`` messages (docs/nodes.md). Topics are stored under their logical
name (``/setpoints`` ...), whatever namespace or remapping the node runs with, so the bag reads
like an offline ``simulate --out`` recording.

Flow control: acknowledgements (``std_msgs/Header``) of what has been taken off the DDS
queues, published once per ``ack_every`` messages or ``ack_period_s``, and only while someone
subscribes (each costs both sides tens of microseconds). ``recorder/progress`` carries the
newest stamp every ``end_streams`` topic has reached (what ``gcode_trajectory`` waits for);
``recorder/stream_progress`` carries one header per recorded stream, ``frame_id`` = its bag
topic (``/power``, ``/measured/power`` ...), stamp = its newest stamp (what ``measured_replay``
waits for).

With ``per_job`` (a graph running jobs, docs/nodes.md "Jobs"), ``output`` is a directory and
every job gets a recording of its own, ``<output>/<job_id>/``, the same bag as a one-program
recording with the job marked in its ``custom_data``: messages go to the job named in their
``header.frame_id``; a job's recording opens at its ``planning`` state (``job/state``) and
closes, complete and checked, after its ``job/result``
(:class:`feed_axis_energy.graph.JobRecorder`). ``recorder/progress`` then carries the job id
in ``frame_id``; per-stream acks are not sent.
"""
from __future__ import annotations

import json
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.type_support import check_is_valid_msg_type
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Header, String
from trajectory_msgs.msg import JointTrajectory

from feed_axis_energy.record import (bagio, BLOCK_ENERGY_PER_MESSAGE, ChunkedBagWriter,
                                     DEFAULT_PLOT_RATE_HZ, JOINT_STATE, parse_start_time, restamp,
                                     TOPIC_PLOT_BLOCK_ENERGY)
from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.graph import (BagSink, EndTracker, GraphPlotter, header_frame_id,
                                    header_stamp_ns, JobRecorder, JobRecording, parse_state_text,
                                    PLOT_SOURCES, read_back, restamp_end_marker, sink_gaps)
from feed_axis_energy.nodes import convert
from feed_axis_energy.nodes.qos import clock_qos, JOB_DEPTH, job_qos, latched_qos, stream_qos
from feed_axis_energy.nodes.runner import (declare, guard_parameters, run, StartupError,
                                           steady_timer)

__all__ = ['McapRecorder', 'main', 'KNOWN_TOPICS']

# logical topic -> (message class, ROS type name, latched)
KNOWN_TOPICS = {
    'setpoints': (JointTrajectory, bagio.JOINT_TRAJECTORY, False),
    'axis_state': (JointTrajectory, bagio.JOINT_TRAJECTORY, False),
    'power': (JointTrajectory, bagio.JOINT_TRAJECTORY, False),
    'measured/power': (JointTrajectory, bagio.JOINT_TRAJECTORY, False),
    'measured/kinematics': (JointTrajectory, bagio.JOINT_TRAJECTORY, False),
    'program/lines': (JointTrajectory, bagio.JOINT_TRAJECTORY, True),
    'block_energy': (DiagnosticArray, bagio.DIAGNOSTIC_ARRAY, True),
    'program/end': (DiagnosticArray, bagio.DIAGNOSTIC_ARRAY, True),
    '/clock': (Clock, 'rosgraph_msgs/msg/Clock', False),
}
DEFAULT_TOPICS = ['setpoints', 'axis_state', 'power', 'block_energy', 'program/end']
# topics whose messages name their job (header.frame_id): the only ones recorded per job
JOB_TOPICS = ('setpoints', 'axis_state', 'power', 'program/lines', 'block_energy',
              'program/end')


class McapRecorder(Node):
    """Serialized subscriptions -> chunked MCAP bag, stamped with header stamps."""

    def __init__(self, **kwargs) -> None:
        super().__init__('mcap_recorder', **kwargs)
        self.exit_code: int | None = None
        out = declare(self, 'output', '', 'bag directory to create (must not exist)')
        topics = declare(self, 'topics', DEFAULT_TOPICS, 'logical topics to record')
        self.chunk_period_s = declare(self, 'chunk_period_s', 1.0,
                                      'flush a chunk file at least this often [s]')
        self.chunk_messages = declare(self, 'chunk_messages', 1000,
                                      'flush a chunk file after this many messages')
        self.exit_at_end = declare(self, 'exit_at_end', False,
                                   'close the bag and exit (code 0) when the program has '
                                   'ended and every stream delivered its last batch')
        end_streams = declare(self, 'end_streams', ['setpoints', 'axis_state', 'power'],
                              'streams that must reach program/end\'s last stamp')
        end_extra = declare(self, 'end_extra', ['block_energy'],
                            'topics of which one message must arrive before the end')
        self.ack_every = declare(self, 'ack_every', 10,
                                 'write and acknowledge after at most this many messages')
        self.ack_period_s = declare(self, 'ack_period_s', 0.005,
                                    'write and acknowledge what arrived at least this often [s]')
        plot = declare(self, 'plot', True,
                       'also record the plot-ready topics plot/power, plot/axes and '
                       'plot/block_energy (one sample per JointState message; README)')
        plot_rate_hz = declare(self, 'plot_rate_hz', DEFAULT_PLOT_RATE_HZ,
                               'display rate of the plot topics [Hz]: per interval the first '
                               'sample and every power/torque extreme; 0: every sample')
        start_time = declare(self, 'start_time', '',
                             'stamp the bag in wall-clock time from this start: now or '
                             'ISO-8601 (no offset: UTC); empty: simulation time')
        self.per_job = declare(self, 'per_job', False,
                               'one recording per job: output is a directory, each job\'s '
                               'recording output/<job_id>/ (docs/nodes.md, Jobs)')
        grace_s = declare(self, 'job_close_grace_s', 5.0,
                          'per_job: how long after its result a job\'s recording waits for '
                          'missing stream messages before it closes as incomplete [s]')
        if not out:
            raise StartupError('parameter output (the bag directory) is required')
        if not plot_rate_hz >= 0 or plot_rate_hz == float('inf'):
            raise StartupError(f'plot_rate_hz must be a finite number >= 0, got {plot_rate_hz}')
        self.start_ns = 0
        if start_time:
            try:
                self.start_ns = parse_start_time(start_time)
            except ValueError as err:
                raise StartupError(f'parameter start_time: {err}') from None
        unknown = [t for t in topics if t not in KNOWN_TOPICS]
        if unknown:
            msg = f'unknown topics {unknown}; known: {sorted(KNOWN_TOPICS)}'
            raise StartupError(msg)
        if self.chunk_period_s <= 0 or self.chunk_messages < 1:
            raise StartupError('chunk_period_s must be > 0 and chunk_messages >= 1')
        if self.ack_every < 1 or self.ack_period_s <= 0:
            raise StartupError('ack_every must be >= 1 and ack_period_s > 0')
        if self.per_job:
            if self.exit_at_end:
                raise StartupError('per_job records job after job until stopped; it excludes '
                                   'exit_at_end')
            self._check_per_job(topics, start_time, grace_s)
        self._end_streams = [t for t in end_streams if t in topics]
        self._end_extra = [t for t in end_extra if t in topics]
        # The ack publishers appear only once every end stream has a matched publisher
        # (:meth:`_announce`): producers start when they see them, so no batch goes out before
        # the recorder can receive it (streams are volatile; a batch lost at start-up would
        # hold the recorder's ack back for good).
        self.pub_progress = None
        self.pub_streams = None
        self._rx: list[tuple[tuple[str, str], bytes]] = []
        self._streams = {t for t in topics if not KNOWN_TOPICS[t][2] and t != '/clock'}
        self.received = 0
        self._end_pending = False
        # (handle, message class, (logical topic, bag topic)) of each serialized subscription
        self._subs: list[tuple[object, type, tuple[str, str]]] = []
        for topic in topics:
            cls, msgtype, latched = KNOWN_TOPICS[topic]
            name = topic if topic.startswith('/') else '/' + topic
            # per job, a latched topic carries one message per job: a reader keeping only the
            # last lost job n's end marker and block energies when job n+1's replaced them
            # before a busy recorder took them (1 of 200 jobs in a row, bench_jobs)
            qos = (latched_qos(JOB_DEPTH if self.per_job else 1) if latched
                   else clock_qos() if topic == '/clock' else stream_qos())
            self._subs.append((self._raw_subscription(cls, topic, qos), cls, (topic, name)))
        self._waitset = _rclpy.WaitSet(len(self._subs), 0, 0, 0, 0, 0, self.context.handle)
        # Created last (nothing left behind if a step above fails); from here on the
        # directory holds a readable bag at every moment.
        bag_topics = {name: KNOWN_TOPICS[topic][1] for _, _, (topic, name) in self._subs}
        self._plot_rate_hz: float | None = None
        if plot and any(t in PLOT_SOURCES for t in topics):
            self._plot_rate_hz = float(plot_rate_hz)
            for t in topics:
                if t in PLOT_SOURCES:
                    bag_topics[PLOT_SOURCES[t]] = JOINT_STATE
            if 'block_energy' in topics:
                bag_topics[TOPIC_PLOT_BLOCK_ENERGY] = JOINT_STATE
        self._bag_topics = bag_topics
        self.sink: BagSink | None = None
        self.jobs: JobRecorder | None = None
        if self.per_job:
            # each job's stamps from its own start (start_time 'now': when it is opened)
            try:
                self.jobs = JobRecorder(out, grace_s=grace_s, new_sink=lambda path: self._sink(
                    path, parse_start_time('now') if start_time else 0))
            except FeedAxisError as err:
                raise StartupError(str(err)) from None
            self.create_subscription(String, 'job/state', self._on_job_state, job_qos())
            self.create_subscription(String, 'job/result', self._on_job_result, job_qos())
        else:
            self.sink = self._sink(out, self.start_ns)
        self._last_flush = time.monotonic()
        self._last_ack = time.monotonic()
        self._announce()
        steady_timer(self, min(self.chunk_period_s, 0.2), self._on_timer)
        where = f'{out}/<job_id>/ (one recording per job)' if self.per_job else out
        self.get_logger().info(f'recording {", ".join(topics)} to {where}')
        guard_parameters(self, {})   # the bag, its topics and the flush rules are fixed

    @staticmethod
    def _check_per_job(topics: list[str], start_time: str, grace_s: float) -> None:
        other = [t for t in topics if t not in JOB_TOPICS]
        if other:
            msg = (f'per_job records the topics whose messages name their job '
                   f'{list(JOB_TOPICS)}; not {other}')
            raise StartupError(msg)
        if start_time and start_time.strip().lower() != 'now':
            msg = ('per_job: start_time must be empty or now (each job\'s recording starts '
                   f'when the job does), got {start_time[:60]!r}')
            raise StartupError(msg)
        if not grace_s > 0 or grace_s == float('inf'):
            raise StartupError(f'job_close_grace_s must be a finite time > 0 s, got {grace_s}')

    def _sink(self, path, start_ns: int) -> BagSink:
        """A new bag at ``path`` with the node's topics, end rule and plot topics."""
        plotter = None
        if self._plot_rate_hz is not None:
            plotter = GraphPlotter(rate_hz=self._plot_rate_hz, start_ns=start_ns,
                                   per_message=BLOCK_ENERGY_PER_MESSAGE)
        bag = ChunkedBagWriter(path, typestore=bagio.typestore(), topics=self._bag_topics)
        return BagSink(bag=bag, tracker=EndTracker(self._end_streams, self._end_extra),
                       plotter=plotter, start_ns=start_ns)

    def _sinks(self) -> list[tuple[str, BagSink]]:
        """``(job id, sink)`` of every open bag ('' for the one bag of a single program)."""
        if self.jobs is not None:
            return self.jobs.sinks
        return [('', self.sink)] if self.sink is not None else []

    def _on_job_state(self, msg: String) -> None:
        try:
            state, job_id, spec = parse_state_text(msg.data)
            self.jobs.note_state(state, job_id, None if spec is None else spec.to_dict())
        except FeedAxisError as err:
            self.get_logger().error(f'job/state: {err}')

    def _on_job_result(self, msg: String) -> None:
        try:
            result = json.loads(msg.data)
        except ValueError as err:
            self.get_logger().error(f'job/result: not JSON: {err}')
            return
        if isinstance(result, dict):
            self.jobs.note_result(result)
        self._close_due()

    def _job_sink(self, data: bytes) -> BagSink | None:
        """The sink of the job a message names (``None``: not recorded, logged)."""
        try:
            job_id = header_frame_id(data)
        except FeedAxisError as err:
            self.get_logger().error(f'a message without a job id: {err}')
            return None
        if not job_id:
            self.jobs.ignored += 1
            return None
        try:
            rec = self.jobs.recording(job_id)
        except FeedAxisError as err:
            self.get_logger().error(f'job {job_id}: not recorded: {err}')
            return None
        return None if rec is None else rec.sink

    def _close_due(self) -> None:
        """Close the job recordings that are due (never inside the take loop)."""
        if self.jobs is None:
            return
        for rec in self.jobs.due():
            self._close_job(rec)

    def _close_job(self, rec: JobRecording, *, note: str = '') -> None:
        try:
            path = self.jobs.close(rec, note=note)
        except (FeedAxisError, OSError) as err:
            self.get_logger().error(f'job {rec.job_id}: recording not kept: {err}')
            return
        status = rec.result.get('status') if rec.result else 'interrupted'
        gaps = sink_gaps(rec.sink)
        counts = ', '.join(f'{t} {n}' for t, n in sorted(rec.sink.bag.counts.items()))
        self.get_logger().info(f'job {rec.job_id}: closed {path} ({status}, '
                               f'{"complete" if not gaps else "; ".join(gaps)}): {counts}')
        problems = read_back(path, rec.sink.bag.counts)     # what is on disk, checked
        if problems:
            self.get_logger().error(f'job {rec.job_id}: {path} read back: '
                                    f'{"; ".join(problems)}')

    def _announce(self) -> None:
        """Create the ack publishers once every end stream has a matched publisher."""
        if self.pub_progress is not None:
            return
        for handle, _, (topic, _) in self._subs:
            if topic in self._end_streams and handle.get_publisher_count() < 1:
                return
        self.pub_progress = self.create_publisher(Header, 'recorder/progress', stream_qos())
        self.pub_streams = self.create_publisher(Header, 'recorder/stream_progress',
                                                 stream_qos())

    def _raw_subscription(self, cls: type, topic: str, qos):
        """An rcl subscription the executor does not know about (only :meth:`poll` takes)."""
        check_is_valid_msg_type(cls)
        with self.handle:
            return _rclpy.Subscription(self.handle, cls, topic, qos.get_c_qos_profile(), None)

    def poll(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` (at most ``ack_period_s``) for messages and take them all.

        Every ready subscription is drained until its queue is empty (take returns ``None``);
        then what arrived is written and acknowledged (:meth:`_drain`) once per ``ack_every``
        messages taken, and at least every ``ack_period_s``. Closing at the end of the
        program happens here, after the take loop, never inside it: the loop must not take
        from a subscription that the close has destroyed.
        """
        if not self._subs:
            time.sleep(min(timeout_s, self.ack_period_s))
            return
        self._take(min(timeout_s, self.ack_period_s))
        if self._rx and time.monotonic() - self._last_ack >= self.ack_period_s:
            self._drain()
        self._flush_if_due()
        self._close_due()
        if self._end_pending:
            self._finish()

    def _take(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` on the wait set, then take every ready queue empty."""
        ws = self._waitset
        ws.clear_entities()
        for handle, _, _ in self._subs:
            ws.add_subscription(handle)
        ws.wait(int(timeout_s * 1e9))
        ready = ws.get_ready_entities('subscription')   # handle pointers
        rx = self._rx
        every = self.ack_every
        for handle, cls, key in self._subs:
            if handle.pointer not in ready:
                continue
            take = handle.take_message
            while True:
                got = take(cls, True)
                if got is None:
                    break
                rx.append((key, got[0]))
                if len(rx) >= every:
                    self._drain()   # never closes (see poll)
                    rx = self._rx

    def _drain(self) -> None:
        """Write what arrived into the bag buffer, then acknowledge it on recorder/progress."""
        if not self._rx or (self.sink is not None and self.sink.bag.closed):
            self._rx.clear()
            return
        rx, self._rx = self._rx, []
        for (topic, name), data in rx:
            sink = self.sink if self.jobs is None else self._job_sink(data)
            if sink is None:
                continue
            try:
                stamp = header_stamp_ns(data)
                start_ns = sink.start_ns
                if start_ns:
                    # the marker's stamp values move with it (the tracker keeps sim time)
                    moved = (restamp_end_marker(data, start_ns) if topic == 'program/end'
                             else restamp(data, stamp + start_ns))
                    sink.bag.write(name, stamp + start_ns, moved)
                else:
                    sink.bag.write(name, stamp, data)
            except FeedAxisError as err:
                self.get_logger().error(f'{topic}: {err}')
                continue
            if sink.plotter is not None and topic not in sink.no_plot:
                try:
                    self._plot(sink, topic, stamp, data)
                except FeedAxisError as err:    # logged once: the stream is still recorded
                    sink.no_plot.add(topic)
                    self.get_logger().error(f'{topic}: no more plot samples from it: {err}')
            if stamp > sink.newest.get(topic, -1):
                sink.newest[topic] = stamp
            sink.tracker.seen(topic, stamp)
            if topic == 'program/end':
                self._on_end(sink, data)
        self.received += len(rx)
        self._publish_acks()
        self._last_ack = time.monotonic()
        for job_id, sink in self._sinks():
            if sink.bag.buffered >= self.chunk_messages:
                self._flush_one(job_id, sink)
        self._flush_if_due()   # also inside a long take loop: the bound holds there too
        self._check_end()

    def _plot(self, sink: BagSink, topic: str, stamp: int, data: bytes) -> None:
        """Write the plot-topic messages this batch completes (feed_axis_energy.graph.plots)."""
        if topic in PLOT_SOURCES:
            batch = convert.decode_trajectory(data)
            out = sink.plotter.add(topic, batch.t_ns, batch.names, batch.fields)
        elif topic == 'block_energy':
            from rclpy.serialization import deserialize_message
            try:
                blocks = convert.block_energy_from_msg(
                    deserialize_message(data, DiagnosticArray))
            except (KeyError, ValueError) as err:    # a status without line/energy numbers
                self.get_logger().error(f'block_energy: no plot/block_energy: {err}')
                return
            out = sink.plotter.block_energy(blocks, stamp + sink.start_ns)
        else:
            return
        for name, log_ns, cdr in out:
            sink.bag.write(name, log_ns, cdr)

    def _publish_acks(self) -> None:
        # Also called by the slow timer: an ack skipped while its subscriber was still being
        # discovered goes out then, even if no further message arrives.
        # Per job: recorder/progress names the job in frame_id (gcode_trajectory counts only
        # its running job's acks); the per-stream acks are for a single program's replay.
        if self.pub_progress is None:
            return
        per_stream = (self.jobs is None and self.pub_streams.get_subscription_count() > 0)
        progress = self.pub_progress.get_subscription_count() > 0
        for job_id, sink in self._sinks():
            for topic, stamp in sink.newest.items():
                if per_stream and topic in self._streams and stamp > sink.acked.get(topic, -1):
                    sink.acked[topic] = stamp
                    self.pub_streams.publish(convert.stamp_msg(stamp, '/' + topic.lstrip('/')))
            low = sink.tracker.min_stamp_ns()
            if low > sink.acked_all and progress:
                sink.acked_all = low
                self.pub_progress.publish(convert.stamp_msg(low, job_id))

    def _on_end(self, sink: BagSink, data: bytes) -> None:
        from rclpy.serialization import deserialize_message
        try:
            sink.tracker.end = convert.program_end_from_msg(
                deserialize_message(data, DiagnosticArray))
        except FeedAxisError as err:
            self.get_logger().error(str(err))

    def _flush_one(self, job_id: str, sink: BagSink) -> None:
        if self.jobs is None:
            sink.bag.flush()
            return
        try:
            sink.bag.flush()
        except (FeedAxisError, OSError) as err:    # the job's recording is lost, not the node
            rec = self.jobs.open.get(job_id)
            if rec is not None:
                self.jobs.discard(rec, err)
            self.get_logger().error(f'job {job_id}: recording removed after a write error: '
                                    f'{err}')

    def _flush(self) -> None:
        for job_id, sink in self._sinks():
            self._flush_one(job_id, sink)
        self._last_flush = time.monotonic()

    def _flush_if_due(self) -> None:
        if time.monotonic() - self._last_flush >= self.chunk_period_s:
            self._flush()

    def _on_timer(self) -> None:
        # Runs from the executor, outside the take loop: closing here is safe.
        if not self._subs:
            return
        self._announce()
        self._drain()
        self._publish_acks()
        self._flush_if_due()
        self._close_due()
        if self._end_pending:
            self._finish()

    def _check_end(self) -> None:
        """Note that the program has ended; the close follows outside the take loop."""
        if (self.exit_at_end and self.sink is not None and self.sink.tracker.done
                and self.exit_code is None):
            self._end_pending = True

    def _finish(self) -> None:
        self._end_pending = False
        self.close()
        self.exit_code = 0

    def close(self) -> None:
        """Take what is still queued in DDS, write the last chunk, finish the bag (idempotent)."""
        if not self._subs:
            return
        self._take(0.0)
        self._drain()
        subs, self._subs = self._subs, []
        self._waitset.clear_entities()
        if self.jobs is not None:
            try:
                self._close_due()
                for rec in list(self.jobs.open.values()):
                    self._close_job(rec)     # marked interrupted: no result
            finally:
                for handle, _, _ in subs:
                    handle.destroy_when_not_in_use()
            return
        sink = self.sink
        if sink.plotter is not None and not sink.bag.closed:
            for name, log_ns, cdr in sink.plotter.finish():
                sink.bag.write(name, log_ns, cdr)
        try:
            sink.bag.close()
        finally:
            for handle, _, _ in subs:
                handle.destroy_when_not_in_use()
        counts = ', '.join(f'{t} {n}' for t, n in sorted(sink.bag.counts.items()))
        self.get_logger().info(f'closed {sink.bag.path}: {counts or "no messages"}')


def main(args: list[str] | None = None) -> None:
    """Run the node."""
    sys.exit(run(McapRecorder, args, name='mcap_recorder'))


if __name__ == '__main__':
    main()
