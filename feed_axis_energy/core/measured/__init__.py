"""Measured runs: campaign manifest, CSV import with column mapping and units, alignment, metrics.

Typical use::

    campaign = load_campaign('config/campaigns/umich_mill.yaml')
    run = load_run(campaign.run('exp01'))
    off = estimate_offset(run.t, run.total_power_w, sim.t, sim_total_w, max_lag_s=5.0,
                          window_s=0.1)
    p_sim = align_simulated(sim.t, sim_total_w, run.t, offset_s=off.offset_s, window_s=0.1)
    print(table1_metrics(run.t, run.total_power_w, p_sim).to_dict())
"""
from .align import align_simulated, estimate_offset, interval_average, OffsetResult
from .campaign import Campaign, ColumnSpec, RowFilter, RunSpec
from .csvload import load_run, MeasuredRun
from .manifest import campaign_from_dict, load_campaign
from .metrics import group_metrics, Metrics, table1_metrics

__all__ = [
    'Campaign', 'ColumnSpec', 'MeasuredRun', 'Metrics', 'OffsetResult', 'RowFilter', 'RunSpec',
    'align_simulated', 'campaign_from_dict', 'estimate_offset', 'group_metrics',
    'interval_average', 'load_campaign', 'load_run', 'table1_metrics',
]
