"""The reference recordings kept in git are complete rosbag2 bags."""
import os

import pytest

from saw_ros.bag import BagReader

ROOT = os.path.join(os.path.dirname(__file__), '..', 'bags')
SIM_TOPICS = {'/clock', '/saw/pose', '/saw/twist', '/saw/contacts', '/saw/contact_wrench',
              '/saw/joint_states'}


def test_reference_default_has_every_simulator_topic_at_1khz():
    path = os.path.join(ROOT, 'reference_default')
    if not os.path.isdir(path):
        pytest.skip('bags/reference_default not made (scripts/make_reference_bags.sh)')
    reader = BagReader(path)
    topics = reader.topics()
    assert SIM_TOPICS <= set(topics)
    counts = {topics[t].count for t in SIM_TOPICS}
    assert len(counts) == 1 and counts.pop() >= 1000
    assert reader.complete and reader.metadata['version'] == 9
    stamps = [msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
              for _, msg in reader.decoded_messages(['/saw/pose'])]
    assert all(b - a == 1_000_000 for a, b in zip(stamps, stamps[1:]))
