"""The records' timing in an analysis: at which offsets runs are fitted, and the meter's lag.

:mod:`.pinning` decides which runs' offsets are pinned down (the rest are left out and named),
moves motion-anchored runs to a common meter lag and re-estimates offsets after each round
with the effects found; :mod:`.jointalign` screens, on records of the power alone, the
offsets each run would have with a candidate effect in the model; :mod:`.meter` estimates a
meter's first-order smoothing with the effects in the model; :mod:`.jointstart` gives the start
from the best screened candidate's offsets. ``analyze``
(:mod:`feed_axis_energy.identify.analyze`) runs its rounds with them.
"""
from .jointalign import (JOINT_REACH_S, JOINT_STEP_S, joint_screen, JointFit,
                         MAX_SCREEN_COLUMNS, MAX_SCREEN_SAMPLES, MAX_SCREEN_SPAN_S,
                         ScreenCandidate, ScreenRun, screen_span)
from .jointstart import JOINT_MIN_GAIN, joint_eligible, joint_start
from .meter import (FILTER_EXTRA_ROUNDS, FILTER_MAX_RATIO, FILTER_TOLERANCE, filter_next,
                    filter_step, may_filter, MIN_FILTER_PERIODS, runs_differ, with_filter)
from .pinning import (at_common_lag, at_motion_offsets, at_offsets, decisive, lag_tolerance_s,
                      left_out_text, LeftOut, MAX_PIN_ROUNDS, motion_lag_s, PIN_MARGIN,
                      PINNED_STATUSES, repin, split_pinned)

__all__ = [
    'at_common_lag', 'at_motion_offsets', 'at_offsets', 'decisive', 'FILTER_EXTRA_ROUNDS',
    'FILTER_MAX_RATIO', 'FILTER_TOLERANCE', 'filter_next', 'filter_step', 'joint_eligible',
    'JOINT_MIN_GAIN', 'JOINT_REACH_S', 'joint_start', 'JOINT_STEP_S', 'joint_screen', 'JointFit',
    'lag_tolerance_s', 'left_out_text', 'LeftOut', 'MAX_PIN_ROUNDS', 'MAX_SCREEN_COLUMNS',
    'MAX_SCREEN_SAMPLES', 'MAX_SCREEN_SPAN_S', 'may_filter', 'MIN_FILTER_PERIODS', 'motion_lag_s',
    'PIN_MARGIN', 'PINNED_STATUSES', 'repin', 'runs_differ', 'ScreenCandidate', 'ScreenRun',
    'screen_span', 'split_pinned', 'with_filter',
]
