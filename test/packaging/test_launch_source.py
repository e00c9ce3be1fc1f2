"""The ROS 2 launch file (issue 12, section 3).

Its source is checked with ast everywhere (arguments, LifecycleNode, executables, parameter
names); loading it through ``launch`` runs only where launch and launch_ros are installed.
"""
from __future__ import annotations

import importlib.util

import pytest

from pkgscan import (console_scripts, declared_parameters, graph_parameters, LAUNCH_FILE,
                     launch_actions, launch_arguments)

REQUIRED = {'program', 'machine', 'load_kg', 'mode', 'params_file', 'namespace', 'use_sim_time',
            'autostart', 'record', 'replay', 'replay_rate'}
# parameters rclpy declares on every node
BUILT_IN = {'use_sim_time'}


def test_launch_arguments_declared():
    args = launch_arguments()
    assert REQUIRED <= set(args), sorted(REQUIRED - set(args))
    assert args['autostart'] == 'true' and args['use_sim_time'] == 'false'


def test_gcode_trajectory_is_lifecycle_node():
    kinds = {exe: kind for kind, exe, _ in launch_actions()}
    assert kinds['gcode_trajectory'] == 'LifecycleNode'
    for exe in ('axis_dynamics', 'energy_estimator', 'mcap_recorder', 'measured_replay'):
        assert kinds[exe] == 'Node', exe


def test_launched_executables_and_parameters_exist():
    scripts = console_scripts()
    declared = declared_parameters()
    graph = graph_parameters()
    for _, exe, keys in launch_actions():
        assert exe in scripts, f'{exe} is not a console script in setup.py'
        unknown = keys - set(declared[exe]) - BUILT_IN
        assert not unknown, f'{exe}: the launch file sets undeclared parameters {unknown}'
        assert exe in graph, f'{exe} has no section in config/graph.yaml'


def _load_description():
    from launch.launch_description_sources import PythonLaunchDescriptionSource
    source = PythonLaunchDescriptionSource(str(LAUNCH_FILE))
    return source.get_launch_description(None)


@pytest.mark.skipif(importlib.util.find_spec('launch') is None
                    or importlib.util.find_spec('launch_ros') is None,
                    reason='launch/launch_ros not installed (no ROS 2 install here)')
def test_launch_description_loads():
    description = _load_description()
    names = {a.name for a in description.get_launch_arguments()}
    assert names == set(launch_arguments())
