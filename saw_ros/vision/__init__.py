"""
Vision: a virtual side-view camera and the two-pink-marker tracker (numpy + OpenCV, no rclpy).

``camera`` (the camera model shared by both), ``render`` (frames of the simulated robot),
``tracker`` (marker detection, front/back assignment, position, pitch, speeds), ``video``
(.mp4 writing and frame-by-frame reading), ``synthetic`` (rendered runs with their ground truth,
for tests and benchmarks; the only module here that imports the simulation core).
"""
import cv2

from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import Renderer, RenderOptions, RobotPose
from saw_ros.vision.tracker import detect, FrameResult, Tracker, TrackerConfig


def one_opencv_thread() -> None:
    """
    Run OpenCV's own work on the calling thread only: for a node sharing a few cores with others.

    Its worker threads split a 1280x720 resize or colour conversion and then spin waiting for
    more: in the vision node on this 2-core machine they added 2.6 ms of CPU to each frame's
    8.2 (imdecode, the bulk, is single-threaded anyway). Offline tools keep them.
    """
    cv2.setNumThreads(1)


__all__ = ['CameraModel', 'FrameResult', 'Renderer', 'RenderOptions', 'RobotPose', 'Tracker',
           'TrackerConfig', 'detect', 'one_opencv_thread']
