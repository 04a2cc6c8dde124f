"""
The Foxglove bridge through the protocol, as the Foxglove app sees it (issue 34).

The bridge runs as its own executable in the run's isolated DDS domain; the test connects as a
Foxglove WebSocket client (saw_ros.graph.foxglove_client, on the websockets library), decodes
what it receives from the channel's ros2msg schema alone (mcap_ros2's dynamic decoder, as
Foxglove does: none of our message classes), and publishes through it. Every wait is on a
condition with a timeout.
"""
import re
import time

import cv2
import numpy as np
import pytest
from saw_ros.graph.foxglove_client import FoxgloveClient
from saw_ros.graph.process import ManagedProcess, node_command, wait_for

pytestmark = pytest.mark.ros

from rclpy.serialization import serialize_message  # noqa: E402, I100
from saw_ros.bag.schema import message_definition  # noqa: E402
from saw_ros.interface import topics  # noqa: E402
from saw_ros.ros.nodes.simulator import MAX_BATCH  # noqa: E402
from saw_ros.ros.qos import message_class, profile  # noqa: E402

COMMAND_TYPE = topics.topic(topics.MOTOR_COMMANDS).type


def start(name, params, tmp_path):
    return ManagedProcess(name, node_command(name, params=params), env=None, log_dir=tmp_path)


def start_bridge(tmp_path, **params):
    """Start the bridge on a free port (port 0); return (process, its ws:// URL from its log)."""
    bridge = start('foxglove_bridge', {'port': 0, **params}, tmp_path)
    found = []

    def url():
        found[:] = re.findall(r'Foxglove WebSocket on (ws://127\.0\.0\.1:\d+)', bridge.output())
        return bool(found) or bridge.returncode is not None
    assert wait_for(url, 30) and found, bridge.output()
    return bridge, found[0]


def decoder(client, name):
    """Decode a topic's payloads from what the server advertised only (as Foxglove does)."""
    from mcap_ros2._dynamic import generate_dynamic
    channel = client.channels[name]
    assert (channel['encoding'], channel['schemaEncoding']) == ('cdr', 'ros2msg')
    assert channel['schemaName'] == topics.topic(name).type
    # The full concatenated definition, as foxglove_bridge and rosbag2 send it.
    assert channel['schema'] == message_definition(channel['schemaName'])
    return generate_dynamic(channel['schemaName'], channel['schema'])[channel['schemaName']]


def test_a_client_decodes_the_pose_the_camera_image_and_the_comparison(tmp_path):
    bridge, url = start_bridge(tmp_path)
    # The simulator steps once each of its topics has a subscriber: the bridge's, once the
    # client subscribed to everything.
    nodes = [start('simulator', {'duration': 2.5, 'real_time_factor': 1.0,
                                 'wait_for_subscribers': 1}, tmp_path),
             start('camera', {}, tmp_path), start('comparison', {'report_period': 0.5}, tmp_path)]
    wanted = (topics.POSE, topics.IMAGE_COMPRESSED, topics.COMPARISON)
    client = FoxgloveClient(url, keep=wanted)
    try:
        assert wait_for(lambda: set(wanted) <= set(client.channels), 10), client.channels
        assert topics.IMAGE not in client.channels       # the camera as CompressedImage only
        assert set(client.channels) == {t.name for t in topics.TOPICS} - {topics.IMAGE}
        client.subscribe(client.channels)
        assert wait_for(lambda: all(client.messages.get(n) for n in wanted), 60), (
            client.counts, [p.output()[-600:] for p in nodes])
        assert wait_for(lambda: nodes[0].returncode is not None, 60), nodes[0].output()
        # Every step reached the client or was reported lost: the simulator started once the
        # bridge's subscriptions (the client's) matched; the bridge reads its 1 kHz streams best
        # effort, and on a busy machine (two hogs on the slower kind) DDS drops some before it,
        # which the bridge counts and names when it stops.
        steps = int(re.search(r'stopped after (\d+) steps', nodes[0].output()).group(1))
        streams = topics.step_topics()
        # (up to 30 s: under a CPU cap of a third the bridge was still handing on /saw/contacts
        # 10 s after the simulator had stopped)
        counts = lambda: {n: client.counts.get(n, 0) for n in streams}  # noqa: E731
        settled = [counts(), time.monotonic()]

        def done():
            now = counts()
            if now != settled[0]:
                settled[:] = [now, time.monotonic()]
            return all(c == steps for c in now.values()) or \
                time.monotonic() - settled[1] > 2.0
        assert wait_for(done, 30), (steps, counts())
    finally:
        client.close()
        for p in nodes + [bridge]:
            p.stop(timeout=10)
    stop_line = [line for line in bridge.output().splitlines() if 'stopped:' in line][-1]
    lost = {name: int(n) for name, n in re.findall(r'(/[\w/]+) (\d+)', stop_line)}
    for name, got in counts().items():
        assert got + lost.get(name, 0) <= steps, (name, got, lost, steps)
    pose = decoder(client, topics.POSE)
    poses = [pose(data) for _, _, data in client.messages[topics.POSE]]
    stamps = [p.header.stamp.sec * 10 ** 9 + p.header.stamp.nanosec for p in poses]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    # DDS sees a loss when a later message comes: poses lost after the last one received are
    # the only ones it cannot count (pose k is stamped k ms).
    unseen_tail = steps - stamps[-1] // 10 ** 6
    assert steps - len(poses) - lost.get(topics.POSE, 0) <= unseen_tail, (
        len(poses), lost, steps, unseen_tail)
    # The other streams' tails: the same steps, published a wake-up (at most MAX_BATCH steps)
    # at a time, topic after topic.
    for name, got in counts().items():
        assert steps - got - lost.get(name, 0) <= unseen_tail + MAX_BATCH, (
            name, got, lost, steps, unseen_tail)
    assert poses[-1].header.frame_id == 'surface' and np.isfinite(poses[-1].pose.position.x)
    assert poses[-1].pose.position.x > poses[0].pose.position.x      # the robot crawls forward
    # Log times: the wall clock when the bridge took each message (batched: in order).
    log_times = [log_ns for log_ns, _, _ in client.messages[topics.POSE]]
    assert log_times == sorted(log_times) and abs(log_times[-1] - time.time_ns()) < 120e9
    images = client.messages[topics.IMAGE_COMPRESSED]
    image = decoder(client, topics.IMAGE_COMPRESSED)(images[-1][2])
    assert 'jpeg' in image.format, image.format
    frame = cv2.imdecode(np.frombuffer(bytes(image.data), np.uint8), cv2.IMREAD_COLOR)
    assert frame is not None and frame.shape == (720, 1280, 3)
    comparison = decoder(client, topics.COMPARISON)(client.messages[topics.COMPARISON][-1][2])
    keys = {kv.key for kv in comparison.status[0].values}
    assert 'comparison' in comparison.status[0].name and 'status' in keys, (
        comparison.status[0].name, keys)
    assert 'Traceback' not in bridge.output() and bridge.returncode == 0, bridge.output()


def test_a_command_through_the_bridge_drives_the_simulated_motor(tmp_path):
    bridge, url = start_bridge(tmp_path)
    simulator = start('simulator', {'motor.voltage': 6.0, 'real_time_factor': 1.0,
                                    'duration': 30.0, 'command_timeout': 0.0}, tmp_path)
    client = FoxgloveClient(url, keep=[topics.MOTOR])
    try:
        assert wait_for(lambda: topics.MOTOR in client.channels, 10), client.channels
        client.subscribe([topics.MOTOR])
        motor = decoder(client, topics.MOTOR)
        assert wait_for(lambda: client.messages.get(topics.MOTOR), 30), simulator.output()
        assert motor(client.messages[topics.MOTOR][-1][2]).voltage == 6.0
        channel = client.advertise(topics.MOTOR_COMMANDS, COMMAND_TYPE)
        command = serialize_message(message_class(COMMAND_TYPE)(data=[9.0]))

        def applied():
            client.publish(channel, command)       # again until the bridge has matched
            return motor(client.messages[topics.MOTOR][-1][2]).voltage == 9.0
        assert wait_for(applied, 30, poll=0.1), (bridge.output(), simulator.output())
    finally:
        client.close()
        simulator.stop(timeout=10)
        bridge.stop(timeout=10)
    assert 'Traceback' not in bridge.output() + simulator.output()
    assert re.search(r'[1-9]\d* client commands published, 0 refused', bridge.output())


def test_a_client_publishing_on_another_topic_is_refused_and_the_bridge_runs_on(
        ros_context, tmp_path):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    node = Node('bridge_watcher', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    got = {topics.POSE: [], topics.MOTOR_COMMANDS: []}
    for name, seen in got.items():
        entry = topics.topic(name)
        node.create_subscription(message_class(entry.type), name, seen.append,
                                 profile(entry.qos), raw=True)
    bridge, url = start_bridge(tmp_path)
    client = FoxgloveClient(url)
    try:
        pose_type = topics.topic(topics.POSE).type
        pose = serialize_message(message_class(pose_type)())
        hostile = client.advertise(topics.POSE, pose_type)
        wrong_type = client.advertise(topics.MOTOR_COMMANDS, pose_type)
        command = client.advertise(topics.MOTOR_COMMANDS, COMMAND_TYPE)
        client.publish(hostile, pose)
        client.publish(wrong_type, pose)
        client.publish(command, b'\x00\x01\x00\x00\x07')             # not a Float64MultiArray
        client.publish(999, pose)      # never advertised: the SDK drops it before the bridge
        assert wait_for(lambda: client.statuses, 10), bridge.output()
        assert 'clients may publish on /saw/motor_controller/commands only' in \
            client.statuses[0]['message']
        good = serialize_message(message_class(COMMAND_TYPE)(data=[3.0]))

        def delivered():
            client.publish(command, good)
            return bool(got[topics.MOTOR_COMMANDS])
        assert wait_for(delivered, 30, poll=0.1, spin=lambda t: executor.spin_once(
            timeout_sec=t)), bridge.output()
    finally:
        client.close()
        bridge.stop(timeout=10)
        executor.shutdown(timeout_sec=1)
        node.destroy_node()
    assert got[topics.POSE] == [], 'a client published on /saw/pose through the bridge'
    assert set(got[topics.MOTOR_COMMANDS]) == {good}
    log = bridge.output()
    assert bridge.returncode == 0 and 'Traceback' not in log, log
    assert 'refused, not published: client' in log
    assert re.search(r'stopped: \d+ messages forwarded, [1-9]\d* client commands published, '
                     r'5 refused', log), log


def test_the_bridge_subscribes_to_a_topic_only_while_a_client_does(ros_context, tmp_path):
    from rclpy.node import Node
    node = Node('bridge_publisher', context=ros_context)
    entry = topics.topic(topics.POSE)
    publisher = node.create_publisher(message_class(entry.type), entry.name, profile(entry.qos))
    bridge, url = start_bridge(tmp_path)
    client = FoxgloveClient(url)
    try:
        assert wait_for(lambda: topics.POSE in client.channels, 10), client.channels
        # Connected and advertised to, but subscribed to nothing: the bridge takes nothing.
        assert not wait_for(lambda: publisher.get_subscription_count() > 0, 1.0)
        client.subscribe([topics.POSE])
        assert wait_for(lambda: publisher.get_subscription_count() == 1, 20), bridge.output()
        client.close()          # a client that leaves unsubscribes from everything
        assert wait_for(lambda: publisher.get_subscription_count() == 0, 20), bridge.output()
    finally:
        client.close()
        bridge.stop(timeout=10)
        node.destroy_node()
    assert bridge.returncode == 0 and 'Traceback' not in bridge.output(), bridge.output()


def test_held_subscriptions_wait_for_the_first_clock(ros_context, tmp_path):
    """With hold_until_clock (the demo's, with a recorder) a client cannot start the run."""
    from rclpy.node import Node
    node = Node('bridge_publisher', context=ros_context)
    pose, clock = (topics.topic(name) for name in (topics.POSE, topics.CLOCK))
    publisher = node.create_publisher(message_class(pose.type), pose.name, profile(pose.qos))
    clock_publisher = node.create_publisher(message_class(clock.type), clock.name,
                                            profile(clock.qos))
    bridge, url = start_bridge(tmp_path, hold_until_clock=True)
    client = FoxgloveClient(url)
    try:
        assert wait_for(lambda: topics.POSE in client.channels, 10), client.channels
        client.subscribe([topics.POSE])
        assert wait_for(lambda: clock_publisher.get_subscription_count() == 1, 20)
        assert not wait_for(lambda: publisher.get_subscription_count() > 0, 1.0)
        clock_publisher.publish(message_class(clock.type)())       # the simulator's first step

        def subscribed():
            if clock_publisher.get_subscription_count():
                clock_publisher.publish(message_class(clock.type)())
            return publisher.get_subscription_count() == 1
        assert wait_for(subscribed, 20, poll=0.05), bridge.output()
        # ...and the bridge's watch on /clock is gone with it.
        assert wait_for(lambda: clock_publisher.get_subscription_count() == 0, 20)
    finally:
        client.close()
        bridge.stop(timeout=10)
        node.destroy_node()
    assert bridge.returncode == 0 and 'Traceback' not in bridge.output(), bridge.output()


def test_a_bridge_stopped_while_a_stream_runs_reports_every_message_it_lost(
        ros_context, tmp_path):
    """
    The 1 kHz streams are read best effort: what DDS drops while the bridge has no CPU is told.

    The bridge is stopped (SIGSTOP, as a busy machine deschedules it) while 8 000 poses go out,
    twice its shared-memory queue: the client gets some, the bridge's status and log count the
    rest, and the two add up to every pose published.
    """
    import os
    import signal
    from rclpy.node import Node
    from saw_ros.ros.qos import publisher_profile
    node = Node('bridge_publisher', context=ros_context)
    entry = topics.topic(topics.POSE)
    pose_type = message_class(entry.type)
    publisher = node.create_publisher(pose_type, entry.name, publisher_profile(entry.qos))
    bridge, url = start_bridge(tmp_path)
    client = FoxgloveClient(url)
    published = 0

    def publish(count):
        nonlocal published
        for _ in range(count):
            published += 1
            publisher.publish(pose_type())

    def lost_in_status():
        found = re.findall(r'Total so far: /saw/pose (\d+)',
                           ' '.join(s['message'] for s in client.statuses))
        return int(found[-1]) if found else 0

    try:
        assert wait_for(lambda: topics.POSE in client.channels, 10), client.channels
        client.subscribe([topics.POSE])
        assert wait_for(lambda: publisher.get_subscription_count() == 1, 20), bridge.output()

        def flowing():
            # The bridge's reader matches the publisher a moment after the publisher matched it:
            # what goes out before that is nobody's loss.
            publish(1)
            return client.counts.get(topics.POSE, 0) > 0
        assert wait_for(flowing, 20, poll=0.1), bridge.output()
        unmatched = published - 1       # at most these went out before the reader matched
        received = client.counts[topics.POSE]
        publish(100)
        assert wait_for(lambda: client.counts[topics.POSE] >= received + 100, 20), \
            bridge.output()
        os.kill(bridge.proc.pid, signal.SIGSTOP)
        try:
            publish(8000)
        finally:
            os.kill(bridge.proc.pid, signal.SIGCONT)

        def all_told():
            # The stream goes on: DDS sees a gap at the first message that reaches the bridge
            # after it (the first ones after SIGCONT may still meet a full queue). The one
            # published now is still on its way.
            before = published
            publish(1)
            return lost_in_status() and client.counts[topics.POSE] + lost_in_status() >= \
                before - unmatched
        assert wait_for(all_told, 30, poll=0.1), (
            published, client.counts, client.statuses, bridge.output())
    finally:
        client.close()
        bridge.stop(timeout=10)
        node.destroy_node()
    log = bridge.output()
    assert bridge.returncode == 0 and 'Traceback' not in log, log
    assert 0 < lost_in_status() < published - 100, client.statuses
    assert f'{lost_in_status()} message(s) lost before the bridge' in log, log
    # Every pose published was either handed to the clients or counted lost.
    forwarded, lost = map(int, re.search(r'stopped: (\d+) messages forwarded, .* (\d+) lost '
                                         r'before the bridge \(/saw/pose', log).groups())
    assert published - unmatched <= forwarded + lost <= published, (
        forwarded, lost, published, unmatched)
    assert forwarded >= client.counts[topics.POSE], (forwarded, client.counts)
