"""A recording's camera frames: as the tracker's frame source and as a video."""
from pathlib import Path

import numpy as np
import pytest

from saw_ros.analysis.bag_frames import bag_video, BagFrames
from saw_ros.bag.reader import BagReader, BagReadError
from saw_ros.interface import topics
from saw_ros.vision import images
from saw_ros.vision.video import read_frames, video_info

BAGS = Path(__file__).resolve().parents[2] / 'bags'


def test_the_raw_camera_stream_is_found_and_read_as_bgr8():
    source = BagFrames(BAGS / 'reference_camera')
    assert source.topic == topics.IMAGE and source.count == 180
    assert source.size == (1280, 720) and source.fps == pytest.approx(60.0)
    _, first = next(BagReader(BAGS / 'reference_camera').decoded_messages([topics.IMAGE]))
    k, t, frame = next(iter(source.frames()))
    assert k == 0 and t == pytest.approx(1 / 60)
    assert np.array_equal(frame, images.decode(first)[0])


def test_a_recording_without_frames_is_refused_with_its_image_topics():
    with pytest.raises(BagReadError, match=r'holds no frames on .*image topics recorded: none'):
        BagFrames(BAGS / 'reference_default')


def test_bag_video_writes_every_frame_at_the_stamps_rate(tmp_path):
    written, fps = bag_video(BAGS / 'reference_camera', tmp_path / 'camera.mp4')
    assert (written, fps) == (180, 60.0)
    rate, _, width, height = video_info(tmp_path / 'camera.mp4')
    assert (rate, width, height) == (60.0, 1280, 720)
    assert sum(1 for _ in read_frames(tmp_path / 'camera.mp4')) == 180
