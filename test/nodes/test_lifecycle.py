"""gcode_trajectory as a lifecycle node driven by hand (autostart off)."""
import pytest

rclpy = pytest.importorskip('rclpy')
from rclpy.context import Context  # noqa: E402
from rclpy.lifecycle import TransitionCallbackReturn  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from feed_axis_energy.nodes.gcode_trajectory import GcodeTrajectory  # noqa: E402


@pytest.fixture
def context(domain_id):
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    yield ctx
    rclpy.shutdown(context=ctx)


def _node(context, program):
    return GcodeTrajectory(context=context, parameter_overrides=[
        Parameter('program', value=str(program)), Parameter('autostart', value=False)])


def test_configure_activate_deactivate_cleanup(context, short_program):
    node = _node(context, short_program)
    try:
        assert node.motion is None
        assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert node.motion.n_samples > 2000   # 2 s move + dwell at 1 kHz
        assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert node._streaming
        assert node.trigger_deactivate() == TransitionCallbackReturn.SUCCESS
        assert not node._streaming
        assert node.trigger_cleanup() == TransitionCallbackReturn.SUCCESS
        assert node.motion is None
    finally:
        node.destroy_node()


def test_configure_fails_on_a_bad_program(context, tmp_path):
    bad = tmp_path / 'bad.nc'
    bad.write_text('G1 X10 F100\nG5 X3\n')
    node = _node(context, bad)
    try:
        assert node.trigger_configure() == TransitionCallbackReturn.FAILURE
        assert 'bad.nc' in node._error
    finally:
        node.destroy_node()
