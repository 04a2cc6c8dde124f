"""
TF for our nodes without tf2_ros: TFMessage on /tf and /tf_static (saw_ros.interface.frames).

tf2_ros (the broadcaster classes) is not among the pip set-up's wheels; the message is
(tf2_msgs, built by scripts/bootstrap.sh, or a ROS install's). A broadcaster is one publisher of
tf2_msgs/TFMessage with the table's QoS: /tf as the 60 Hz 'tracking' profile (reliable), /tf_static
latched (reliable, transient local, depth 1, as tf2_ros' StaticTransformBroadcaster offers it).
"""
from __future__ import annotations

from typing import Iterable, Sequence

from geometry_msgs.msg import TransformStamped
from saw_ros.interface import frames, topics
from saw_ros.ros.conversions import time_msg
from saw_ros.ros.qos import message_class, publisher_profile

TFMessage = message_class(topics.topic(topics.TF).type)


def transform(parent: str, child: str, nanoseconds: int, translation: Sequence[float],
              rotation: Sequence[float]) -> TransformStamped:
    """``child`` in ``parent`` at ``nanoseconds``: translation (m), quaternion (x, y, z, w)."""
    t = TransformStamped()
    t.header.stamp = time_msg(nanoseconds)
    t.header.frame_id = parent
    t.child_frame_id = child
    v, q = t.transform.translation, t.transform.rotation
    v.x, v.y, v.z = (float(c) for c in translation)
    q.x, q.y, q.z, q.w = (float(c) for c in rotation)
    return t


def planar(parent: str, child: str, nanoseconds: int, x: float, y: float,
           theta: float) -> TransformStamped:
    """Return a side-view pose (x, y in the plane, pitch ``theta`` about z) as a transform."""
    return transform(parent, child, nanoseconds, (x, y, 0.0), frames.yaw_quaternion(theta))


def publisher(node, static: bool = False):
    """Create a /tf (or /tf_static) publisher with the topic table's QoS."""
    name = topics.TF_STATIC if static else topics.TF
    return node.create_publisher(TFMessage, name, publisher_profile(topics.topic(name).qos))


def message(transforms: Iterable[TransformStamped]) -> 'TFMessage':
    return TFMessage(transforms=list(transforms))


def camera_transform(model, child: str = frames.CAMERA,
                     nanoseconds: int = 0) -> TransformStamped:
    """Return surface -> ``child``, a vision CameraModel's optical frame (frames.camera_pose)."""
    translation, rotation = frames.camera_pose(model.center_x, model.center_y, model.distance,
                                               model.slope, model.mirror)
    return transform(frames.SURFACE, child, nanoseconds, translation, rotation)
