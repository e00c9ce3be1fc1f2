"""Measured runs: campaign manifests, CSV and bag runs, alignment, metrics, comparison.

Live drive data compared while the machine runs (the ``measured_live`` node's core):
:mod:`.live`.

What a trace measures (power, current, torque, force) and how it is predicted: :mod:`.quantity`.

Typical use::

    campaign = load_campaign('config/campaigns/umich_mill.yaml')
    run = load_run(campaign.run('exp01'))
    result = compare_campaign(campaign, machine=machine)
"""
from .align import (align_simulated, estimate_offset, first_order_lag, interval_average,
                    MAX_FILTER_S, OffsetResult, ShiftedAverage, stamp_shift)
from .campaign import Campaign, ColumnSpec, RowFilter, RunSpec, TimeWindow
from .compare import (compare_campaign, compare_one_run, DEFAULT_MAX_LAG_S, MotionCache,
                      simulate_declared, simulate_declared_chunks)
from .comparison import CampaignComparison, json_clean, offset_dict, RunComparison
from .csvload import load_run
from .importer import import_campaign
from .live import (ALARM_KEYS, alarm_text, comparison_text, COMPARISON_KEYS, KINEMATICS,
                   LiveComparison, LiveMonitor, LiveMotionPredictor, LiveSettings,
                   parse_job_live, parse_live, SOURCES, ThreadedLag)
from .manifest import campaign_from_dict, load_campaign
from .metrics import group_metrics, Metrics, table1_metrics
from .quantity import (MEASURES, measured_signal, POWER_MEASURES, predicted_signal,
                       QUANTITIES, Quantity, quantity_of, SignalMetrics, signal_metrics,
                       torque_per_unit)
from .run import GAP_FACTOR, MeasuredRun

__all__ = [
    'ALARM_KEYS', 'alarm_text', 'align_simulated', 'Campaign', 'campaign_from_dict',
    'CampaignComparison', 'ColumnSpec', 'compare_campaign', 'compare_one_run', 'COMPARISON_KEYS',
    'comparison_text', 'DEFAULT_MAX_LAG_S', 'estimate_offset', 'first_order_lag', 'GAP_FACTOR',
    'group_metrics', 'MAX_FILTER_S',
    'import_campaign', 'interval_average', 'json_clean', 'KINEMATICS', 'LiveComparison',
    'LiveMonitor', 'LiveMotionPredictor', 'LiveSettings', 'load_campaign', 'load_run',
    'measured_signal', 'MeasuredRun', 'MEASURES', 'Metrics', 'MotionCache', 'offset_dict',
    'OffsetResult', 'parse_job_live', 'parse_live', 'POWER_MEASURES', 'predicted_signal',
    'QUANTITIES', 'Quantity',
    'quantity_of', 'RowFilter', 'RunComparison', 'RunSpec', 'ShiftedAverage',
    'signal_metrics', 'SignalMetrics', 'simulate_declared', 'simulate_declared_chunks',
    'SOURCES', 'stamp_shift',
    'table1_metrics', 'ThreadedLag',
    'TimeWindow', 'torque_per_unit',
]
