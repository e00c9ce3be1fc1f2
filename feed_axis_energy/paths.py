"""Where the shipped configs and example programs live (source tree or ROS 2 install)."""
from __future__ import annotations

from pathlib import Path

__all__ = ['config_dir', 'default_machine', 'program_path']


def config_dir() -> Path:
    """Return the ``config/`` directory: the source tree's, else the ament share directory."""
    here = Path(__file__).resolve().parent.parent / 'config'
    if here.is_dir():
        return here
    try:
        from ament_index_python.packages import get_package_share_directory
    except ImportError:  # pragma: no cover - only without both source tree and ament
        return here
    return Path(get_package_share_directory('feed_axis_energy')) / 'config'


def default_machine() -> Path:
    """Return the embedded default machine: the paper's demonstrator."""
    return config_dir() / 'demonstrator.yaml'


def program_path(name: str) -> Path:
    """Return a shipped example program by file name."""
    return config_dir() / 'programs' / name
