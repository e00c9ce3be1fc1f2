"""Report directories: written whole or not at all, marked so that a later run may replace them."""
from __future__ import annotations

from contextlib import contextmanager
import os
from pathlib import Path
import re
from typing import Iterator

from ..outputs import marked_or_empty, REPORT_MARKER, staged_directory

__all__ = ['MARKER', 'report_stem', 'staged_report']

MARKER = REPORT_MARKER
"""File that marks a directory written by :func:`write_report` (it may then be replaced)."""


def report_stem(i: int, name: str) -> str:
    """File stem of the images of run ``i``: its number and its name made safe."""
    return f'{i + 1:02d}_' + re.sub(r'[^A-Za-z0-9_.-]+', '_', name).strip('._')


@contextmanager
def staged_report(out_dir: str | os.PathLike[str], *, written_by: str, force: bool = False,
                  option: str = '--report') -> Iterator[Path]:
    """Yield a temporary directory to write a report into; move it to ``out_dir`` at the end.

    All or nothing (:func:`feed_axis_energy.outputs.staged_directory`): on an exception
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
