"""Report of a campaign comparison: one ``index.html`` with the paper's plots per run embedded.

Outside :mod:`feed_axis_energy.core` because it uses matplotlib (Agg canvas only); it imports
no ROS either. Usage::

    from feed_axis_energy.core.measured import load_campaign
    from feed_axis_energy.core.measured.compare import compare_campaign
    from feed_axis_energy.report import write_report

    index = write_report(compare_campaign(load_campaign('campaign.yaml')), 'out/report')
"""
from __future__ import annotations

from contextlib import contextmanager
import os
from pathlib import Path
import re
from typing import Iterator

from feed_axis_energy.core.measured.compare import CampaignComparison
from feed_axis_energy.core.outputs import marked_or_empty, REPORT_MARKER, staged_directory

from .html import render_index
from .plots import PLOT_KINDS, run_plots

__all__ = ['MARKER', 'PLOT_KINDS', 'staged_report', 'write_report']

MARKER = REPORT_MARKER
"""File that marks a directory written by :func:`write_report` (it may then be replaced)."""


def _stem(i: int, name: str) -> str:
    return f'{i + 1:02d}_' + re.sub(r'[^A-Za-z0-9_.-]+', '_', name).strip('._')


@contextmanager
def staged_report(out_dir: str | os.PathLike[str], *, written_by: str, force: bool = False,
                  option: str = '--report') -> Iterator[Path]:
    """Yield a temporary directory to write a report into; move it to ``out_dir`` at the end.

    All or nothing (:func:`feed_axis_energy.core.outputs.staged_directory`): on an exception
    the temporary directory is removed and an earlier report in ``out_dir`` stays as it was;
    on success ``out_dir`` holds exactly what was written, plus the :data:`MARKER` file.

    Parameters
    ----------
    out_dir
        Report directory: must not exist, unless ``force`` and it is empty or an earlier
        report (then replaced once the new one is complete).
    written_by
        Written into the marker file.
    force
        Replace an earlier report.
    option
        The argument ``out_dir`` comes from, for messages.

    Raises
    ------
    OutputError
        ``out_dir`` exists (without ``force``), is a symbolic link, a file, or a directory
        that is neither empty nor an earlier report.
    """
    with staged_directory(out_dir, option=option, force=force,
                          replaceable=marked_or_empty(MARKER)) as tmp:
        tmp.mkdir()
        yield tmp
        (tmp / MARKER).write_text(f'written by {written_by}\n')


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
        From :func:`feed_axis_energy.core.measured.compare.compare_campaign`.
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
