"""Every node parameter is in config/graph.yaml and in the node's ``--help`` (issue 12, s. 3)."""
from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import must_run
import pytest

from pkgscan import declared_parameters, graph_parameters, ROOT

NODES = ['gcode_trajectory', 'axis_dynamics', 'energy_estimator', 'mcap_recorder',
         'measured_replay', 'opcua_bridge']


def test_every_node_found_by_the_scan():
    assert set(declared_parameters()) == set(NODES)


@pytest.mark.parametrize('node', NODES)
def test_graph_yaml_lists_every_parameter(node):
    declared = declared_parameters()[node]
    listed = graph_parameters().get(node, {})
    missing = [name for name in declared if name not in listed]
    assert not missing, f'config/graph.yaml lacks {node}: {missing}'
    unknown = sorted(set(listed) - set(declared))
    assert not unknown, f'config/graph.yaml sets parameters {node} does not declare: {unknown}'


@must_run.skipif('rclpy', importlib.util.find_spec('rclpy') is None, 'rclpy not installed')
@pytest.mark.parametrize('node', NODES)
def test_help_lists_every_parameter(node):
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT), env.get('PYTHONPATH', '')])
    done = subprocess.run([sys.executable, '-m', f'feed_axis_energy.nodes.{node}', '--help'],
                          capture_output=True, text=True, timeout=120, env=env, check=False)
    assert done.returncode == 0, done.stderr
    listed = [line.split(':')[0].strip() for line in done.stdout.splitlines()
              if line.startswith('  ') and ':' in line]
    missing = [name for name in declared_parameters()[node] if name not in listed]
    assert not missing, f'{node} --help lacks {missing}'
