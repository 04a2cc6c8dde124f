"""
The camera's compressed images on the wire and in a recording.

The encoder's bytes are a sensor_msgs/CompressedImage; the recorder takes
/saw/camera/image_raw/compressed by default and mcap_ros2 decodes the bag's messages.
"""
import os

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest

from saw_ros.graph.process import ManagedProcess, node_command, wait_for
from saw_ros.interface import topics as table
from saw_ros.vision import compressed

pytestmark = [pytest.mark.ros]
FRAMES = 10


def frame(k: int) -> np.ndarray:
    image = np.zeros((72, 128, 3), np.uint8)
    image[20:50, 10 + 5 * k:40 + 5 * k] = (180, 60, 230)
    return image


def test_encoder_bytes_are_a_compressed_image():
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import CompressedImage

    from saw_ros.ros import cdr
    data = compressed.encode_jpeg(frame(0))
    raw = cdr.CompressedImageCdr(compressed.JPEG_FORMAT, 'saw_camera')(data, 3_016_666_667)
    msg = deserialize_message(raw, CompressedImage)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (3, 16_666_667)
    assert msg.header.frame_id == 'saw_camera' and msg.format == compressed.JPEG_FORMAT
    assert bytes(msg.data) == data


def test_recorder_records_the_compressed_images(tmp_path, ros_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import CompressedImage

    from saw_ros.ros import cdr
    from saw_ros.ros.qos import image_publisher_qos
    assert table.IMAGE_COMPRESSED in table.recorded_topics()
    out = tmp_path / 'bag'
    rec = ManagedProcess('recorder', node_command('recorder', params={'output': str(out)}),
                         os.environ, tmp_path / 'logs')
    node = Node('camera_stand_in', context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    try:
        assert wait_for(lambda: 'recording to' in rec.output(), 20), rec.output()
        pub = node.create_publisher(CompressedImage, table.IMAGE_COMPRESSED,
                                    image_publisher_qos())
        assert wait_for(lambda: pub.get_subscription_count() >= 1, 20,
                        spin=lambda t: ex.spin_once(timeout_sec=t)), rec.output()
        encode = cdr.CompressedImageCdr(compressed.JPEG_FORMAT, 'saw_camera')
        for k in range(FRAMES):
            pub.publish(encode(compressed.encode_jpeg(frame(k)), k * 16_666_667))
        ex.spin_once(timeout_sec=0.5)
        assert rec.stop(20) == 0, rec.output()
    finally:
        ex.shutdown()
        node.destroy_node()
    with open(out / 'bag_0.mcap', 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        got = [(msg.header.stamp.nanosec, msg.format, bytes(msg.data)) for _, channel, _, msg
               in reader.iter_decoded_messages(topics=[table.IMAGE_COMPRESSED])]
    assert [t for t, _, _ in got] == [k * 16_666_667 for k in range(FRAMES)]
    for k, (_, fmt, data) in enumerate(got):
        image, encoding = compressed.decode(fmt, data)
        assert encoding == 'bgr8'
        assert np.abs(image.astype(int) - frame(k)).mean() < 3
