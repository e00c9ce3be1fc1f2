"""Report of a campaign comparison: the paper's plots per run and one ``index.html``.

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
import shutil
import tempfile
from typing import Iterator

from feed_axis_energy.core.measured.compare import CampaignComparison

from .html import render_index
from .plots import PLOT_KINDS, write_run_plots

__all__ = ['MARKER', 'PLOT_KINDS', 'staged_report', 'write_report']

MARKER = '.feed_axis_energy_report'
"""File that marks a directory written by :func:`write_report` (it may then be replaced)."""


def _stem(i: int, name: str) -> str:
    return f'{i + 1:02d}_' + re.sub(r'[^A-Za-z0-9_.-]+', '_', name).strip('._')


def _check_target(out: Path) -> None:
    if not out.exists():
        return
    if not out.is_dir():
        msg = f'{out} exists and is not a directory; choose another report directory'
        raise FileExistsError(msg)
    if any(out.iterdir()) and not (out / MARKER).exists():
        msg = (f'{out} exists, is not empty and was not written by a feed-axis-energy report; '
               'choose another report directory')
        raise FileExistsError(msg)


@contextmanager
def staged_report(out_dir: str | os.PathLike[str], *, written_by: str) -> Iterator[Path]:
    """Yield a temporary directory to write a report into; move it to ``out_dir`` at the end.

    All or nothing: on an exception the temporary directory is removed and an earlier report
    in ``out_dir`` stays as it was; on success ``out_dir`` (new, empty, or an earlier report,
    which is replaced) holds exactly what was written, plus the :data:`MARKER` file.

    Raises
    ------
    FileExistsError
        If ``out_dir`` is a file or a non-empty directory that is not an earlier report.
    """
    out = Path(out_dir)
    _check_target(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f'.{out.name}.tmp-', dir=out.parent))
    try:
        yield tmp
        (tmp / MARKER).write_text(f'written by {written_by}\n')
        os.chmod(tmp, 0o755)  # mkdtemp makes it private; a report is meant to be read
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f'.{out.name}.old-', dir=out.parent))
            old.rmdir()
            out.rename(old)
            try:
                tmp.rename(out)
            except OSError:
                old.rename(out)     # put the earlier report back
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def write_report(comparison: CampaignComparison, out_dir: str | os.PathLike[str], *,
                 dpi: int = 100) -> Path:
    """Write the plots of every run and ``index.html`` into ``out_dir``, all or nothing.

    Everything is written into a temporary directory next to ``out_dir`` and moved into
    place at the end, so a failure leaves no half-written report (and an earlier report in
    ``out_dir`` untouched).

    Parameters
    ----------
    comparison
        From :func:`feed_axis_energy.core.measured.compare.compare_campaign`.
    out_dir
        Report directory: new, empty, or an earlier report (replaced).
    dpi
        Resolution of the PNG files.

    Returns
    -------
    pathlib.Path
        The ``index.html`` file.

    Raises
    ------
    FileExistsError
        If ``out_dir`` is a file or a non-empty directory that is not an earlier report.
    """
    out = Path(out_dir)
    with staged_report(out, written_by='feed-axis-energy compare --report') as tmp:
        images = {run.name: write_run_plots(run, tmp, _stem(i, run.name), dpi=dpi)
                  for i, run in enumerate(comparison.runs)}
        (tmp / 'index.html').write_text(render_index(comparison, images), encoding='utf-8')
    return out / 'index.html'
