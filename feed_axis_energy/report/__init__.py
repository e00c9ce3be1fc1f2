"""Reports and plots for people: HTML pages with PNG figures, drawn by the tool itself.

Uses matplotlib (Agg canvas only) and no ROS. One module per report: the campaign comparison
(:mod:`.compare_report`), the analysis (:mod:`.analyze_report`), a simulation
(:mod:`.sim_report`, with its decimated power trace :mod:`.decimate`) and a sweep
(:mod:`.sweep_report`); every report directory is written whole or not at all
(:mod:`.staging`).
"""
from .analyze_report import write_analyze_report
from .compare_report import write_report
from .decimate import PowerTrace
from .plots import PLOT_KINDS
from .sim_report import write_sim_report
from .staging import MARKER, report_stem, staged_report
from .sweep_report import write_sweep_report

__all__ = ['MARKER', 'PLOT_KINDS', 'PowerTrace', 'report_stem', 'staged_report',
           'write_analyze_report', 'write_report', 'write_sim_report', 'write_sweep_report']
