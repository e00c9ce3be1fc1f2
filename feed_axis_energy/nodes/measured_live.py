"""``measured_live``: live measured drive data against the prediction, while the machine runs.

Subscribes to ``measured/live`` (the cell's drive data, one JSON sample or a batch per
message), ``job/state`` and ``job/live``; publishes the running comparison on
``measured/comparison`` and the alarm's changes on ``measured/alarm`` (docs/nodes.md,
"measured_live"). The work is done by :class:`feed_axis_energy.measured.LiveMonitor`; this
node only routes messages to it. The comparison's lag estimates run on a worker thread
(:class:`~feed_axis_energy.measured.ThreadedLag`), so that the executor delivering samples
never waits for one.

``source``: ``job_live`` compares with the running job's predicted power (``job/live``,
wall-clock stamps: the graph in real-time mode), one comparison per job, final
``final_after_s`` after the job ends (measured samples still on their way are used);
``live_motion`` predicts from the stream's own kinematics (runs without an NC program),
one comparison per stretch of stream, final after ``end_after_s`` without samples.
"""
from __future__ import annotations

import json
import math
import sys
import time

from rclpy.node import Node
from std_msgs.msg import String

from feed_axis_energy.errors import FeedAxisError
from feed_axis_energy.graph import parse_state_text
from feed_axis_energy.machine import load_machine
from feed_axis_energy.measured import (alarm_text, comparison_text, KINEMATICS, LiveMonitor,
                                       LiveMotionPredictor, LiveSettings, parse_job_live,
                                       parse_live, POWER_MEASURES, SOURCES, ThreadedLag)
from feed_axis_energy.nodes.qos import command_qos, job_qos, latched_qos, measured_live_qos
from feed_axis_energy.nodes.runner import declare, run, StartupError, steady_timer
from feed_axis_energy.paths import default_machine

__all__ = ['MeasuredLive', 'main']

_FINAL_STATES = ('ended', 'aborted', 'failed')


def _names(text: str) -> tuple[str, ...]:
    return tuple(a.strip() for a in text.split(',') if a.strip())


def _constants(text: str) -> dict[str, float]:
    """``'X=1.3,Y=1.3'`` -> ``{'X': 1.3, 'Y': 1.3}``; ``ValueError`` naming the bad item."""
    out = {}
    for item in _names(text):
        axis, eq, value = item.partition('=')
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not eq or not axis.strip() or not (math.isfinite(number) and number > 0.0):
            msg = f"parameter kt_nm_a: expected AXIS=N·m/A > 0, got {item!r}"
            raise ValueError(msg)
        out[axis.strip()] = number
    return out


class MeasuredLive(Node):
    """Routes live samples and predictions to a :class:`LiveMonitor`; publishes its output."""

    def __init__(self, **kwargs) -> None:
        super().__init__('measured_live', **kwargs)
        self.source = declare(self, 'source', 'job_live',
                              'prediction: job_live (the running job) or live_motion (the '
                              "stream's own kinematics)")
        if self.source not in SOURCES:
            raise StartupError(f'parameter source must be one of {SOURCES}, got '
                               f'{self.source!r}')
        path = declare(self, 'machine', '', 'machine config YAML (live_motion: the model)')
        self.machine = load_machine(path or default_machine())
        axes = _names(declare(self, 'measured_axes', '',
                              "axes with measured power, comma-separated ('': all the "
                              "machine's)")) or self.machine.axis_names
        motion = _names(declare(self, 'motion_axes', '',
                                "live_motion: axes whose kinematics the stream sends ('': "
                                "all the machine's)")) or self.machine.axis_names
        quantities = _names(declare(self, 'motion_quantities', ','.join(KINEMATICS),
                                    'live_motion: kinematic quantities of each axis'))
        self.load_kg = float(declare(self, 'load_kg', 0.0, 'live_motion: workpiece mass [kg]'))
        self.measures = declare(self, 'measures', 'shaft',
                                'what the measured trace is (compare\'s instrument.measures): '
                                'shaft, motor, supply (power_w samples), current (current_a), '
                                'torque (torque_nm), force (force_n); a drive trace needs '
                                'live_motion')
        kt_text = declare(self, 'kt_nm_a', '',
                          "measures current: torque constants 'X=1.3,Y=1.3' [N·m/A] ('': "
                          "the machine's drives)")
        self.reorder_s = float(declare(self, 'reorder_s', 0.5,
                                       'how long a row waits for its missing values [s]'))
        self.end_after_s = float(declare(self, 'end_after_s', 10.0,
                                         'live_motion: the comparison is final after this '
                                         'long without samples [s]'))
        self.final_after_s = float(declare(self, 'final_after_s', 1.0,
                                           'job_live: the comparison is final this long after '
                                           'its job ends; samples still on their way are used '
                                           '[s] (0: at once)'))
        rate = float(declare(self, 'publish_rate_hz', 2.0, 'measured/comparison rate [Hz]'))
        d = LiveSettings()
        options = {
            'max_lag_s': declare(self, 'max_lag_s', d.max_lag_s,
                                 'largest lag searched, in either direction [s]'),
            'window_s': declare(self, 'window_s', d.window_s,
                                "the meter's averaging window [s] (0: point samples)"),
            'ring_s': declare(self, 'ring_s', d.ring_s,
                              'measured time kept for re-alignment [s]'),
            'realign_every_s': declare(self, 'realign_every_s', d.realign_every_s,
                                       'measured time between lag estimates [s]'),
            'freeze_count': declare(self, 'freeze_count', d.freeze_count,
                                    'estimates in a row within 0.5 ms that freeze the lag '
                                    '(0: never)'),
            'band_floor_w': declare(self, 'band_floor_w', d.band_floor_w,
                                    'alarm band: this [W] ...'),
            'band_pct': declare(self, 'band_pct', d.band_pct,
                                '... plus this share of the mean predicted power [%]'),
            'alarm_window_s': declare(self, 'alarm_window_s', d.alarm_window_s,
                                      'the residual is averaged over this [s]'),
            'alarm_hold_s': declare(self, 'alarm_hold_s', d.alarm_hold_s,
                                    'outside (or back inside) the band this long [s]'),
        }
        stamp = declare(self, 'stamp', d.stamp, 'where the meter stamps its window')
        self.band_sigmas = float(declare(self, 'band_sigmas', 2.0,
                                         "live_motion on a calibrated machine (loss_covariance): "
                                         'band = this many standard uncertainties of the '
                                         'predicted energy (0: band_pct)'))
        if (not rate > 0.0 or not self.end_after_s > 0.0 or not self.band_sigmas >= 0.0
                or not (math.isfinite(self.final_after_s) and self.final_after_s >= 0.0)):
            raise StartupError('parameters publish_rate_hz and end_after_s must be > 0, '
                               'band_sigmas and final_after_s finite and >= 0')
        try:
            self.kt_nm_a = _constants(kt_text)
            if self.source != 'live_motion' and self.measures not in POWER_MEASURES:
                raise StartupError(f'measures {self.measures!r} needs source live_motion: '
                                   'job/live predicts power only')
            self.settings = LiveSettings(stamp=stamp, **{
                n: (int(v) if n == 'freeze_count' else float(v)) for n, v in options.items()})
            self.measured_axes = tuple(axes)
            self._motion = (tuple(motion), tuple(quantities))
            self._predictor()       # checks the axes and quantities against the machine now
        except (FeedAxisError, ValueError, TypeError) as err:
            raise StartupError(str(err)) from err
        self.monitor: LiveMonitor | None = None
        self.job_id = ''
        self.job_state = 'idle'
        self.rejected: dict[str, int] = {}
        self.outside_job = 0
        self.prediction_clock = 0
        self.finals = 0
        self._final_at: float | None = None     # job_live: when the ended job's comparison
        #                                         becomes final (monotonic clock)
        self._last_sample = time.monotonic()
        self._dirty = False
        self._alarm_active = False
        self.pub = self.create_publisher(String, 'measured/comparison', command_qos())
        self.pub_alarm = self.create_publisher(String, 'measured/alarm', latched_qos())
        self.create_subscription(String, 'measured/live', self._on_measured,
                                 measured_live_qos())
        self.create_subscription(String, 'job/state', self._on_job_state, job_qos())
        self.create_subscription(String, 'job/live', self._on_job_live, command_qos())
        steady_timer(self, 1.0 / rate, self._tick)

    def _predictor(self) -> LiveMotionPredictor | None:
        if self.source != 'live_motion':
            return None
        axes, quantities = self._motion
        return LiveMotionPredictor(self.machine, axes=axes, measured_axes=self.measured_axes,
                                   quantities=quantities, load_kg=self.load_kg,
                                   measures=self.measures, kt_nm_a=self.kt_nm_a or None)

    def _new_monitor(self, job_id: str) -> LiveMonitor:
        return LiveMonitor(self.measured_axes, source=self.source, settings=self.settings,
                           predictor=self._predictor(), reorder_s=self.reorder_s,
                           job_id=job_id, band_sigmas=self.band_sigmas,
                           lag_runner=ThreadedLag(name='measured_live lag'))

    # -- input -------------------------------------------------------------------------
    def _on_job_state(self, msg: String) -> None:
        try:
            state, job_id, _ = parse_state_text(msg.data)
        except FeedAxisError as err:
            self.get_logger().error(str(err))
            return
        self.job_state = state
        if self.source != 'job_live':
            self.job_id = job_id if state in ('planning', 'running') else ''
            return
        if state in ('planning', 'running') and job_id != self.job_id:
            self._finish()
            self.job_id = job_id
            self.monitor = self._new_monitor(job_id)
        elif (state in _FINAL_STATES and job_id == self.job_id and self.monitor is not None
              and self._final_at is None):
            # the drive data of the job's last moments may still be on their way (fieldbus,
            # bridge, DDS): the comparison is final a little later (_tick), or at once when
            # the next job starts
            self._final_at = time.monotonic() + self.final_after_s
            if self.final_after_s == 0.0:
                self._finish()

    def _on_job_live(self, msg: String) -> None:
        if self.source != 'job_live' or self.monitor is None:
            return
        live = parse_job_live(msg.data)
        if live is None or live.job_id != self.monitor.job_id:
            return
        if live.clock != 'wall':
            self.prediction_clock += 1      # simulation time cannot meet wall-clock stamps
            return
        try:
            self.monitor.add_prediction(live.stamp_ns, live.power_w)
        except (FeedAxisError, ValueError) as err:     # never out of a callback
            self.get_logger().error(f'prediction not used: {err}')
        self._dirty = True

    def _on_measured(self, msg: String) -> None:
        samples, rejects = parse_live(msg.data)
        for key, n in rejects.items():
            self.rejected[key] = self.rejected.get(key, 0) + n
        if not samples:
            return
        self._last_sample = time.monotonic()
        if self.monitor is None:
            if self.source == 'job_live':
                self.outside_job += len(samples)
                return
            self.monitor = self._new_monitor(self.job_id)
        try:
            for sample in samples:
                self.monitor.add_sample(*sample)
        except (FeedAxisError, ValueError) as err:     # never out of a callback
            self.get_logger().error(f'measured sample not compared: {err}')
        self._dirty = True

    # -- output ------------------------------------------------------------------------
    def _publish(self, comparison: dict) -> None:
        comparison['counters'].update(rejected=dict(self.rejected),
                                      outside_job=self.outside_job,
                                      prediction_clock=self.prediction_clock)
        self.pub.publish(String(data=comparison_text(comparison)))
        if comparison['alarm']['active'] != self._alarm_active:
            self._alarm_active = comparison['alarm']['active']
            self.pub_alarm.publish(String(data=alarm_text(comparison)))
            level = self.get_logger().warning if self._alarm_active else self.get_logger().info
            level(f'alarm {"on" if self._alarm_active else "off"}: '
                  f'{json.loads(alarm_text(comparison))}')

    def _finish(self) -> None:
        self._final_at = None
        if self.monitor is None:
            return
        monitor, self.monitor = self.monitor, None
        try:
            final = monitor.finish()
        except (FeedAxisError, ValueError) as err:     # never out of a callback
            self.get_logger().error(f'comparison of job {monitor.job_id!r} not finished: {err}')
            return
        self.finals += 1
        self._publish(final)
        self._dirty = False
        total = final['energy_error_pct']['total']
        self.get_logger().info(
            f'comparison final (job {monitor.job_id!r}): measured '
            f"{final['measured_energy_j']['total']:.3f} J, predicted "
            f"{final['predicted_energy_j']['total']:.3f} J, error "
            f'{total:+.3f} %, lag {final["lag"]["lag_s"]:+.4f} s ({final["lag"]["status"]})')

    def destroy_node(self) -> None:
        """Publish an ended job's comparison still waiting for ``final_after_s``, let the
        running comparison's lag worker go, then the node."""
        if self._final_at is not None:
            self._finish()
        if self.monitor is not None:
            self.monitor.close()
        super().destroy_node()

    def _tick(self) -> None:
        try:
            if (self.source == 'live_motion' and self.monitor is not None
                    and time.monotonic() - self._last_sample > self.end_after_s):
                self._finish()
            elif self._final_at is not None and time.monotonic() >= self._final_at:
                self._finish()
            elif self.monitor is not None and self._dirty:
                self._dirty = False
                self._publish(self.monitor.snapshot())
        except (FeedAxisError, ValueError) as err:
            self.get_logger().error(f'comparison not published: {err}')


def main(args: list[str] | None = None) -> None:
    """Run the node."""
    sys.exit(run(MeasuredLive, args, name='measured_live'))


if __name__ == '__main__':
    main()
