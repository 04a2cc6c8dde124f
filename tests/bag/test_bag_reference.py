"""The reference recordings kept in git are complete rosbag2 bags."""
import os

from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
import pytest

from saw_ros.bag import BagReader

ROOT = os.path.join(os.path.dirname(__file__), '..', '..', 'bags')
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


@pytest.mark.parametrize('name', ['reference_default', 'reference_camera'])
def test_reference_bags_are_in_log_time_order_with_chunks_apart(name):
    """
    Check what ``mcap doctor --strict-message-order`` and ``mcap info`` ("overlaps: no") check.

    Read in file order with mcap's stream reader; and intact (every chunk CRC).
    """
    path = os.path.join(ROOT, name, f'{name}_0.mcap')
    if not os.path.isfile(path):
        pytest.skip(f'bags/{name} not made (scripts/make_reference_bags.sh)')
    with open(path, 'rb') as f:
        times = [r.log_time for r in StreamReader(f, validate_crcs=True).records
                 if isinstance(r, Message)]
        f.seek(0)
        summary = make_reader(f).get_summary()
    assert times and all(a <= b for a, b in zip(times, times[1:]))
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert all(a.message_end_time < b.message_start_time for a, b in zip(chunks, chunks[1:]))
    assert summary.statistics.message_count == len(times)
    reader = BagReader(os.path.join(ROOT, name))
    assert sum(t.count for t in reader.topics().values()) == len(times)
    assert reader.complete and not reader.damage
