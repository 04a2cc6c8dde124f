"""
The ROS executables (``ros2 run saw_ros <name>``, ``python -m saw_ros.ros.nodes.<name>``).

Importing this package as one of them starts (a console script of that name, or ``python -m``
locating its module, while Python sets ``sys.argv[0]`` to ``'-m'``) takes SIGINT and SIGTERM
from then on: the imports take 0.3-0.5 s (numpy, OpenCV, rclpy), and Python's defaults would
end a Ctrl-C there with a KeyboardInterrupt traceback and a SIGTERM with -15. The request is
kept, and ``run_node`` then stops before anything starts, with exit code 0. Anything else
importing the package (tests, tools) keeps its own handlers.
"""
import os
import sys

from saw_ros.ros.runtime import take_stop_signals

EXECUTABLES = ('simulator', 'camera', 'vision', 'comparison', 'recorder', 'player',
               'video_source', 'speed_controller', 'foxglove_bridge')


def starting_as_executable(argv0: str) -> bool:
    """``argv0`` (``sys.argv[0]`` now) says this process is one of the executables starting."""
    return argv0 == '-m' or os.path.basename(argv0) in EXECUTABLES


if sys.argv and starting_as_executable(sys.argv[0]):
    take_stop_signals()
