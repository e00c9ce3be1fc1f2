"""Where the tests find the shared data (G-code corpus, measured runs, the oracle tool).

The shared data is not part of the repository: it lives in a directory ``shared`` beside
the clone (``<repository>/../shared``, as on CI), or wherever the environment variable
``FAE_SHARED`` points. The candidates, in order: ``$FAE_SHARED`` (when set and not empty),
then ``<repository>/../shared``. A test that needs the data asks :func:`shared_path` for
the file or folder inside it and skips with :func:`need_shared` (or a
``must_run.skipif('shared', ...)`` mark quoting :data:`SKIP_REASON`) when no candidate holds
it, so the suite passes without the data and says how to give it; with ``shared`` in
``FAE_MUST_RUN`` (CI) those skips fail instead (``test/must_run.py``). Tests that load
``config/campaigns/umich_mill.yaml`` as it is need the data at ``../shared`` itself: the
manifest names its files relative to itself.

Tests import it as ``from shared_data import ...`` (``test/`` is on ``sys.path`` through
``test/conftest.py``).
"""
from __future__ import annotations

from collections.abc import Iterable
import importlib.util
from pathlib import Path
import sys

import must_run

__all__ = ['REPO', 'SKIP_REASON', 'shared_candidates', 'shared_path', 'need_shared',
           'bench_corpus']

REPO = Path(__file__).resolve().parents[1]
SKIP_REASON = 'shared data not found (set FAE_SHARED to the shared directory)'


def _bench_lookup():
    """``bench/shared_lookup.py``, loaded by path under its own module name: the one place
    that says where the shared data is looked up (standard library only)."""
    name = 'fae_bench_shared_lookup'
    module = sys.modules.get(name)
    if module is None:
        spec = importlib.util.spec_from_file_location(
            name, REPO / 'bench' / 'shared_lookup.py')
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return module


def bench_corpus():
    """``bench/corpus.py`` (the corpus reader the benchmarks use), loaded once by path as
    ``fae_bench_corpus``."""
    name = 'fae_bench_corpus'
    module = sys.modules.get(name)
    if module is None:
        spec = importlib.util.spec_from_file_location(name, REPO / 'bench' / 'corpus.py')
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module   # dataclasses look their module up by name
        spec.loader.exec_module(module)
    return module


def shared_candidates() -> list[Path]:
    """Directories that may hold the shared data, in the order they are tried:
    ``$FAE_SHARED`` (when set and not empty), then ``<repository>/../shared``
    (:func:`bench/shared_lookup.shared_candidates`)."""
    return _bench_lookup().shared_candidates()


def shared_path(*parts: str, needs: Iterable[str] = ()) -> Path | None:
    """The first candidate's ``parts`` that exists (and holds ``needs``), or ``None``
    (:func:`bench/shared_lookup.shared_path`)."""
    return _bench_lookup().shared_path(*parts, needs=tuple(needs))


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
        must_run.skip('shared', f'{what} not found in the shared data (set FAE_SHARED to '
                                'the shared directory; default: ../shared beside the '
                                'repository)')
    return path
