"""The ROS 2 launch file (skipped where ``launch``/``launch_ros`` are not installed)."""
import importlib.util
from pathlib import Path

import pytest

pytest.importorskip('launch')
pytest.importorskip('launch_ros')

LAUNCH = Path(__file__).resolve().parents[2] / 'launch' / 'feed_axis_energy.launch.py'


def test_launch_description_declares_the_arguments():
    spec = importlib.util.spec_from_file_location('fae_launch', LAUNCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    desc = module.generate_launch_description()
    names = {a.name for a in desc.get_launch_arguments()}
    assert {'program', 'machine', 'load_kg', 'mode', 'record'} <= names
