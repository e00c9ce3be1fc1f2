"""ROS 2 launch file: the same node graph as ``feed-axis-energy launch``.

    ros2 launch feed_axis_energy feed_axis_energy.launch.py program:=/path/p.nc \
        record:=/tmp/run1 load_kg:=5.0 mode:=fast

Arguments (``--show-args`` lists them): ``program``, ``machine``, ``load_kg``, ``mode``,
``params_file`` (node parameters; default the installed ``config/graph.yaml``), ``namespace``
(every node and relative topic), ``use_sim_time``, ``autostart`` (false: ``gcode_trajectory``
waits in the unconfigured state for a lifecycle manager or ``ros2 lifecycle set``),
``record`` (bag directory), ``replay`` and ``replay_rate`` (a measured-run bag played by
``measured_replay`` beside the simulation; recorded with ``record``). The arguments override
the parameter file. ``gcode_trajectory`` is a managed node and is started as a
``LifecycleNode``, so launch sees its transitions. The launch ends when energy_estimator exits
(it does after publishing block_energy); with ``record`` the recorder closes its bag first.
Every node gets ``FAE_PARENT_PID`` (this launch process), so it arms the parent-death signal
(``feed_axis_energy.lifeline``) and stops if the launch process is killed, as with
``feed-axis-energy launch``.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node
import yaml

PACKAGE = 'feed_axis_energy'
# recorded in addition to the recorder's default topics when a measured run is replayed
MEASURED_TOPICS = ['measured/power', 'measured/kinematics']

ARGUMENTS = [
    ('program', '', 'NC program file (empty: config/programs/demonstrator_f100.nc)'),
    ('machine', '', 'machine config YAML (empty: the shipped demonstrator)'),
    ('load_kg', '0.0', 'workpiece mass on the load axis [kg]'),
    ('mode', 'fast', 'fast (simulated time, /clock) | realtime (wall-clock pacing)'),
    ('params_file', '', 'node parameter YAML (empty: the installed config/graph.yaml)'),
    ('namespace', '', 'namespace of every node and relative topic'),
    ('use_sim_time', 'false', 'nodes take time from /clock'),
    ('autostart', 'true', 'gcode_trajectory configures and activates itself; false: it '
                          'waits for a lifecycle manager (ros2 lifecycle set ...)'),
    ('record', '', 'bag directory to create (empty: no recording)'),
    ('replay', '', 'measured-run bag directory to play on measured/* (empty: none)'),
    ('replay_rate', '1.0', 'replay time scale: 1 original, 2 twice as fast, 0 as acked'),
]


def _flag(text: str, name: str) -> bool:
    value = text.strip().lower()
    if value not in ('true', 'false'):
        msg = f'launch argument {name} must be true or false, got {text[:60]!r}'
        raise ValueError(msg)
    return value == 'true'


def _recorder_topics(params: str) -> list[str]:
    """The recorder's ``topics`` from the parameter file, plus the measured ones."""
    with open(params, encoding='utf-8') as stream:
        data = yaml.safe_load(stream) or {}
    node = data.get('mcap_recorder', {}).get('ros__parameters', {})
    topics = list(node.get('topics', ['setpoints', 'axis_state', 'power', 'block_energy',
                                      'program/end']))
    return topics + [t for t in MEASURED_TOPICS if t not in topics]


def _graph(context):
    share = get_package_share_directory(PACKAGE)
    arg = {name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS}
    params = arg['params_file'] or os.path.join(share, 'config', 'graph.yaml')
    program = arg['program'] or os.path.join(share, 'config', 'programs',
                                             'demonstrator_f100.nc')
    common = {'use_sim_time': _flag(arg['use_sim_time'], 'use_sim_time')}
    if arg['machine']:
        common['machine'] = arg['machine']
    load = {'load_kg': float(arg['load_kg'])}
    record, replay = arg['record'], arg['replay']
    ns = arg['namespace']
    # the nodes are this process's children: tie their lives to it (lifeline.arm_from_env)
    lifeline = {'FAE_PARENT_PID': str(os.getpid())}
    shared = {'namespace': ns, 'output': 'screen'}
    energy = Node(package=PACKAGE, executable='energy_estimator', name='energy_estimator',
                  parameters=[params, {**common, **load, 'exit_at_end': True}],
                  additional_env=lifeline, **shared)
    nodes = [
        LifecycleNode(package=PACKAGE, executable='gcode_trajectory', name='gcode_trajectory',
                      parameters=[params, {**common, 'program': program, 'mode': arg['mode'],
                                           'autostart': _flag(arg['autostart'], 'autostart'),
                                           'ack_recorder': bool(record)}],
                      additional_env=lifeline, **shared),
        Node(package=PACKAGE, executable='axis_dynamics', name='axis_dynamics',
             parameters=[params, {**common, **load}], additional_env=lifeline, **shared),
        energy,
    ]
    if replay:
        # its end marker goes to measured/end: program/end belongs to gcode_trajectory
        nodes.append(Node(package=PACKAGE, executable='measured_replay', name='measured_replay',
                          parameters=[params, {'use_sim_time': common['use_sim_time'],
                                               'bag': replay,
                                               'rate': float(arg['replay_rate'])}],
                          remappings=[('program/end', 'measured/end')],
                          additional_env=lifeline, **shared))
    done = energy
    if record:
        recorder = {'use_sim_time': common['use_sim_time'], 'output': record,
                    'exit_at_end': True}
        if replay:
            recorder['topics'] = _recorder_topics(params)
        done = Node(package=PACKAGE, executable='mcap_recorder', name='mcap_recorder',
                    parameters=[params, recorder], additional_env=lifeline, **shared)
        nodes.insert(0, done)
    nodes.append(RegisterEventHandler(OnProcessExit(
        target_action=done, on_exit=[EmitEvent(event=Shutdown(reason='program finished'))])))
    return nodes


def generate_launch_description():
    """Declare the arguments and the graph."""
    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=text)
          for name, default, text in ARGUMENTS),
        OpaqueFunction(function=_graph),
    ])
