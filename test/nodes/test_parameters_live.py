"""Run-time parameter changes: the live ones validated and applied, the rest refused."""
import must_run
import pytest

rclpy = must_run.import_or_skip('rclpy', 'rclpy')
from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from feed_axis_energy.nodes.axis_dynamics import AxisDynamicsNode  # noqa: E402
from feed_axis_energy.nodes.energy_estimator import EnergyEstimator  # noqa: E402
from feed_axis_energy.nodes.gcode_trajectory import GcodeTrajectory  # noqa: E402
from feed_axis_energy.nodes.mcap_recorder import McapRecorder  # noqa: E402


def _set(node, name, value):
    (result,) = node.set_parameters([Parameter(name, value=value)])
    return result


@child_only
@pytest.mark.parametrize('cls', [AxisDynamicsNode, EnergyEstimator])
def test_load_kg_is_live(context, cls):
    node = cls(context=context)
    try:
        assert node.load_kg == 0.0
        result = _set(node, 'load_kg', 17.336)
        assert result.successful, result.reason
        assert node.load_kg == 17.336
        assert node.get_parameter('load_kg').value == 17.336
        for bad in (-1.0, float('nan'), float('inf')):
            result = _set(node, 'load_kg', bad)
            assert not result.successful
            assert 'load_kg' in result.reason and '>= 0 kg' in result.reason
            assert node.load_kg == 17.336          # unchanged
        result = _set(node, 'machine', '/elsewhere.yaml')
        assert not result.successful
        assert 'read at start-up' in result.reason and 'load_kg' in result.reason
        assert node.get_parameter('machine').value == ''
    finally:
        node.destroy_node()


@child_only
def test_energy_estimator_load_reaches_the_running_integrator(context):
    node = EnergyEstimator(context=context)
    try:
        class Power:   # stands in for the StreamingPower made at the first batch
            load_kg = 0.0
        node.power = Power()
        assert _set(node, 'load_kg', 5.0).successful
        assert node.power.load_kg == 5.0
    finally:
        node.destroy_node()


@child_only
def test_gcode_trajectory_stall_timeout_live_program_fixed(context, short_program):
    node = GcodeTrajectory(context=context, parameter_overrides=[
        Parameter('program', value=str(short_program)), Parameter('autostart', value=False)])
    try:
        assert _set(node, 'stall_timeout_s', 5.0).successful
        assert node.stall_timeout_s == 5.0
        assert not _set(node, 'stall_timeout_s', 0.0).successful
        result = _set(node, 'program', '/other.nc')
        assert not result.successful and 'restart the node' in result.reason
        assert node.program == str(short_program)
    finally:
        node.destroy_node()


@child_only
def test_recorder_refuses_every_change_but_not_foreign_parameters(context, tmp_path):
    node = McapRecorder(context=context, parameter_overrides=[
        Parameter('output', value=str(tmp_path / 'bag'))])
    try:
        result = _set(node, 'chunk_period_s', 2.0)
        assert not result.successful and 'none' in result.reason
        # not declared by the node itself: left to rclpy
        assert _set(node, 'use_sim_time', True).successful
    finally:
        node.close()
        node.destroy_node()


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The tests above, in their own interpreter (see conftest.run_module_in_child)."""
    run_module_in_child(__file__)
