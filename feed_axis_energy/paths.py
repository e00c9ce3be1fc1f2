"""Where the shipped configs and example programs live.

Three places, tried in this order (the first that holds ``graph.yaml`` wins):

1. the source tree's ``config/`` beside the package (a clone, or the editable install of
   ``scripts/_venv.sh``);
2. the package data ``feed_axis_energy/config/`` of an installed package, found through
   :mod:`importlib.resources` (``pip install .`` or a wheel; ``setup.py`` puts it there);
3. ``share/feed_axis_energy/config`` of a ROS 2 install, found through the ament index.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ['config_dir', 'config_candidates', 'default_machine', 'program_path']

PACKAGE = 'feed_axis_energy'
_MARKER = 'graph.yaml'


def _source_tree() -> Path:
    return Path(__file__).resolve().parent.parent / 'config'


def _package_data() -> Path | None:
    try:
        root = resources.files(PACKAGE) / 'config'
    except (ModuleNotFoundError, TypeError):  # pragma: no cover - the package is importable
        return None
    # an installed package is a directory on disk (setup.py: zip_safe=False)
    return root if isinstance(root, Path) else None


def _ament_share() -> Path | None:
    try:
        from ament_index_python.packages import (get_package_share_directory,
                                                 PackageNotFoundError)
    except ImportError:
        return None
    try:
        return Path(get_package_share_directory(PACKAGE)) / 'config'
    except (PackageNotFoundError, ValueError, OSError):
        return None


def config_candidates() -> list[tuple[str, Path]]:
    """Return ``(kind, path)`` of every place looked at, in the order of the module docstring."""
    found = [('source tree', _source_tree())]
    data = _package_data()
    if data is not None:
        found.append(('package data', data))
    share = _ament_share()
    if share is not None:
        found.append(('ament index', share))
    return found


def config_dir() -> Path:
    """Return the ``config/`` directory (see the module docstring for where it is looked for).

    Returns
    -------
    Path
        The first candidate holding ``graph.yaml``; the source tree's path if none does (the
        caller's error then names a path the user recognises).
    """
    candidates = config_candidates()
    for _kind, path in candidates:
        if (path / _MARKER).is_file():
            return path
    return candidates[0][1]


def default_machine() -> Path:
    """Return the embedded default machine: the paper's demonstrator."""
    return config_dir() / 'demonstrator.yaml'


def program_path(name: str) -> Path:
    """Return a shipped example program by file name."""
    return config_dir() / 'programs' / name
