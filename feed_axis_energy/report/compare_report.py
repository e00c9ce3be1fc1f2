"""Report of a campaign comparison: one ``index.html`` with the paper's plots per run embedded.

Usage::

    from feed_axis_energy.measured import compare_campaign, load_campaign
    from feed_axis_energy.report import write_report

    index = write_report(compare_campaign(load_campaign('campaign.yaml')), 'out/report')
"""
from __future__ import annotations

import os
from pathlib import Path

from ..measured import CampaignComparison
from .html import render_index
from .plots import run_plots
from .staging import staged_report

__all__ = ['write_report']


def write_report(comparison: CampaignComparison, out_dir: str | os.PathLike[str], *,
                 dpi: int = 90, force: bool = False) -> Path:
    """Write ``index.html`` with the plots of every run embedded into ``out_dir``, all or
    nothing (one file however many runs: the plots are ``data:`` URIs).

    Everything is written into a temporary directory next to ``out_dir`` and moved into
    place at the end, so a failure leaves no half-written report (and an earlier report in
    ``out_dir`` untouched).

    Parameters
    ----------
    comparison
        From :func:`feed_axis_energy.measured.compare.compare_campaign`.
    out_dir
        Report directory: must not exist unless ``force`` (see :func:`staged_report`).
    dpi
        Resolution of the embedded PNG images.
    force
        Replace an earlier report (or an empty directory) in ``out_dir``.

    Returns
    -------
    pathlib.Path
        The ``index.html`` file.

    Raises
    ------
    OutputError
        If ``out_dir`` must not be written (see :func:`staged_report`).
    """
    out = Path(out_dir)
    with staged_report(out, written_by='feed-axis-energy compare --report',
                       force=force) as tmp:
        images = {run.name: run_plots(run, dpi=dpi) for run in comparison.runs}
        (tmp / 'index.html').write_text(render_index(comparison, images), encoding='utf-8')
    return out / 'index.html'
