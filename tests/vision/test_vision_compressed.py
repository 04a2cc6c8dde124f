"""JPEG images in image_transport's compressed format: they decode to the frame."""
import numpy as np
import pytest

from saw_ros.core import Scenario
from saw_ros.vision import compressed
from saw_ros.vision.camera import CameraModel
from saw_ros.vision.frames import Renderer, RobotPose


def frame():
    s = Scenario()
    pose = RobotPose(x=0.0, y=s.conditions.gap / 2, theta=0.0, phase=0.3)
    return Renderer(s.robot, s.conditions.gap, CameraModel()).render(pose)


def psnr(a, b) -> float:
    mse = np.mean((a.astype(float) - b.astype(float)) ** 2)
    return 10 * np.log10(255.0 ** 2 / mse)


def test_jpeg_at_quality_90_decodes_to_the_frame():
    image = frame()
    data = compressed.encode_jpeg(image, 90)
    assert data[:2] == b'\xff\xd8' and len(data) < image.nbytes / 10
    assert compressed.JPEG_FORMAT == 'bgr8; jpeg compressed bgr8'
    decoded, encoding = compressed.decode(compressed.JPEG_FORMAT, data)
    assert encoding == 'bgr8' and decoded.shape == image.shape
    assert psnr(decoded, image) > 35.0
    rgb, encoding = compressed.decode('rgb8; jpeg compressed bgr8', data)
    assert encoding == 'rgb8' and np.array_equal(rgb, decoded[:, :, ::-1])


def test_undecodable_data_and_other_encodings_are_refused():
    with pytest.raises(ValueError, match='does not decode'):
        compressed.decode(compressed.JPEG_FORMAT, b'not a jpeg')
    data = compressed.encode_jpeg(frame())
    with pytest.raises(ValueError, match='bgr8 or rgb8'):
        compressed.decode('mono16; jpeg compressed mono16', data)
    assert compressed.compressed_topic('/saw/camera/image_raw') == \
        '/saw/camera/image_raw/compressed'
