"""
rosbag2-compatible bags (MCAP storage) without rosbag2: schemas, writer, reader.

No rclpy here: the recorder and player nodes (``saw_ros/ros/nodes``) adapt ROS to these classes.
What the files contain, and what rosbag2 expects of them, is described in ``docs/bags.md``.
"""
from saw_ros.bag.reader import BagReader, BagReadError  # noqa: F401
from saw_ros.bag.schema import message_definition, type_hash  # noqa: F401
from saw_ros.bag.writer import (BagExistsError, BagWriteError, BagWriter,  # noqa: F401
                                qos_profile_dict)
