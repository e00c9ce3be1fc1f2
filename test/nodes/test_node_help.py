"""Every node executable answers --help without starting ROS."""
import subprocess
import sys

import must_run
import pytest

must_run.import_or_skip('rclpy', 'rclpy')


@pytest.mark.parametrize('node, param', [
    ('gcode_trajectory', 'program'), ('axis_dynamics', 'load_kg'),
    ('energy_estimator', 'load_kg'), ('measured_replay', 'rate'),
    ('mcap_recorder', 'chunk_period_s'), ('opcua_bridge', 'opcua_port'),
])
def test_help(node: str, param: str) -> None:
    proc = subprocess.run([sys.executable, '-m', f'feed_axis_energy.nodes.{node}', '--help'],
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 0, proc.stderr
    assert f'ros2 run feed_axis_energy {node}' in proc.stdout
    assert f'  {param}:' in proc.stdout
