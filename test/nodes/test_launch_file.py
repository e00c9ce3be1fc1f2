"""The ROS 2 launch file (loading it is skipped where ``launch``/``launch_ros`` are not
installed)."""
import importlib.util
from pathlib import Path

import pytest

LAUNCH = Path(__file__).resolve().parents[2] / 'launch' / 'feed_axis_energy.launch.py'


def test_launch_description_declares_the_arguments():
    pytest.importorskip('launch')
    pytest.importorskip('launch_ros')
    spec = importlib.util.spec_from_file_location('fae_launch', LAUNCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    desc = module.generate_launch_description()
    names = {a.name for a in desc.get_launch_arguments()}
    assert {'program', 'machine', 'load_kg', 'mode', 'record', 'params_file', 'namespace',
            'use_sim_time', 'autostart', 'replay', 'replay_rate'} <= names


def test_launch_file_ties_every_node_to_the_launch_process():
    """The env variable name in the launch file is lifeline's (checked without launch)."""
    from feed_axis_energy import lifeline
    text = LAUNCH.read_text()
    assert f"'{lifeline.ENV}': str(os.getpid())" in text
    assert text.count('Node(') == text.count('additional_env=lifeline')
