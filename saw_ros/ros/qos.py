"""
QoS profiles of our topics, and the message classes behind the table's type names.

``saw_ros.interface.topics`` names each topic's profile ('stream', 'clock', 'image',
'tracking', 'latched'); ``profile(name)`` is the QoSProfile a subscriber asks for (the
contract), ``publisher_profile(name)`` what our publishers offer (same policies, deeper
histories where a reader that falls behind must be repaired from the writer's history).
"""
from __future__ import annotations

import importlib

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)

# Every 1 kHz stream must arrive complete (tests and bags count stamps): reliable, and a queue
# deep enough to ride out a subscriber's scheduling hiccup of a few tens of milliseconds.
STREAM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=200,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
# /clock as rosgraph expects it from a simulator: reliable, shallow.
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
# Camera images: reliable so that recordings and accuracy figures see every frame; 60 Hz of
# 1280x720 images is light next to the 1 kHz streams.
IMAGE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=30,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
# Low-rate reports (comparison, status): late joiners get the last one.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)


def with_depth(qos: QoSProfile, depth: int) -> QoSProfile:
    """
    ``qos`` with another history depth.

    The same contract (depth does not take part in QoS matching), a longer queue on this side.
    """
    return QoSProfile(history=qos.history, depth=depth, reliability=qos.reliability,
                      durability=qos.durability)


# A subscriber of the 1 kHz streams in a busy graph keeps 1 s of queue (docs/measurements.md).
INPUT_DEPTH = 1000
# Publishers of the 1 kHz streams keep the contract's policies (STREAM_QOS, CLOCK_QOS) with a
# deeper history, 3000 = 3 s at 1 kHz: a reliable reader that falls behind can only be repaired
# from the writer's history, and Clock, a plain type, is handed to same-host readers straight
# from it (Fast DDS data sharing), so a reader further behind than the writer's depth loses
# /clock ticks however deep its own queue is. (Depth does not affect QoS compatibility.) With
# 1 s, a recorder whose process stood still for 1.3 s (SIGSTOP, as a busy machine deschedules
# it) lost 101 messages and for 2.5 s 4802; with 3 s (and the recorder's queue_depth 3000), 0
# and 0 (docs/measurements.md). Memory is used only while a reader is behind: a volatile
# writer drops the samples every reader has acknowledged.
PUBLISHER_DEPTH = 3000
# Publishers of camera images and infos keep 1 s of history at 60 fps: a reliable reader that
# falls behind is repaired from the writer's history (cf. PUBLISHER_DEPTH).
IMAGE_PUBLISHER_DEPTH = 60
# The vision node's outputs (tracking/*): reliable, 200 deep.
TRACKING_DEPTH = 200


def image_publisher_qos() -> QoSProfile:
    """
    IMAGE_QOS offered transient-local with IMAGE_PUBLISHER_DEPTH of history.

    Compatible with every volatile reader, and a recorder (which asks for transient-local when all
    publishers offer it) that matches late still gets the last second of frames
    (docs/measurements.md).
    """
    return QoSProfile(history=IMAGE_QOS.history, depth=IMAGE_PUBLISHER_DEPTH,
                      reliability=IMAGE_QOS.reliability,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


# Commands (saw_ros.ros.command): reliable and volatile, shallow. A late joiner must not be
# handed old commands (transient-local would replay them), and only the newest one counts.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)

_PROFILES = {'command': COMMAND_QOS, 'stream': STREAM_QOS, 'clock': CLOCK_QOS, 'image': IMAGE_QOS,
             'tracking': with_depth(STREAM_QOS, TRACKING_DEPTH), 'latched': LATCHED_QOS}


def profile(name: str) -> QoSProfile:
    """Return the QoS a subscriber of a topic with the table's profile ``name`` asks for."""
    return _PROFILES[name]


def publisher_profile(name: str) -> QoSProfile:
    """
    Return the QoS our publishers offer on a topic with the table's profile ``name``.

    Images and the 60 Hz 'tracking' outputs are offered transient-local, as image_publisher_qos
    says why: the main job's recorder matches the vision node's topics independently of the
    simulator's (whose matching starts the run), and under load it matched one of them after
    the first frame (the bag lacked that frame's message); with the writer's history it still
    gets it. Volatile readers match as before.
    """
    if name in ('stream', 'clock'):
        return with_depth(_PROFILES[name], PUBLISHER_DEPTH)
    if name == 'image':
        return image_publisher_qos()
    if name == 'tracking':
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=TRACKING_DEPTH,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
    return _PROFILES[name]


def message_class(type_name: str):
    """'geometry_msgs/msg/PoseStamped' -> the message class."""
    pkg, namespace, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{namespace}'), name)
