"""ROS 2 launch file: the same node graph as ``feed-axis-energy launch``.

    ros2 launch feed_axis_energy feed_axis_energy.launch.py program:=/path/p.nc \
        record:=/tmp/run1 load_kg:=5.0 mode:=fast

Parameters come from ``config/graph.yaml``; the arguments override them. The launch ends
when energy_estimator exits (it does after publishing block_energy); with ``record`` the
recorder closes its bag first. Every node gets ``FAE_PARENT_PID`` (this launch process), so
it arms the parent-death signal (``feed_axis_energy.lifeline``) and stops if the launch
process is killed, as with ``feed-axis-energy launch``.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = 'feed_axis_energy'


def _graph(context):
    share = get_package_share_directory(PACKAGE)
    params = os.path.join(share, 'config', 'graph.yaml')
    arg = {k: LaunchConfiguration(k).perform(context)
           for k in ('program', 'machine', 'load_kg', 'mode', 'record')}
    program = arg['program'] or os.path.join(share, 'config', 'programs',
                                             'demonstrator_f100.nc')
    machine = {'machine': arg['machine']} if arg['machine'] else {}
    record = arg['record']
    # the nodes are this process's children: tie their lives to it (lifeline.arm_from_env)
    lifeline = {'FAE_PARENT_PID': str(os.getpid())}
    energy = Node(package=PACKAGE, executable='energy_estimator', name='energy_estimator',
                  parameters=[params, {**machine, 'load_kg': float(arg['load_kg']),
                                       'exit_at_end': True}], output='screen',
                  additional_env=lifeline)
    nodes = [
        Node(package=PACKAGE, executable='gcode_trajectory', name='gcode_trajectory',
             parameters=[params, {**machine, 'program': program, 'mode': arg['mode'],
                                  'ack_recorder': bool(record)}], output='screen',
             additional_env=lifeline),
        Node(package=PACKAGE, executable='axis_dynamics', name='axis_dynamics',
             parameters=[params, {**machine, 'load_kg': float(arg['load_kg'])}],
             output='screen', additional_env=lifeline),
        energy,
    ]
    done = energy
    if record:
        done = Node(package=PACKAGE, executable='mcap_recorder', name='mcap_recorder',
                    parameters=[params, {'output': record, 'exit_at_end': True}],
                    output='screen', additional_env=lifeline)
        nodes.insert(0, done)
    nodes.append(RegisterEventHandler(OnProcessExit(
        target_action=done, on_exit=[EmitEvent(event=Shutdown(reason='program finished'))])))
    return nodes


def generate_launch_description():
    """Declare the arguments and the graph."""
    return LaunchDescription([
        DeclareLaunchArgument('program', default_value='', description='NC program file'),
        DeclareLaunchArgument('machine', default_value='', description='machine config YAML'),
        DeclareLaunchArgument('load_kg', default_value='0.0', description='workpiece [kg]'),
        DeclareLaunchArgument('mode', default_value='fast', description='fast | realtime'),
        DeclareLaunchArgument('record', default_value='', description='bag directory'),
        OpaqueFunction(function=_graph),
    ])
