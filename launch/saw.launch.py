"""
The main job's graph (``saw-ros demo``) for ``ros2 launch saw_ros saw.launch.py``.

    ros2 launch saw_ros saw.launch.py [duration:=10.0] [real_time_factor:=0.5] [slope:=0.0]
                                      [record:=true] [bag:=<dir>] [report_path:=<file>]

Nodes and parameters come from the table ``run_pipeline`` uses
(``saw_ros.graph.pipeline.node_parameters``), so both start the same graph: simulator,
comparison, vision and camera at once, the consumers under SCHED_BATCH (``chrt --batch 0``,
as the pipeline's ``batch_policy``); the recorder only once camera, comparison and vision said
ready on /saw/ready (the probe ``python -m saw_ros.ros.ready``), and the simulator steps only once
the recorder has subscribed to its topics (``wait_for_subscribers``). Fast DDS reads
``share/saw_ros/msg_config/fastdds.xml`` unless the environment names a profile already. When the
comparison node has published its final summary and exits, the launch shuts down: the recorder
closes its bag (``bags/<date-time>_launch`` unless ``bag`` is given).

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
    ('record', 'true', 'record the run with the recorder node'),
    ('bag', '', 'bag directory; empty: bags/<date-time>_launch'),
    ('report_path', '', "the comparison's final summary as JSON here; empty: none"),
)
PROFILE_VARIABLES = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def _graph(context):
    value = context.launch_configurations.get
    record = value('record').lower() in ('true', '1', 'yes')
    slope = float(value('slope'))
    params = node_parameters(float(value('duration')), float(value('real_time_factor')),
                             {'conditions.slope': slope} if slope else {}, record,
                             report_path=value('report_path') or None)
    # The consumers must not preempt the simulator (saw_ros.graph.process.batch_policy).
    batch = 'chrt --batch 0' if shutil.which('chrt') else None
    # No `name=`: it would remap every node of the process (the recorder has two) to that name.
    # exec_name labels the output, which would otherwise read 'chrt'.
    nodes = {name: Node(package='saw_ros', executable=name, exec_name=name, output='screen',
                        parameters=[values], prefix=None if name == 'simulator' else batch)
             for name, values in params.items()}
    actions = list(nodes.values())
    if record:
        probe = ExecuteProcess(
            cmd=[sys.executable, '-m', 'saw_ros.ros.ready', '--nodes', ','.join(READY_NODES),
                 '--timeout', f'{3 * MATCH_TIMEOUT:g}'], name='ready', output='screen')
        recorded = {'topics': topics.recorded_topics()}
        recorded.update({'output': value('bag')} if value('bag') else {'label': 'launch'})
        recorder = Node(package='saw_ros', executable='recorder', exec_name='recorder',
                        output='screen', parameters=[recorded], prefix=batch)
        actions += [probe, RegisterEventHandler(OnProcessExit(target_action=probe,
                                                              on_exit=[recorder]))]
    actions.append(RegisterEventHandler(OnProcessExit(
        target_action=nodes['comparison'],
        on_exit=[EmitEvent(event=Shutdown(reason='the comparison published its summary'))])))
    return actions


def generate_launch_description():
    actions = [DeclareLaunchArgument(name, default_value=default, description=text)
               for name, default, text in ARGUMENTS]
    if not any(os.environ.get(v) for v in PROFILE_VARIABLES):
        actions.append(SetEnvironmentVariable(PROFILE_VARIABLES[0],
                                              str(config_path('fastdds.xml'))))
    actions.append(OpaqueFunction(function=_graph))
    return LaunchDescription(actions)
