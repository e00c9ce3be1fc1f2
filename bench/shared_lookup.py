"""Where the benchmark scripts find the shared data (G-code corpus, measured runs, oracle tool).

The shared data is not part of the repository: it lives in a directory ``shared`` beside
the clone (``<repository>/../shared``), or wherever the environment variable ``FAE_SHARED``
points. The candidates, in order: ``$FAE_SHARED`` (when set and not empty), then
``<repository>/../shared``. A script that finds nothing says so, naming ``FAE_SHARED``
(:data:`HINT`), and exits 1.

Standard library only: ``bench/oracle_trace.py`` imports it under the system Python that
has LinuxCNC's ``gcode`` module. Scripts import it as ``from shared_lookup import ...``
(``bench/`` is ``sys.path[0]`` when a script of it runs; a script loaded from elsewhere
puts ``bench/`` on the path first, as ``bench/corpus.py`` does). Its name differs from the
tests' ``test/shared_data.py`` so that a test loading a bench script gets this one.
"""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ['REPO', 'HINT', 'shared_candidates', 'shared_path', 'umich_data']

REPO = Path(__file__).resolve().parents[1]
HINT = 'set FAE_SHARED to the shared directory (default: ../shared beside the repository)'


def shared_candidates() -> list[Path]:
    """Directories that may hold the shared data, in the order they are tried.

    Returns
    -------
    list of pathlib.Path
        ``$FAE_SHARED`` (when set and not empty), then ``<repository>/../shared``.
    """
    out = []
    given = os.environ.get('FAE_SHARED')
    if given:
        out.append(Path(given))
    out.append(REPO.parent / 'shared')
    return out


def shared_path(*parts: str, needs: tuple[str, ...] = ()) -> Path | None:
    """The first candidate's ``parts`` that exists (and holds ``needs``), or ``None``.

    Parameters
    ----------
    *parts
        Path components inside the shared directory (none: the directory itself).
    needs
        Names that must exist inside the found path, e.g. ``('oracle.json',)``.

    Returns
    -------
    pathlib.Path or None
        The resolved path, or ``None`` when no candidate holds it.
    """
    for base in shared_candidates():
        path = base.joinpath(*parts)
        if path.exists() and all((path / name).exists() for name in needs):
            return path.resolve()
    return None


def umich_data() -> Path | None:
    """The UMich CNC mill runs (``data/umich-cnc-mill``), or ``None``."""
    return shared_path('data', 'umich-cnc-mill', needs=('experiment_03.csv',))
