"""
The main job's graph (``saw-ros demo``) for ``ros2 launch saw_ros saw.launch.py``.

    ros2 launch saw_ros saw.launch.py [duration:=10.0] [real_time_factor:=0.5] [slope:=0.0]
        [camera:=true] [controller:=false] [target_speed:=0.05] [record:=true] [bag:=<dir>]
        [report_path:=<file>] [foxglove:=false]

``ros2 launch saw_ros saw.launch.py --show-args`` lists them with their meaning (ARGUMENTS below).

Nodes and parameters come from the table ``run_pipeline`` uses
(``saw_ros.graph.pipeline.node_parameters``), so both start the same graph: simulator,
comparison, vision and camera at once, the consumers under SCHED_BATCH (``chrt --batch 0``,
as the pipeline's ``batch_policy``); the recorder only once camera, comparison and vision said
ready on /saw/ready (the probe ``python -m saw_ros.ros.ready``), and the simulator steps only once
the recorder has subscribed to its topics (``wait_for_subscribers``). Fast DDS reads
``share/saw_ros/msg_config/fastdds.xml`` unless the environment names a profile already. When the
comparison node has published its final summary and exits, the launch shuts down: the recorder
closes its bag (``bags/<date-time>_launch`` unless ``bag`` is given).

``camera:=false`` runs the simulator alone (no camera, tracker or comparison: nothing to compare),
until ``duration``, e.g. to watch the robot model at real time. ``controller:=true`` adds the
speed controller closing the loop through the camera (``saw-ros demo --controller``);
``foxglove:=true`` the Foxglove WebSocket bridge (``foxglove_bridge``, 127.0.0.1:8765).

Unlike ``saw-ros demo`` the graph runs in the caller's ROS domain (ROS_DOMAIN_ID, discovery
range), so that RViz, Foxglove or ``ros2 topic`` can watch it. docs/ros.md.
"""
import os
import shutil
import sys

from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, EmitEvent, ExecuteProcess, OpaqueFunction,
                            RegisterEventHandler, SetEnvironmentVariable)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch_ros.actions import Node
from saw_ros.graph.pipeline import MATCH_TIMEOUT, node_parameters, READY_NODES
from saw_ros.interface import topics
from saw_ros.interface.config import config_path

# name, default, description: the defaults of node_parameters() and `saw-ros demo`.
ARGUMENTS = (
    ('duration', '10.0', 'simulated seconds, then the run ends'),
    ('real_time_factor', '0.5', 'simulated seconds per wall-clock second'),
    ('slope', '0.0', 'slope of the surfaces, rad (conditions.slope)'),
    ('camera', 'true', 'run the camera, the tracker (vision) and the comparison; false: the '
                       'simulator alone, until duration'),
    ('controller', 'false', 'also run speed_controller, holding target_speed through the camera'),
    ('target_speed', '0.05', "the controller's target speed, m/s"),
    ('record', 'true', 'record the run with the recorder node'),
    ('bag', '', 'bag directory; empty: bags/<date-time>_launch'),
    ('report_path', '', "the comparison's final summary as JSON here; empty: none"),
    ('foxglove', 'false', 'also run foxglove_bridge: the graph live in Foxglove over its '
                          'WebSocket protocol, on 127.0.0.1:8765'),
)
TRUE = ('true', '1', 'yes')
PROFILE_VARIABLES = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def _graph(context):
    value = context.launch_configurations.get
    record, camera, controller = (value(name).lower() in TRUE
                                  for name in ('record', 'camera', 'controller'))
    if controller and not camera:
        raise ValueError('controller:=true needs camera:=true: the controller holds the speed the '
                         'camera and tracker measure')
    slope = float(value('slope'))
    params = node_parameters(float(value('duration')), float(value('real_time_factor')),
                             {'conditions.slope': slope} if slope else {}, record,
                             report_path=value('report_path') or None,
                             controller=({'target_speed': float(value('target_speed'))}
                                         if controller else None))
    if not camera:
        params = {'simulator': params['simulator']}
    # The consumers must not preempt the simulator (saw_ros.graph.process.batch_policy).
    batch = 'chrt --batch 0' if shutil.which('chrt') else None
    # No `name=`: it would remap every node of the process (the recorder has two) to that name.
    # exec_name labels the output, which would otherwise read 'chrt'.
    nodes = {name: Node(package='saw_ros', executable=name, exec_name=name, output='screen',
                        parameters=[values], prefix=None if name == 'simulator' else batch)
             for name, values in params.items()}
    actions = list(nodes.values())
    if value('foxglove').lower() in TRUE:
        # With a recorder, clients' subscriptions wait for the first step: a client would
        # otherwise be the subscriber the simulator waits for, ahead of the recorder.
        actions.append(Node(package='saw_ros', executable='foxglove_bridge',
                            exec_name='foxglove_bridge', output='screen', prefix=batch,
                            parameters=[{'hold_until_clock': record}]))
    if record:
        # A list: launch_ros writes parameters as YAML, and a tuple is a Python-only YAML tag.
        recorded = {'topics': list(topics.recorded_topics())}
        recorded.update({'output': value('bag')} if value('bag') else {'label': 'launch'})
        recorder = Node(package='saw_ros', executable='recorder', exec_name='recorder',
                        output='screen', parameters=[recorded], prefix=batch)
        # A recorder that ends first (it could not start) leaves the simulator waiting for its
        # subscriptions: the run ends with it.
        actions.append(RegisterEventHandler(OnProcessExit(
            target_action=recorder,
            on_exit=[EmitEvent(event=Shutdown(reason='the recorder ended'))])))
        if camera:
            probe = ExecuteProcess(
                cmd=[sys.executable, '-m', 'saw_ros.ros.ready', '--nodes', ','.join(READY_NODES),
                     '--timeout', f'{3 * MATCH_TIMEOUT:g}'], name='ready', output='screen')
            actions += [probe, RegisterEventHandler(OnProcessExit(target_action=probe,
                                                                  on_exit=[recorder]))]
        else:
            # The simulator alone needs no probe: it waits for the recorder's subscriptions.
            actions.append(recorder)
    # The run ends with the comparison's summary, or without a camera at the simulator's end.
    last, reason = ((nodes['comparison'], 'the comparison published its summary') if camera
                    else (nodes['simulator'], 'the simulator ran its duration'))
    actions.append(RegisterEventHandler(OnProcessExit(
        target_action=last, on_exit=[EmitEvent(event=Shutdown(reason=reason))])))
    return actions


def generate_launch_description():
    actions = [DeclareLaunchArgument(name, default_value=default, description=text)
               for name, default, text in ARGUMENTS]
    if not any(os.environ.get(v) for v in PROFILE_VARIABLES):
        actions.append(SetEnvironmentVariable(PROFILE_VARIABLES[0],
                                              str(config_path('fastdds.xml'))))
    actions.append(OpaqueFunction(function=_graph))
    return LaunchDescription(actions)
