"""
TF for our nodes without tf2_ros: TFMessage on /tf and /tf_static (saw_ros.interface.frames).

tf2_ros (the broadcaster classes) is not among the pip set-up's wheels; the message is
(tf2_msgs, built by scripts/bootstrap.sh, or a ROS install's). A broadcaster is one publisher of
tf2_msgs/TFMessage with the table's QoS: /tf as the 60 Hz 'tracking' profile (reliable), /tf_static
latched (reliable, transient local, depth 1, as tf2_ros' StaticTransformBroadcaster offers it).
"""
from __future__ import annotations

import struct
from typing import Any, Iterable, Sequence, Tuple

from geometry_msgs.msg import TransformStamped
from saw_ros.interface import frames, topics
from saw_ros.ros.cdr import ENCAPSULATION, stamp_bytes, string_bytes
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


def message(transforms: Iterable[TransformStamped]) -> Any:     # a TFMessage
    return TFMessage(transforms=list(transforms))


def camera_transform(model, child: str = frames.CAMERA,
                     nanoseconds: int = 0) -> TransformStamped:
    """Return surface -> ``child``, a vision CameraModel's optical frame (frames.camera_pose)."""
    translation, rotation = frames.camera_pose(model.center_x, model.center_y, model.distance,
                                               model.slope, model.mirror)
    return transform(frames.SURFACE, child, nanoseconds, translation, rotation)


# parent, child, translation (m), rotation (x, y, z, w): saw_ros.interface.urdf.Frame.
Frame = Tuple[str, str, Sequence[float], Sequence[float]]
_SEVEN = struct.Struct('<7d')
_PAD = (b'', b'\0', b'\0' * 2, b'\0' * 3, b'\0' * 4, b'\0' * 5, b'\0' * 6, b'\0' * 7)


def message_cdr(transforms: Sequence[Frame], nanoseconds: int) -> bytes:
    """
    Return a TFMessage of ``transforms``, all stamped ``nanoseconds``, serialized (XCDR1 LE).

    The simulator's TF holds every link of the robot (79 transforms at 60 Hz): rclpy's own
    conversion of so many TransformStamped objects costs about a millisecond, this a tenth of
    it. tests/ros/test_tf.py checks it byte for byte against rclpy's serialization.
    """
    stamp = stamp_bytes(nanoseconds)
    parts = [ENCAPSULATION, struct.pack('<I', len(transforms))]
    size = 4                                  # bytes after the encapsulation
    for parent, child, translation, rotation in transforms:
        # Each transform starts 8-aligned (after the u32 count: 4-aligned), so 4-aligned.
        head = stamp + string_bytes(parent)
        head += _PAD[-(size + len(head)) % 4] + string_bytes(child)
        head += _PAD[-(size + len(head)) % 8]
        parts += [head, _SEVEN.pack(*translation, *rotation)]
        size += len(head) + 56
    return b''.join(parts)
