"""
The topic table: every topic our nodes publish, in one place (pure: no rclpy).

Each entry names the topic, its message type ('geometry_msgs/msg/PoseStamped'), its QoS profile
by name (``saw_ros.ros.qos.profile`` / ``publisher_profile`` turn it into an rclpy QoSProfile;
``saw_ros.ros.qos.message_class`` the type into its class), the node that publishes it, rate,
frame and a one-line description; which nodes subscribe to it, and what a message from anyone
else on the DDS domain can still do when it passes every check (``trust``; docs/security.md).
The nodes, the graph, the benchmarks and the tests take
topic names from here; ``msg_config/record_topics.yaml`` is generated from it
(``python -m saw_ros.interface.topics --write-record-yaml msg_config/record_topics.yaml``) and
the README's topic table is checked against it (tests/interface/test_topics.py).
"""
from __future__ import annotations

from dataclasses import dataclass
import sys
from typing import List, Optional, Tuple


@dataclass(frozen=True)
class Topic:
    name: str
    type: str           # 'package/msg/Name'  # noqa: A003
    qos: str            # profile name: stream, clock, image, tracking, latched, command
    publisher: str      # node name (several: 'camera, comparison')
    rate: str
    frame: str          # '' when the topic has no frame
    description: str
    recorded: bool = True   # by the recorder by default (msg_config/record_topics.yaml)
    subscribers: str = ''   # our nodes that subscribe (the recorder: see subscribed_by)
    trust: str = ''         # what a spoofed message that passes the checks can still do


CLOCK = '/clock'
POSE = '/saw/pose'
TWIST = '/saw/twist'
CONTACTS = '/saw/contacts'
CONTACT_WRENCH = '/saw/contact_wrench'
JOINT_STATES = '/saw/joint_states'
MOTOR = '/saw/motor'
MOTOR_COMMANDS = '/saw/motor_controller/commands'
WALLS = '/saw/walls'
IMAGE = '/saw/camera/image_raw'
IMAGE_COMPRESSED = '/saw/camera/image_raw/compressed'
CAMERA_INFO = '/saw/camera/camera_info'
TRACKING_FRONT = '/saw/tracking/front'
TRACKING_BACK = '/saw/tracking/back'
TRACKING_POSE = '/saw/tracking/pose'
TRACKING_TWIST = '/saw/tracking/twist'
TRACKING_TWIST_SMOOTHED = '/saw/tracking/twist_smoothed'
TRACKING_STEADY_SPEED = '/saw/tracking/steady_speed'
TRACKING_STATUS = '/saw/tracking/status'
COMPARISON = '/saw/comparison'
READY = '/saw/ready'
MARKERS = '/saw/markers'
TRACKING_MARKERS = '/saw/tracking/markers'
DIAGNOSTICS = '/diagnostics'
TF = '/tf'
TF_STATIC = '/tf_static'
ROBOT_DESCRIPTION = '/robot_description'
PREFIX = '/saw/'

TOPICS: Tuple[Topic, ...] = (
    Topic(CLOCK, 'rosgraph_msgs/msg/Clock', 'clock', 'simulator', '1000 Hz', '',
          'simulated time, one per step'),
    Topic(POSE, 'geometry_msgs/msg/PoseStamped', 'stream', 'simulator', '1000 Hz', 'surface',
          'robot pose (centre of mass, pitch)', subscribers='camera, comparison',
          trust='a finite pose in frame surface within 1 km, stamped in order: moves the drawn '
                'robot and the camera on its rail, and enters the comparison; a stream of '
                'earlier stamps restarts both, as a replay does'),
    Topic(TWIST, 'geometry_msgs/msg/TwistStamped', 'stream', 'simulator', '1000 Hz', 'surface',
          'robot velocity', subscribers='speed_controller',
          trust="a finite speed stamped in order: the speed controller's ground_truth "
                'feedback, so it changes the voltage commanded (within voltage_min..max)'),
    Topic(CONTACTS, 'sensor_msgs/msg/PointCloud2', 'stream', 'simulator', '1000 Hz', 'surface',
          'contact points with their forces, link, surface and slipping'),
    Topic(CONTACT_WRENCH, 'geometry_msgs/msg/WrenchStamped', 'stream', 'simulator', '1000 Hz',
          'base_link', 'net contact force and moment about the COM'),
    Topic(JOINT_STATES, 'sensor_msgs/msg/JointState', 'stream', 'simulator', '100 Hz',
          'base_link', 'helix phase, speed and motor torque (effort), and every URDF joint: '
          "each wave link's angle, its centre along x and along y, its deflection on its "
          'flexure',
          subscribers='camera, comparison, speed_controller',
          trust='a finite helix position and velocity, arrays one a name, `link_NN_flex` '
                "finite and within the joint's limit (2 A): the camera draws that wave phase "
                'and those deflections, the comparison counts helix turns with it, the speed '
                "controller's helix feedback changes the voltage commanded"),
    Topic(MOTOR, 'sensor_msgs/msg/BatteryState', 'tracking', 'simulator', '100 Hz', 'base_link',
          'motor supply voltage and current (negative: drawn; NaN at constant frequency)'),
    Topic(MOTOR_COMMANDS, 'std_msgs/msg/Float64MultiArray', 'command', 'speed_controller',
          '60 Hz (speed_controller), or yours', '',
          "the helix's drive: [voltage V] with a motor, [frequency Hz] without "
          '(ros2_control forward-command convention; saw_ros.ros.command)',
          subscribers='simulator',
          trust="one finite value in the parameter's range: drives the helix (voltage or "
                'frequency) until the next command or command_timeout'),
    Topic(WALLS, 'sensor_msgs/msg/PointCloud2', 'tracking', 'simulator', '60 Hz', 'surface',
          "the bending walls' shape (surface.foundation_stiffness > 0 only): x, y, "
          'deflection, surface', subscribers='camera',
          trust='a well-formed shape (fields, sizes, finite, two points a wall): the camera '
                'draws the walls bent that way for 0.25 s'),
    Topic(IMAGE, 'sensor_msgs/msg/Image', 'image', 'camera', '60 Hz', 'saw_camera',
          'virtual camera frames, bgr8 1280x720', recorded=False, subscribers='vision',
          trust='a bgr8/rgb8 image within max_image_pixels, stamped in order: tracked as a '
                'frame (a wrong picture gives wrong tracking outputs; a new size restarts the '
                'tracker)'),
    Topic(IMAGE_COMPRESSED, 'sensor_msgs/msg/CompressedImage', 'image', 'camera', '60 Hz',
          'saw_camera', "the same frames as JPEG, image_transport's 'compressed' format",
          subscribers='vision',
          trust='a JPEG/PNG declaring at most max_image_pixels that decodes: tracked as a '
                'frame (vision with image_transport compressed)'),
    Topic(CAMERA_INFO, 'sensor_msgs/msg/CameraInfo', 'image', 'camera', '60 Hz', 'saw_camera',
          'K, P matching the rendering', subscribers='vision',
          trust="finite K with a focal length: sets the tracker's scale (a changed principal "
                'point moves its camera, other changes restart it)'),
    Topic(TRACKING_FRONT, 'geometry_msgs/msg/PointStamped', 'tracking', 'vision', '60 Hz',
          'surface', 'front marker centre'),
    Topic(TRACKING_BACK, 'geometry_msgs/msg/PointStamped', 'tracking', 'vision', '60 Hz',
          'surface', 'back marker centre'),
    Topic(TRACKING_POSE, 'geometry_msgs/msg/PoseStamped', 'tracking', 'vision', '60 Hz',
          'surface', 'tracked robot position and pitch', subscribers='comparison',
          trust='a finite pose in frame surface within 1 km, stamped in order: enters the '
                "comparison's tracked speed"),
    Topic(TRACKING_TWIST, 'geometry_msgs/msg/TwistStamped', 'tracking', 'vision', '60 Hz',
          'surface', 'instantaneous tracked speed'),
    Topic(TRACKING_TWIST_SMOOTHED, 'geometry_msgs/msg/TwistStamped', 'tracking', 'vision',
          '60 Hz', 'surface', 'tracked speed, least squares over 0.25 s',
          subscribers='speed_controller',
          trust="a finite speed stamped in order: the speed controller's tracking feedback, "
                'so it changes the voltage commanded'),
    Topic(TRACKING_STEADY_SPEED, 'geometry_msgs/msg/TwistStamped', 'tracking', 'vision',
          '60 Hz', 'surface', 'steady mean tracked speed'),
    Topic(TRACKING_STATUS, 'diagnostic_msgs/msg/DiagnosticArray', 'tracking', 'vision', '60 Hz',
          '', 'tracker state per frame'),
    Topic(COMPARISON, 'diagnostic_msgs/msg/DiagnosticArray', 'latched', 'comparison', '~1 Hz',
          '', 'AR of simulation and tracking, their relative error'),
    Topic(MARKERS, 'visualization_msgs/msg/MarkerArray', 'tracking', 'simulator', '60 Hz',
          'surface', 'surfaces, robot and contact forces for RViz / Foxglove'),
    Topic(TRACKING_MARKERS, 'visualization_msgs/msg/MarkerArray', 'tracking', 'vision',
          '60 Hz', 'surface', "the tracker's marker centres and pose, over /saw/markers"),
    Topic(TF, 'tf2_msgs/msg/TFMessage', 'tracking', 'simulator, vision', '60 Hz', 'surface',
          'surface -> base_link and every link frame of the URDF (simulator, markers_rate, '
          'link_tf), surface -> base_link_tracked (vision, per frame); saw_ros.interface.frames'),
    Topic(TF_STATIC, 'tf2_msgs/msg/TFMessage', 'latched', 'camera', 'once', 'surface',
          'surface -> saw_camera, the camera optical frame'),
    Topic(ROBOT_DESCRIPTION, 'std_msgs/msg/String', 'latched', 'simulator', 'once', '',
          'URDF of the robot (saw_ros.interface.urdf), for robot_state_publisher and RViz'),
    Topic(DIAGNOSTICS, 'diagnostic_msgs/msg/DiagnosticArray', 'tracking',
          'simulator, camera, vision, comparison, speed_controller',
          '1 Hz, and at each fault', '', "the simulator's health: OK, WARN after recoveries, "
          'ERROR at each divergence or change the state cannot take, with the reset it made; '
          "every node's refused input messages, per topic and reason (saw_ros.ros.guard)"),
    Topic(READY, 'diagnostic_msgs/msg/DiagnosticArray', 'latched', 'camera, comparison, vision',
          'once per node', '', "node's status: name, level OK, 'ready': 'true' once its inputs "
          'matched (saw_ros.ros.ready)', recorded=False, subscribers='ready_probe',
          trust='any status: the start-up probe (python -m saw_ros.ros.ready) takes a node '
                'for ready, and the recorder may start before it'),
)
BY_NAME = {t.name: t for t in TOPICS}
# Topics rclpy itself gives every node (not ours, so not in TOPICS nor recorded), that a node of
# ours subscribes to.
PARAMETER_EVENTS = '/parameter_events'
ROSOUT = '/rosout'
RCL_TOPICS: Tuple[Topic, ...] = (
    Topic(PARAMETER_EVENTS, 'rcl_interfaces/msg/ParameterEvent', 'parameter_events',
          'every node', 'at each parameter change', '', 'parameter changes of every node',
          recorded=False, subscribers='camera, comparison',
          trust="new values for the simulator's robot, gap or conditions that a Scenario "
                'accepts: the camera draws that robot and gap, the comparison restarts with '
                'those conditions (saw_ros.ros.simulator_parameters)'),
    Topic(ROSOUT, 'rcl_interfaces/msg/Log', 'rosout', 'every node', 'per log line', '',
          "every node's log", recorded=False),
)
# The recorder subscribes to what it records (default: every recorded topic), raw: it writes the
# bytes as they came and parses none, so no message can make it fail.
RECORDER = 'recorder'


def topic(name: str) -> Topic:
    return BY_NAME[name]


def published_by(node: str) -> Tuple[Topic, ...]:
    return tuple(t for t in TOPICS if node in t.publisher.split(', '))


def subscribed_by(node: str) -> Tuple[Topic, ...]:
    """Return the topics ``node`` subscribes to (the recorder: every recorded topic)."""
    return tuple(t for t in TOPICS + RCL_TOPICS
                 if node in t.subscribers.split(', ') or node == RECORDER and t.recorded)


def subscribers(t: Topic) -> Tuple[str, ...]:
    """Return the nodes subscribing to ``t``: its ``subscribers``, and the recorder if recorded."""
    return tuple(n for n in t.subscribers.split(', ') if n) + ((RECORDER,) if t.recorded else ())


def step_topics() -> Tuple[str, ...]:
    """Return what the simulator publishes once per step, in order: its 1 kHz clock and streams."""
    return tuple(t.name for t in published_by('simulator')
                 if t.qos in ('clock', 'stream') and t.rate == '1000 Hz')


def recorded_topics() -> List[str]:
    """Return what the recorder records by default: every topic of the table but the raw frames."""
    return [t.name for t in TOPICS if t.recorded]


def record_topics_yaml() -> str:
    """Return the text of msg_config/record_topics.yaml."""
    lines = ['# Generated from saw_ros/interface/topics.py (python -m saw_ros.interface.topics',
             '# --write-record-yaml msg_config/record_topics.yaml); '
             'tests/interface/test_topics.py pins it.',
             '# Topics the recorder takes by default (node `recorder`, parameter `topics` empty): '
             'every topic',
             '# the saw_ros nodes publish, and /clock, but the raw camera frames. A topic that '
             'appears later is',
             '# picked up when it appears.',
             'topics:']
    last = None
    for t in TOPICS:
        if not t.recorded:
            continue
        note = f'# {t.publisher}, {t.rate}' if t.publisher != last else ''
        last = t.publisher
        lines.append((f'  - {t.name} '.ljust(36) + note).rstrip())
    lines += ['# Every topic under these prefixes is recorded too (tracker outputs may grow)...',
              'prefixes:', f'  - {PREFIX}',
              '# ...but these. /saw/camera/image_raw: 60 fps of 1280x720 bgr8 is 166 MB/s, '
              '1.3 GB of bag a',
              '# minute; on 2 cores the recorder did not keep up (1.9 GB of memory, ~20 % of '
              'the images lost)',
              "# and the camera's video file (`video_path`) keeps the frames anyway. Record "
              'them with',
              '# `-p exclude_topics:="[\'\']"` (or by naming the topic in `topics`). /saw/ready: '
              "the nodes' start-up",
              '# handshake (saw_ros.ros.ready), nothing to analyse.',
              'exclude:']
    lines += [f'  - {t.name}' for t in TOPICS if not t.recorded]
    return '\n'.join(lines) + '\n'


def main(argv: Optional[List[str]] = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2 or argv[0] != '--write-record-yaml':
        print('usage: python -m saw_ros.interface.topics --write-record-yaml PATH',
              file=sys.stderr)
        return 2
    with open(argv[1], 'w', encoding='utf-8') as f:
        f.write(record_topics_yaml())
    return 0


if __name__ == '__main__':
    sys.exit(main())
