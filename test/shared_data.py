"""Where the tests find the shared data (G-code corpus, measured runs, the oracle tool).

The shared data is not part of the repository: it lives in a directory ``shared`` beside
the clone (``<repository>/../shared``, as on CI), or wherever the environment variable
``FAE_SHARED`` points. The candidates, in order: ``$FAE_SHARED`` (when set and not empty),
then ``<repository>/../shared``. A test that needs the data asks :func:`shared_path` for
the file or folder inside it and skips with :func:`need_shared` (or a ``skipif`` on
:data:`SKIP_REASON`) when no candidate holds it, so the suite passes without the data and
says how to give it. Tests that load ``config/campaigns/umich_mill.yaml`` as it is need the
data at ``../shared`` itself: the manifest names its files relative to itself.

Tests import it as ``from shared_data import ...`` (``test/`` is on ``sys.path`` through
``test/conftest.py``).
"""
from __future__ import annotations

from collections.abc import Iterable
import os
from pathlib import Path

import pytest

__all__ = ['REPO', 'SKIP_REASON', 'shared_candidates', 'shared_path', 'need_shared']

REPO = Path(__file__).resolve().parents[1]
SKIP_REASON = 'shared data not found (set FAE_SHARED to the shared directory)'


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


def shared_path(*parts: str, needs: Iterable[str] = ()) -> Path | None:
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
    needs = tuple(needs)
    for base in shared_candidates():
        path = base.joinpath(*parts)
        if path.exists() and all((path / name).exists() for name in needs):
            return path.resolve()
    return None


def need_shared(*parts: str, needs: Iterable[str] = ()) -> Path:
    """:func:`shared_path`, or skip the calling test with a message naming ``FAE_SHARED``.

    Parameters
    ----------
    *parts, needs
        As for :func:`shared_path`.

    Returns
    -------
    pathlib.Path
        The path found.
    """
    path = shared_path(*parts, needs=needs)
    if path is None:
        what = '/'.join(parts) or 'the shared directory'
        pytest.skip(f'{what} not found in the shared data (set FAE_SHARED to the shared '
                    'directory; default: ../shared beside the repository)')
    return path
