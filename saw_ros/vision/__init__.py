"""
Vision: a virtual side-view camera and the two-pink-marker tracker (numpy + OpenCV, no rclpy).

``camera`` (the camera model shared by both), ``render`` (frames of the simulated robot),
``tracker`` (marker detection, front/back assignment, position, pitch, speeds), ``video``
(.mp4 writing and frame-by-frame reading), ``synthetic`` (rendered runs with their ground truth,
for tests and benchmarks; the only module here that imports the simulation core).
"""
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import Renderer, RenderOptions, RobotPose
from saw_ros.vision.tracker import detect, FrameResult, Tracker, TrackerConfig

__all__ = ['CameraModel', 'FrameResult', 'Renderer', 'RenderOptions', 'RobotPose', 'Tracker',
           'TrackerConfig', 'detect']
