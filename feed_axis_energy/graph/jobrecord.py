"""One recording per job (docs/nodes.md, "Jobs", "Recording"): ``<root>/<job_id>/``.

The recorder (``nodes/mcap_recorder.py`` with ``per_job``) hands every message it takes to
the recording of the job named in its ``header.frame_id``. A job's recording is a graph
recording of one program from time 0, as ``launch --record`` writes for a single program
(the same topics, the plot topics, the crash-safe
:class:`~feed_axis_energy.record.ChunkedBagWriter`),
so every reader of graph recordings works on it unchanged. What this module adds is its
life and its place on disk:

* **opened** when the job is first seen: its ``planning`` state on ``job/state``, or (DDS does
  not order topics) a message of the job that arrives before that state;
* **built in a hidden temporary directory**
  (:func:`feed_axis_energy.outputs.staged_directory`:
  ``<root>/.<job_id>.tmp-<pid>/<job_id>``), **renamed to** ``<root>/<job_id>`` when closed,
  never over an existing entry (checked when opened and again just before the rename), the
  job id confined to one path component; a writer error removes the temporary, so nothing
  half-written is left;
* **closed** once the job's result has arrived (``job/result``) and every stream holds what
  the job's ``program/end`` says was sent, at once for a job that failed before it sent
  anything, else ``grace_s`` after the result (a job failed by a stall); on shutdown of the
  recorder, whatever is open is closed as ``interrupted``;
* **marked** in the bag's ``custom_data`` under :data:`JOB_KEY` (JSON): ``job_id``,
  ``status`` (the result's ``ended``, ``aborted`` or ``failed``, or ``interrupted``),
  ``message``, ``complete`` (every stream up to the end marker), ``gaps`` (what is missing
  if not), ``spec`` (the job as ``job/state`` announced it) and ``result`` (the ``job/result``
  object, ``null`` when interrupted).

Bounded: at most ``max_open`` recordings open at once (the board runs one job at a time; a
closing one may overlap the next), ids of the last ``remember`` closed jobs kept to ignore
late duplicates.
"""
from __future__ import annotations

from collections import OrderedDict
import contextlib
from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import re
import stat
import time
from typing import Any, Callable, Mapping

from ..cell import check_job_id
from ..errors import DataError, FeedAxisError, OutputError, shorten
from ..outputs import check_component, remove_stale_temporaries, staged_directory
from ..record import check_mcap, ChunkedBagWriter
from ..safeyaml import load_yaml_file
from .end import EndTracker
from .plots import GraphPlotter

__all__ = ['BagSink', 'JOB_KEY', 'JobRecorder', 'JobRecording', 'read_back',
           'RECORDING_STATUSES', 'sink_gaps']

JOB_KEY = 'feed_axis_energy/job'
"""``custom_data`` key of a job's recording (JSON object, module docstring)."""
RECORDING_STATUSES = ('ended', 'aborted', 'failed', 'interrupted')
_STREAM_TOPICS = ('/setpoints', '/axis_state', '/power')
_TMP = re.compile(r'^\.(?P<name>.+)\.tmp-[0-9]{1,10}(?:-[0-9]{1,6})?$')


@dataclass
class BagSink:
    """One bag being written and what the recorder knows of its streams.

    Attributes
    ----------
    bag
        The crash-safe writer.
    tracker
        End of the program: which streams reached the end marker's last stamp.
    plotter
        The plot topics' decimators (``None``: no plot topics).
    start_ns
        Added to every stamp (wall-clock start; 0: simulation time).
    newest
        Newest header stamp per logical topic (simulation time).
    acked
        Newest stamp acknowledged per stream on ``recorder/stream_progress``.
    acked_all
        Newest stamp acknowledged on ``recorder/progress``.
    no_plot
        Streams whose batches the plot topics refused (logged once).
    """

    bag: ChunkedBagWriter
    tracker: EndTracker
    plotter: GraphPlotter | None = None
    start_ns: int = 0
    newest: dict[str, int] = field(default_factory=dict)
    acked: dict[str, int] = field(default_factory=dict)
    acked_all: int = -1
    no_plot: set[str] = field(default_factory=set)


def sink_gaps(sink: BagSink) -> list[str]:
    """What the sink's bag lacks against its end marker, from the writer's own counts
    (the rule of :func:`~feed_axis_energy.graph.flow.recording_gaps`; flushed messages only)."""
    end = sink.tracker.end
    if end is None:
        return ['no /program/end marker: the recording ended before the job\'s stream did']
    counts = sink.bag.counts
    return [f'{topic}: {counts.get(topic, 0)} of {end.batches} batches'
            for topic in _STREAM_TOPICS
            if topic in sink.bag.topics and counts.get(topic, 0) != end.batches]


def read_back(path: str | os.PathLike[str], counts: Mapping[str, int]) -> list[str]:
    """Problems of a closed bag read back from disk (empty: none): its ``metadata.yaml``
    must list ``counts`` messages per topic, and every MCAP file it lists must be complete
    (:func:`~feed_axis_energy.record.check_mcap`: framing, summary, footer).

    A few milliseconds per job: the metadata and the records' framing only, not the
    messages (``rosbags`` takes about half a second to open a job's bag on a busy machine,
    which the recorder cannot spend between two jobs).
    """
    path = Path(path)
    try:
        meta = load_yaml_file(path / 'metadata.yaml', error=DataError, what='bag metadata')
        info = meta['rosbag2_bagfile_information']
        listed = {t['topic_metadata']['name']: int(t['message_count'])
                  for t in info['topics_with_message_count']}
        files = [str(f) for f in info['relative_file_paths']]
    except (FeedAxisError, KeyError, TypeError, ValueError) as err:
        return [f'metadata.yaml: {shorten(str(err))}']
    problems = [f'{topic}: {listed.get(topic, 0)} messages listed, {n} written'
                for topic, n in sorted(counts.items()) if listed.get(topic, 0) != n]
    for name in files:
        if Path(name).name != name:
            problems.append(f'{shorten(name)}: not a file name of the bag')
            continue
        try:
            check_mcap(path / name, bag=path)
        except (FeedAxisError, OSError) as err:
            problems.append(shorten(str(err)))
    return problems


@dataclass
class JobRecording:
    """One job's recording while it is open."""

    job_id: str
    sink: BagSink
    final: Path
    stack: contextlib.ExitStack
    spec: dict[str, Any] | None = None
    result: dict[str, Any] | None = None
    result_at: float | None = None


class JobRecorder:
    """The recordings of the jobs under ``root`` (module docstring).

    Parameters
    ----------
    root
        Directory of the recordings: created if missing (its last component without
        following a link); an existing one must be a directory, not a symbolic link.
    new_sink
        ``new_sink(path)`` creates the bag at ``path`` (which does not exist yet) and
        returns its sink.
    grace_s
        How long after its result a job's recording waits for missing stream messages.
    max_open, remember
        Bounds (module docstring).
    clock
        Monotonic seconds (tests pass their own).
    """

    def __init__(self, root: str | os.PathLike[str], *, new_sink: Callable[[Path], BagSink],
                 grace_s: float = 5.0, max_open: int = 4, remember: int = 256,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.root = _job_root(Path(root))
        self._new_sink = new_sink
        self.grace_s = float(grace_s)
        self.max_open = int(max_open)
        self.remember = int(remember)
        self._clock = clock
        self.open: OrderedDict[str, JobRecording] = OrderedDict()
        self._done: OrderedDict[str, str] = OrderedDict()     # job id -> why not recording
        # results of jobs not opened yet: DDS does not order job/result before the job's
        # state and stream messages
        self._early: OrderedDict[str, tuple[dict[str, Any], float]] = OrderedDict()
        self.ignored = 0          # messages of closed, refused or unnamed jobs
        self.closed: list[Path] = []
        for entry in os.listdir(self.root):
            m = _TMP.match(entry)
            if m is not None:    # a recorder killed mid-job left its temporary
                remove_stale_temporaries(self.root / m.group('name'))

    def recording(self, job_id: str) -> JobRecording | None:
        """The open recording of ``job_id``, opened now if the job was not seen before.

        Returns ``None`` for a job already closed or refused (its later messages are
        ignored and counted in :attr:`ignored`).

        Raises
        ------
        OutputError
            The recording cannot be created (a bad job id, ``<root>/<job_id>`` exists, the
            disk refuses); the job is remembered as refused.
        """
        rec = self.open.get(job_id)
        if rec is not None:
            return rec
        if job_id in self._done:
            self.ignored += 1
            return None
        try:
            return self._open(job_id)
        except FeedAxisError as err:
            self._forget(job_id, f'not recorded: {err}')
            raise

    def _open(self, job_id: str) -> JobRecording:
        try:
            check_job_id(job_id)
        except FeedAxisError as err:
            raise OutputError(f'job id {shorten(job_id)!r}: {err}', option='job_id') from None
        check_component(job_id, option='job_id')
        while len(self.open) >= self.max_open:     # bounded: the oldest is closed as is
            oldest = next(iter(self.open.values()))
            self.close(oldest, note='closed early: more than '
                                    f'{self.max_open} job recordings were open')
        stack = contextlib.ExitStack()
        final = self.root / job_id
        inner = stack.enter_context(staged_directory(final, option='job_id', forceable=False))
        try:
            sink = self._new_sink(inner)
        except BaseException as err:
            _unwind(stack, err)
            raise
        rec = JobRecording(job_id, sink, final, stack)
        if job_id in self._early:
            rec.result, rec.result_at = self._early.pop(job_id)
        self.open[job_id] = rec
        return rec

    def note_state(self, state: str, job_id: str, spec: Mapping[str, Any] | None) -> None:
        """A ``job/state`` message: ``planning`` (or ``running``) opens the job's recording.

        Raises
        ------
        OutputError
            As :meth:`recording`.
        """
        if not job_id or state not in ('planning', 'running'):
            return
        if job_id in self._done:
            return
        rec = self.recording(job_id)
        if rec is not None and spec is not None:
            rec.spec = dict(spec)

    def note_result(self, result: Mapping[str, Any]) -> None:
        """A ``job/result`` object: the job's recording closes once complete (:meth:`due`)."""
        job_id = result.get('job_id')
        if not isinstance(job_id, str) or job_id in self._done:
            return
        rec = self.open.get(job_id)
        if rec is None:       # its first message or state has not been taken yet
            self._early[job_id] = (dict(result), self._clock())
            while len(self._early) > self.max_open:
                self._early.popitem(last=False)
        elif rec.result is None:
            rec.result = dict(result)
            rec.result_at = self._clock()

    def due(self) -> list[JobRecording]:
        """Open recordings whose job has its result and whose streams are complete, or whose
        grace after the result has passed."""
        now = self._clock()
        return [rec for rec in self.open.values() if rec.result is not None
                and rec.result_at is not None
                and (rec.sink.tracker.done or now - rec.result_at >= self.grace_s
                     or (rec.result.get('samples') == 0 and not rec.sink.newest))]

    @property
    def sinks(self) -> list[tuple[str, BagSink]]:
        """``(job id, sink)`` of every open recording, oldest first."""
        return [(job_id, rec.sink) for job_id, rec in self.open.items()]

    def close(self, rec: JobRecording, *, note: str = '') -> Path | None:
        """Finish ``rec``: plot topics, the mark (module docstring), the last file, the
        rename to ``<root>/<job_id>``. Returns the recording's path, or ``None`` if it could
        not be written (then nothing of it is left).

        Raises
        ------
        OutputError
            The recording could not be finished; its temporary is removed.
        """
        self.open.pop(rec.job_id, None)
        sink = rec.sink
        try:
            if sink.plotter is not None and not sink.bag.closed:
                for name, log_ns, cdr in sink.plotter.finish():
                    sink.bag.write(name, log_ns, cdr)
            sink.bag.flush()
            gaps = sink_gaps(sink)
            result = rec.result
            status = str(result.get('status')) if result else 'interrupted'
            if status not in RECORDING_STATUSES:
                status = 'failed'
            message = str(result.get('message', '')) if result else (
                'the recorder stopped before the job\'s result')
            if note:
                message = f'{message}; {note}' if message else note
            mark = {'job_id': rec.job_id, 'status': status, 'message': message,
                    'complete': not gaps, 'gaps': gaps, 'spec': rec.spec, 'result': result}
            sink.bag.set_custom_data(JOB_KEY, json.dumps(mark, allow_nan=False))
            sink.bag.close()
        except BaseException as err:
            self._forget(rec.job_id, 'not recorded: the recording could not be written')
            _unwind(rec.stack, err)
            raise
        self._forget(rec.job_id, 'recorded')
        try:
            rec.stack.close()      # the rename into place (re-checks that nothing is there)
        except BaseException:
            self._forget(rec.job_id, 'not recorded: its place was taken meanwhile')
            raise
        self.closed.append(rec.final)
        del self.closed[:-self.remember]
        return rec.final

    def discard(self, rec: JobRecording, err: BaseException) -> None:
        """Remove ``rec``'s temporary after a writer error (nothing of it is left)."""
        self.open.pop(rec.job_id, None)
        self._forget(rec.job_id, f'not recorded: {err}')
        with contextlib.suppress(BaseException):
            _unwind(rec.stack, err)

    def close_all(self, *, note: str = '') -> list[str]:
        """Close every open recording (shutdown); returns the errors, one line each."""
        errors = []
        for rec in list(self.open.values()):
            try:
                self.close(rec, note=note)
            except (FeedAxisError, OSError) as err:
                errors.append(f'{rec.job_id}: {err}')
        return errors

    def _forget(self, job_id: str, why: str) -> None:
        self._done[job_id] = why
        while len(self._done) > self.remember:
            self._done.popitem(last=False)


def _unwind(stack: contextlib.ExitStack, err: BaseException) -> None:
    """Leave the staged directory as on an exception: its temporary is removed."""
    try:
        stack.__exit__(type(err), err, err.__traceback__)
    except BaseException:
        pass


def _job_root(root: Path) -> Path:
    """The recordings' directory: an existing directory (no link), or created now."""
    try:
        st = os.lstat(root)
    except FileNotFoundError:
        try:
            os.mkdir(root, 0o755)     # mkdir does not follow a link in the last component
        except OSError as err:
            raise OutputError(f'cannot create it: {err.strerror}', path=root,
                              option='output') from None
        return root
    except OSError as err:
        raise OutputError(f'cannot read it: {err.strerror}', path=root, option='output') from None
    if stat.S_ISLNK(st.st_mode):
        raise OutputError('is a symbolic link; give the directory itself', path=root,
                          option='output')
    if not stat.S_ISDIR(st.st_mode):
        raise OutputError('exists and is not a directory', path=root, option='output')
    return root
