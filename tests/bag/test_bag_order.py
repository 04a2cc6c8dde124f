"""
Messages in a written bag are in log_time order and its chunks do not overlap in time.

That holds although the recorder hands them to the writer in bursts per subscription (``mcap doctor
--strict-message-order`` and ``mcap info``'s "overlaps: no" hold). Checked with the mcap library's
stream reader (file order, not the indexed reader, which sorts).
"""
import os
import random
import signal
import struct
import subprocess
import sys
import textwrap
import time

from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader

from saw_ros.bag import BagReader, BagWriter, qos_profile_dict

T0 = 1_700_000_000_000_000_000
MS = 1_000_000
TOPICS = [('/clock', 'rosgraph_msgs/msg/Clock'), ('/saw/pose', 'geometry_msgs/msg/PoseStamped'),
          ('/saw/twist', 'geometry_msgs/msg/TwistStamped'),
          ('/saw/contacts', 'sensor_msgs/msg/PointCloud2'),
          ('/saw/contact_wrench', 'geometry_msgs/msg/WrenchStamped'),
          ('/saw/joint_states', 'sensor_msgs/msg/JointState'),
          ('/saw/camera/image_raw', 'sensor_msgs/msg/Image')]
IMAGE = len(TOPICS) - 1


def received(seconds=2.0, seed=7):
    """
    Return per topic what a subscription receives, in receive order.

    Each message is (log_time, publish_time, sequence, data); 1 kHz on six topics, 60 Hz images.
    """
    rng = random.Random(seed)
    out = []
    for k in range(IMAGE):
        out.append([(T0 + i * MS + k * 1000 + rng.randrange(900), T0 + i * MS, i + 1,
                     struct.pack('<HI', k, i) + bytes(60)) for i in range(int(seconds * 1000))])
    out.append([(T0 + i * 16_666_667 + 5000, T0 + i * 16_666_667, i + 1,
                 struct.pack('<HI', IMAGE, i) + bytes(20_000)) for i in range(int(seconds * 60))])
    return out


def recorder_order(per_topic, seed=3):
    """
    Return the order the recorder's callbacks take them.

    Executor rounds every ms, each round the ready subscriptions in random order, each taking
    everything received so far; a 1 kHz subscription is ready in 40 % of the rounds (bursts of ~2.5
    ms), the image one (its own participant and thread) only every 150 rounds.
    """
    rng = random.Random(seed)
    pending = [list(reversed(msgs)) for msgs in per_topic]
    order = []
    now = T0
    while any(pending):
        now += MS
        for k in rng.sample(range(len(pending)), len(pending)):
            ready = (now - T0) % (150 * MS) == 0 if k == IMAGE else rng.random() < 0.4
            while ready and pending[k] and pending[k][-1][0] <= now:
                order.append((k,) + pending[k].pop())
        if now > T0 + 10**10:
            for k, rest in enumerate(pending):
                order += [(k,) + m for m in reversed(rest)]
                rest.clear()
    return order


def write(path, order, **options):
    bag = BagWriter(str(path), chunk_size=64 * 1024, **options)
    for name, type_name in TOPICS:
        bag.add_topic(name, type_name, [qos_profile_dict()])
    for k, log_time, publish_time, sequence, data in order:
        bag.write(TOPICS[k][0], data, log_time, publish_time, sequence)
    bag.close()
    return bag


def file_messages(mcap_path):
    """(log_time, publish_time, sequence, data) in file order, by mcap's stream reader."""
    with open(mcap_path, 'rb') as f:
        return [(r.log_time, r.publish_time, r.sequence, r.data)
                for r in StreamReader(f).records if isinstance(r, Message)]


def chunk_ranges(mcap_path):
    with open(mcap_path, 'rb') as f:
        indexes = make_reader(f).get_summary().chunk_indexes
    return [(c.message_start_time, c.message_end_time)
            for c in sorted(indexes, key=lambda c: c.chunk_start_offset)]


def assert_ordered(mcap_path):
    times = [m[0] for m in file_messages(mcap_path)]
    steps_back = [a - b for a, b in zip(times, times[1:]) if b < a]
    assert not steps_back, f'{len(steps_back)} steps back in log_time, max {max(steps_back)} ns'
    ranges = chunk_ranges(mcap_path)
    overlaps = [(a, b) for a, b in zip(ranges, ranges[1:]) if b[0] <= a[1]]
    assert not overlaps, f'{len(overlaps)} chunks overlap the next one in time'
    return times, ranges


def test_recorder_bursts_are_written_in_log_time_order(tmp_path):
    per_topic = received()
    order = recorder_order(per_topic)
    log_times = [m[1] for m in order]
    back = max(a - b for a, b in zip(log_times, log_times[1:]))
    assert back > 100 * MS  # the input does step back (images up to 150 ms)
    bag = write(tmp_path / 'run', order)
    path = tmp_path / 'run' / 'run_0.mcap'
    times, ranges = assert_ordered(path)
    assert len(ranges) > 10
    assert bag.late_messages == 0 and bag.buffered == 0
    # Every message kept its own times, sequence and bytes.
    assert sorted(file_messages(path)) == sorted(m for msgs in per_topic for m in msgs)
    # Our reader gives the file order too; metadata.yaml's start and duration are the span.
    ours = [m.log_time for m in BagReader(str(tmp_path / 'run')).messages()]
    assert ours == times
    meta = bag.metadata()
    assert meta['starting_time']['nanoseconds_since_epoch'] == times[0]
    assert meta['duration']['nanoseconds'] == times[-1] - times[0]


def test_message_later_than_the_window_lands_in_order_and_is_counted(tmp_path):
    bag = BagWriter(str(tmp_path / 'late'), reorder_window_ns=10 * MS)
    bag.add_topic('/a', 'std_msgs/msg/String', [qos_profile_dict()])
    for i in range(100):                      # 0 .. 99 ms
        bag.write('/a', b'%d' % i, T0 + i * MS, T0 + i * MS - 7, i)
    bag.write('/a', b'late', T0 + 50 * MS + 3, T0 + 50 * MS, 1000)  # 49 ms late: 0..~89 written
    bag.close()
    rows = file_messages(tmp_path / 'late' / 'late_0.mcap')
    times = [r[0] for r in rows]
    assert times == sorted(times) and len(rows) == 101
    late = [r for r in rows if r[3] == b'late'][0]
    written_before = rows[:rows.index(late)]
    assert late[0] == written_before[-1][0] > T0 + 50 * MS + 3   # raised to the last written
    assert late[1:3] == (T0 + 50 * MS, 1000)                       # publish time, sequence kept
    assert bag.late_messages == 1
    assert bag.max_lateness_ns == late[0] - (T0 + 50 * MS + 3)


def test_topic_with_two_publishers_out_of_order_within_itself(tmp_path):
    bag = BagWriter(str(tmp_path / 'two'), chunk_size=1024)
    bag.add_topic('/a', 'std_msgs/msg/String', [qos_profile_dict()])
    rng = random.Random(1)
    stamps = [T0 + i * MS for i in range(2000)]
    arrival = sorted(stamps, key=lambda t: t + rng.randrange(30 * MS))   # up to 30 ms apart
    for t in arrival:
        bag.write('/a', b'%d' % t, t, t, 0)
    bag.close()
    times, _ = assert_ordered(tmp_path / 'two' / 'two_0.mcap')
    assert times == stamps and bag.late_messages == 0


def test_buffer_byte_limit_writes_the_oldest_first(tmp_path):
    per_topic = received(seconds=0.5)
    order = recorder_order(per_topic)
    # 50 kB hold ~0.13 s of the 1 kHz topics (400 kB/s): less than the images' 150 ms lag
    bag = write(tmp_path / 'small', order, max_buffer_bytes=50_000)
    times, _ = assert_ordered(tmp_path / 'small' / 'small_0.mcap')
    assert len(times) == sum(len(m) for m in per_topic)   # late ones too
    assert bag.late_messages > 0 and bag.max_lateness_ns < 150 * MS


def test_quiet_recording_writes_its_buffer(tmp_path):
    """
    No message for idle_flush_s.

    The buffer goes to the file (a kill -9 then loses only the open chunk, as before the buffer).
    """
    bag = BagWriter(str(tmp_path / 'quiet'), chunk_size=1024, idle_flush_s=0.2)
    bag.add_topic('/a', 'std_msgs/msg/String', [qos_profile_dict()])
    for i in range(300):                          # 0.3 s: all within the 0.5 s window
        bag.write('/a', b'x' * 50, T0 + i * MS, T0 + i * MS, i)
    assert bag.buffered == 300
    assert wait_until(lambda: bag.buffered == 0, 5.0)
    reader = BagReader(str(tmp_path / 'quiet'))  # still open: as if killed now
    assert 270 < len(list(reader.messages())) < 300 and not reader.complete
    bag.close()
    assert len(list(BagReader(str(tmp_path / 'quiet')).messages())) == 300


def wait_until(condition, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.02)
    return condition()


def test_killed_writer_leaves_complete_ordered_chunks(tmp_path):
    """
    Kill -9 while recording: the chunks written so far are readable and in order.

    What is lost is the reorder buffer (0.5 s) and the open chunk.
    """
    script = textwrap.dedent(f"""
        import os, signal, sys
        sys.path.insert(0, {os.getcwd()!r})
        from saw_ros.bag import BagWriter, qos_profile_dict
        bag = BagWriter({str(tmp_path / 'killed')!r}, chunk_size=16 * 1024)
        bag.add_topic('/a', 'std_msgs/msg/String', [qos_profile_dict()])
        bag.add_topic('/b', 'std_msgs/msg/String', [qos_profile_dict()])
        for burst in range(400):                  # 2 s: bursts of 5 ms, /b 3 ms behind /a
            for topic, lag in (('/a', 0), ('/b', 3)):
                for i in range(5):
                    t = {T0} + (burst * 5 + i - lag) * {MS}
                    bag.write(topic, b'x' * 100, t, t, burst * 5 + i)
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    proc = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    reader = BagReader(str(tmp_path / 'killed'))
    times = [m.log_time for m in reader.messages()]
    assert not reader.complete and not reader.damage
    assert times == sorted(times)
    # 4000 written; the last 0.5 s (~1000) buffered and up to one chunk (~140) not in the file
    assert 2800 < len(times) < 3100
