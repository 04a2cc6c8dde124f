"""
Node ``loadgen``: the simulator's and the camera's topic types at fixed rates.

It publishes counted messages, to test and benchmark the recorder without the simulator.

Parameters: ``rate`` (Hz, for each 1 kHz-class topic), ``duration`` (s), ``streams`` (how many of
clock, pose, twist, contacts, contact_wrench, joint_states: 0-6), ``image_fps`` (0: no images),
``image_width``/``image_height``, ``prefix`` (topic namespace, default ``/saw``; /clock is
``<prefix>/clock`` unless ``prefix`` is /saw), ``wait_subscribers`` (start once every topic has
this many subscriptions, at most 30 s), ``start_delay`` (s, after that), ``publisher_depth``
(history of the 1 kHz-class publishers: 3000 as the simulator's, ``PUBLISHER_DEPTH``; 0 = the
contract's STREAM_QOS/CLOCK_QOS depths 200/100), ``image_depth`` (history of the image publisher,
default 120: see IMAGE_DEPTH), ``image_participant`` (images from a DDS participant of their own,
as from the camera node). At the end it waits for reliable delivery, prints ``published <topic>
<count>`` lines and exits.
"""
from __future__ import annotations

import time
from typing import Dict

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from saw_ros.ros.qos import CLOCK_QOS, IMAGE_QOS, PUBLISHER_DEPTH, STREAM_QOS, with_depth
from saw_ros.ros.runtime import run_node
from sensor_msgs.msg import Image, JointState, PointCloud2, PointField

# Images: 2 s at 60 fps, longer than the bursts this node publishes to catch up after being
# descheduled (a KEEP_LAST writer overwrites unacknowledged samples; docs/measurements.md).
IMAGE_DEPTH = 120


def _cloud(points: int) -> PointCloud2:
    msg = PointCloud2()
    msg.header.frame_id = 'world'
    msg.height, msg.width = 1, points
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate(('x', 'y', 'z', 'fx', 'fy', 'fz'))]
    msg.point_step, msg.row_step = 24, 24 * points
    msg.data = bytes(24 * points)
    msg.is_dense = True
    return msg


class LoadGen(Node):
    def __init__(self):
        super().__init__('loadgen')
        p = {name: self.declare_parameter(name, default).value for name, default in (
            ('rate', 1000.0), ('duration', 3.0), ('streams', 6), ('image_fps', 0.0),
            ('image_width', 1280), ('image_height', 720), ('prefix', '/saw'),
            ('start_delay', 0.0), ('wait_subscribers', 1),
            ('publisher_depth', PUBLISHER_DEPTH), ('image_depth', IMAGE_DEPTH),
            ('image_participant', True))}
        self.p = p
        prefix = p['prefix'].rstrip('/')
        clock_topic = '/clock' if prefix == '/saw' else f'{prefix}/clock'
        joints = JointState(name=[f'segment_{i}' for i in range(12)], position=[0.0] * 12,
                            velocity=[0.0] * 12, effort=[0.0] * 12)
        streams = [(clock_topic, Clock, Clock(), CLOCK_QOS),
                   (f'{prefix}/pose', PoseStamped, PoseStamped(), STREAM_QOS),
                   (f'{prefix}/twist', TwistStamped, TwistStamped(), STREAM_QOS),
                   (f'{prefix}/contacts', PointCloud2, _cloud(40), STREAM_QOS),
                   (f'{prefix}/contact_wrench', WrenchStamped, WrenchStamped(), STREAM_QOS),
                   (f'{prefix}/joint_states', JointState, joints, STREAM_QOS)][:int(p['streams'])]
        depth = int(p['publisher_depth'])
        self.streams = [(topic, self.create_publisher(t, topic, with_depth(qos, depth) if depth > 0
                                                      else qos), msg)
                        for topic, t, msg, qos in streams]
        self.image = None
        if p['image_fps'] > 0:
            w, h = int(p['image_width']), int(p['image_height'])
            img = Image(height=h, width=w, encoding='rgb8', step=3 * w)
            img.header.frame_id = 'camera'
            img.data = bytes(range(256)) * (3 * w * h // 256) + bytes(3 * w * h % 256)
            self.image = (f'{prefix}/camera/image_raw',
                          self._image_node().create_publisher(Image, f'{prefix}/camera/image_raw',
                                                              with_depth(IMAGE_QOS,
                                                                         int(p['image_depth']))),
                          img)
        self.counts = {topic: 0 for topic, _, _ in self.streams}
        if self.image:
            self.counts[self.image[0]] = 0

    def _image_node(self) -> Node:
        """
        With ``image_participant`` images go out from a DDS participant of their own.

        As they do from the camera node (another process) in the real graph.
        """
        if not self.p['image_participant']:
            return self
        import rclpy
        from rclpy.context import Context
        context = Context()
        rclpy.init(context=context)
        self._image_context = context
        return Node('loadgen_images', context=context)

    def run(self) -> None:
        p = self.p
        from saw_ros.graph.process import wait_for
        pubs = [pub for _, pub, _ in self.streams] + ([self.image[1]] if self.image else [])
        need = int(p['wait_subscribers'])
        if need > 0 and not wait_for(
                lambda: all(pub.get_subscription_count() >= need for pub in pubs), 30.0):
            self.get_logger().warning('not every topic has a subscriber; publishing anyway')
        time.sleep(p['start_delay'])
        period = 1.0 / p['rate'] if p['rate'] > 0 else None
        image_period = 1.0 / p['image_fps'] if self.image else None
        start = time.monotonic()
        next_tick, next_image, tick = start, start, 0
        max_lag, lag_at = 0.0, 0.0   # how far publishing fell behind its schedule, and when
        end = start + p['duration']
        while True:
            now = time.monotonic()
            if now >= end:
                break
            if period is not None and now >= next_tick:
                if now - next_tick > max_lag:
                    max_lag, lag_at = now - next_tick, next_tick - start
                tick += 1
                stamp = Time(sec=tick // 1000, nanosec=(tick % 1000) * 1_000_000)
                for topic, pub, msg in self.streams:
                    if isinstance(msg, Clock):
                        msg.clock = stamp
                    else:
                        msg.header.stamp = stamp
                    pub.publish(msg)
                    self.counts[topic] += 1
                next_tick += period
            if image_period is not None and now >= next_image:
                topic, pub, img = self.image
                img.header.stamp = Time(sec=int(now), nanosec=int((now % 1) * 1e9))
                pub.publish(img)
                self.counts[topic] += 1
                next_image += image_period
            wake = min(t for t in (next_tick if period else end,
                                   next_image if image_period else end, end))
            delay = wake - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        for _, pub, _ in self.streams:
            pub.wait_for_all_acked()
        if self.image:
            self.image[1].wait_for_all_acked()
        elapsed = time.monotonic() - start
        for topic, n in self.counts.items():
            print(f'published {topic} {n}', flush=True)
        print(f'elapsed {elapsed:.3f}', flush=True)
        print(f'max_lag {max_lag:.4f} at {lag_at:.3f}', flush=True)


def published_counts(output: str) -> Dict[str, int]:
    """Return {topic: messages} from a load generator's ``published <topic> <n>`` lines."""
    return {line.split()[1]: int(line.split()[2]) for line in output.splitlines()
            if line.startswith('published ')}


def main(args=None) -> int:
    return run_node(LoadGen, args=args, spin=lambda node: node.run())


if __name__ == '__main__':
    raise SystemExit(main())
