"""
The markers node: the robot, its contact forces and the tracker's estimate for RViz or Foxglove.

Subscribes to the simulator's /saw/pose, /saw/contacts and /saw/joint_states (the helix phase)
and to the tracker's /saw/tracking/front, /saw/tracking/back and /saw/tracking/pose, and
publishes visualization_msgs/MarkerArray on /saw/markers (frame ``surface``) at ``rate`` Hz of
simulated time: decimated by the messages' stamps, not by a wall timer, so a simulator at any
real-time factor (or a bag played back) gives the same pictures. Each array starts with a
DELETEALL, then the two surfaces (at y = 0 and y = conditions.gap), the body (at the pose), base
link, wave links and tips (saw_ros.core.kinematics at the helix phase), one ARROW per touching
tip (its contact force, ``force_scale`` m per N; green sticking, red slipping) and, once the
tracker has published, its marker centres (SPHEREs) and pose (ARROW along the tracked pitch).

The robot's geometry and the gap are this node's own Scenario parameters (``robot.*``,
``conditions.gap``, defaults as the simulator's; pass the simulator's values when they differ).
What is drawn where: saw_ros.interface.scene_markers.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import Point, PointStamped, PoseStamped
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from saw_ros.core.params import ParameterError, spec_meta
from saw_ros.interface import scene_markers, topics
from saw_ros.ros import cdr
from saw_ros.ros import conversions as conv
from saw_ros.ros.params import declare_spec, ScenarioParameters, SIMULATOR_EXCLUDED
from saw_ros.ros.qos import INPUT_DEPTH, profile, STREAM_QOS, with_depth
from saw_ros.ros.runtime import NodeFailure, run_node
from sensor_msgs.msg import JointState, PointCloud2
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

NS_PER_S = 1_000_000_000
FRAME = 'surface'
PENDING = 100          # stamps kept while waiting for the other topic of the same step

PARAMETERS = (
    ('rate', 60.0, spec_meta('Hz', 'marker arrays per simulated second', 0.0, 1000.0,
                             low_open=True, read_only=True)),
    ('force_scale', scene_markers.FORCE_SCALE, spec_meta(
        'm/N', 'arrow length per newton of contact force', 0.0, None, low_open=True,
        read_only=True)),
)

_KINDS = {'cube': Marker.CUBE, 'sphere': Marker.SPHERE, 'arrow': Marker.ARROW,
          'line_list': Marker.LINE_LIST, 'sphere_list': Marker.SPHERE_LIST}


def marker_of(shape: scene_markers.Shape, stamp, frame: str = FRAME) -> Marker:
    """Return a scene_markers.Shape as a visualization_msgs/Marker."""
    m = Marker()
    m.header.stamp = stamp
    m.header.frame_id = frame
    m.ns = shape.namespace
    m.id = shape.id
    m.type = _KINDS[shape.kind]
    m.action = Marker.ADD
    m.pose.position.x, m.pose.position.y, m.pose.position.z = shape.position
    m.pose.orientation.z = math.sin(0.5 * shape.yaw)
    m.pose.orientation.w = math.cos(0.5 * shape.yaw)
    m.scale.x, m.scale.y, m.scale.z = shape.scale
    m.color = ColorRGBA(r=shape.colour[0], g=shape.colour[1], b=shape.colour[2],
                        a=shape.colour[3])
    m.points = [Point(x=p[0], y=p[1], z=p[2]) for p in shape.points]
    return m


def next_due(stamp_ns: int, rate: float) -> int:
    """Return the first stamp of the next 1/rate slot after ``stamp_ns`` (slots start at 0)."""
    period = NS_PER_S / rate
    return int(math.ceil((math.floor(stamp_ns / period) + 1) * period - 1e-3))


class MarkersNode(Node):
    def __init__(self, **kwargs):
        super().__init__('markers', **kwargs)
        try:
            declare_spec(self, PARAMETERS)
            self.scenario_parameters = ScenarioParameters(self, exclude=SIMULATOR_EXCLUDED)
        except (ParameterException, ParameterError, ValueError) as exc:
            raise NodeFailure(f'invalid parameters: {exc}') from None
        self.rate = float(self.get_parameter('rate').value)
        self.force_scale = float(self.get_parameter('force_scale').value)
        self._due = None           # first stamp of the next array
        self._poses = {}           # stamp -> (x, y, pitch)
        self._contacts = {}        # stamp -> raw CDR of the PointCloud2
        self._phases = {}          # stamp -> helix phase
        self._phase = None         # the latest phase (for a stamp without joint states)
        self._read_phase = cdr.JointPosition('helix')
        self.front = self.back = self.tracked = None
        self.published = 0
        self.publisher = self.create_publisher(MarkerArray, topics.MARKERS,
                                               profile(topics.topic(topics.MARKERS).qos))
        stream = with_depth(STREAM_QOS, INPUT_DEPTH)
        tracking = profile('tracking')
        self.create_subscription(PoseStamped, topics.POSE, self._on_pose, stream, raw=True)
        self.create_subscription(PointCloud2, topics.CONTACTS, self._on_contacts, stream,
                                 raw=True)
        self.create_subscription(JointState, topics.JOINT_STATES, self._on_joints, stream,
                                 raw=True)
        self.create_subscription(PointStamped, topics.TRACKING_FRONT, self._on_front, tracking)
        self.create_subscription(PointStamped, topics.TRACKING_BACK, self._on_back, tracking)
        self.create_subscription(PoseStamped, topics.TRACKING_POSE, self._on_tracked, tracking)

    # -- ground truth: an array when pose and contacts of one due stamp are both in -------------
    def _wanted(self, stamp: int) -> bool:
        if self._due is not None and stamp < self._due - NS_PER_S:   # time went back: restart
            self._due = None
            for pending in (self._poses, self._contacts, self._phases):
                pending.clear()
        return self._due is None or stamp >= self._due

    def _on_pose(self, data) -> None:
        stamp, x, y, pitch = cdr.pose_stamped_ns(data)
        if self._wanted(stamp):
            self._poses[stamp] = (x, y, pitch)
            self._try(stamp)

    def _on_contacts(self, data) -> None:
        stamp = cdr.stamp_ns(data)
        if self._wanted(stamp):
            self._contacts[stamp] = data
            self._try(stamp)

    def _on_joints(self, data) -> None:
        stamp, phase = self._read_phase(data)
        if phase is not None and self._wanted(stamp):
            self._phases[stamp] = self._phase = phase
            self._try(stamp)

    def _try(self, stamp: int) -> None:
        # Pose, contacts and (while someone publishes them) joint states of one step.
        if stamp not in self._poses or stamp not in self._contacts or (
                stamp not in self._phases and self.count_publishers(topics.JOINT_STATES)):
            for pending in (self._poses, self._contacts, self._phases):
                while len(pending) > PENDING:
                    pending.pop(next(iter(pending)))
            return
        pose = self._poses.pop(stamp)
        cloud = deserialize_message(self._contacts.pop(stamp), PointCloud2)
        phase = self._phases.pop(stamp, self._phase)
        for pending in (self._poses, self._contacts, self._phases):   # older stamps are past
            for old in [s for s in pending if s <= stamp]:
                del pending[old]
        self._due = next_due(stamp, self.rate)
        self.publish_scene(stamp, pose, phase, conv.points_of(cloud))

    def publish_scene(self, stamp: int, pose, phase, contacts) -> None:
        """Publish the MarkerArray of one instant (a DELETEALL first: the arrows come and go)."""
        scenario = self.scenario_parameters.scenario
        shapes = scene_markers.scene(scenario.robot, scenario.conditions.gap, pose, phase,
                                     contacts, self.front, self.back, self.tracked,
                                     self.force_scale)
        ros_stamp = conv.time_msg(stamp)
        clear = Marker()
        clear.header.stamp = ros_stamp
        clear.header.frame_id = FRAME
        clear.action = Marker.DELETEALL
        self.publisher.publish(MarkerArray(
            markers=[clear] + [marker_of(s, ros_stamp) for s in shapes]))
        self.published += 1

    # -- the tracker's estimate: the latest of each -------------------------------------------
    def _on_front(self, msg: PointStamped) -> None:
        self.front = (msg.point.x, msg.point.y, msg.point.z)

    def _on_back(self, msg: PointStamped) -> None:
        self.back = (msg.point.x, msg.point.y, msg.point.z)

    def _on_tracked(self, msg: PoseStamped) -> None:
        self.tracked = (msg.pose.position.x, msg.pose.position.y,
                        conv.pitch_of(msg.pose.orientation))


def main(args=None):
    return run_node(MarkersNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
