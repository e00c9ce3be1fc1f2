"""gcode_trajectory as a lifecycle node driven by hand (autostart off)."""
import must_run
import pytest

rclpy = must_run.import_or_skip('rclpy', 'rclpy')
from conftest import child_only, IN_CHILD, run_module_in_child  # noqa: E402
from rclpy.lifecycle import TransitionCallbackReturn  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from feed_axis_energy.nodes.gcode_trajectory import GcodeTrajectory  # noqa: E402


def _node(context, program):
    return GcodeTrajectory(context=context, parameter_overrides=[
        Parameter('program', value=str(program)), Parameter('autostart', value=False)])


@child_only
def test_configure_activate_deactivate_cleanup(context, short_program):
    node = _node(context, short_program)
    try:
        assert node.survey is None
        assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert node.survey.n_samples > 2000   # 2 s move + dwell at 1 kHz
        assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert node._streaming
        assert node.trigger_deactivate() == TransitionCallbackReturn.SUCCESS
        assert not node._streaming
        assert node.trigger_cleanup() == TransitionCallbackReturn.SUCCESS
        assert node.survey is None
    finally:
        node.destroy_node()


@child_only
def test_configure_fails_on_a_bad_program(context, tmp_path):
    bad = tmp_path / 'bad.nc'
    bad.write_text('G1 X10 F100\nG5 X3\n')
    node = _node(context, bad)
    try:
        assert node.trigger_configure() == TransitionCallbackReturn.FAILURE
        assert 'bad.nc' in node._error
    finally:
        node.destroy_node()


def _lifecycle_call(node, executor, srv_type, name, request, timeout_s=15.0):
    client = node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=timeout_s), f'{name} not offered'
    future = client.call_async(request)
    executor.spin_until_future_complete(future, timeout_sec=timeout_s)
    assert future.done(), f'{name} did not answer'
    return future.result()


@child_only
def test_lifecycle_services_under_the_nodes_executor(tmp_path, short_program, node_env,
                                                     context):
    """~/change_state and ~/get_state of a gcode_trajectory process (runner: EventsExecutor)."""
    import subprocess
    import sys
    from lifecycle_msgs.msg import State, Transition
    from lifecycle_msgs.srv import ChangeState, GetState
    from feed_axis_energy.nodes.runner import make_executor

    def start(name, params, ns):
        cmd = [sys.executable, '-m', f'feed_axis_energy.nodes.{name}', '--ros-args',
               '-r', f'__ns:=/{ns}']
        for k, v in params.items():
            cmd += ['-p', f'{k}:={v}']
        return subprocess.Popen(cmd, env=node_env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)

    bad = tmp_path / 'bad.nc'
    bad.write_text('G21 G90\nG1 X10 F100\nG5 X3\n')
    procs = [start('gcode_trajectory', {'program': short_program, 'autostart': False,
                                        'ack_recorder': False}, 'good'),
             start('axis_dynamics', {}, 'good'),
             start('energy_estimator', {'exit_at_end': True}, 'good'),
             start('gcode_trajectory', {'program': bad, 'autostart': False}, 'bad')]
    node = rclpy.create_node('cell_controller', context=context)
    ex = make_executor(context=context)
    ex.add_node(node)

    def state(ns):
        return _lifecycle_call(node, ex, GetState, f'/{ns}/gcode_trajectory/get_state',
                               GetState.Request()).current_state.id

    def change(ns, transition):
        req = ChangeState.Request()
        req.transition.id = transition
        return _lifecycle_call(node, ex, ChangeState, f'/{ns}/gcode_trajectory/change_state',
                               req).success
    try:
        assert state('good') == State.PRIMARY_STATE_UNCONFIGURED
        assert change('good', Transition.TRANSITION_CONFIGURE)
        assert state('good') == State.PRIMARY_STATE_INACTIVE
        assert change('good', Transition.TRANSITION_ACTIVATE)
        assert state('good') == State.PRIMARY_STATE_ACTIVE
        estimator = procs[2]
        out, _ = estimator.communicate(timeout=30)   # the program ran to its end
        assert estimator.returncode == 0, out
        assert 'program end' in out

        assert not change('bad', Transition.TRANSITION_CONFIGURE)
        assert state('bad') == State.PRIMARY_STATE_UNCONFIGURED
        procs[3].send_signal(2)
        out, _ = procs[3].communicate(timeout=10)
        assert 'configure failed' in out and 'bad.nc:3' in out, out
        assert 'Traceback' not in out
    finally:
        ex.shutdown()
        node.destroy_node()
        for proc in procs:
            proc.kill()
            out, _ = proc.communicate(timeout=5)
            # shown by pytest only when the test fails: what each node logged
            print(f'--- {proc.args[2]} (exit {proc.returncode}) ---\n{out or ""}')


@pytest.mark.skipif(IN_CHILD, reason='the wrapper itself')
def test_in_a_child_process():
    """The tests above, in their own interpreter (see conftest.run_module_in_child)."""
    run_module_in_child(__file__)
