"""
``saw-ros bag reindex``: an unfinished bag made a finished one that the standard reader opens.

Checked with mcap's own seeking reader (which needs the summary) and its summary statistics,
against what our reader salvages from the unfinished file; then after ``kill -9`` of a real
recorder at random moments.
"""
import os
import random
import shutil
import signal
import time

from mcap.reader import make_reader
from mcap_ros2._dynamic import serialize_dynamic
import pytest
from saw_ros.bag import BagReader, BagWriter, qos_profile_dict
from saw_ros.bag.reindex import SUFFIX
from saw_ros.bag.schema import message_definition
from saw_ros.cli.main import main
from saw_ros.graph.process import ManagedProcess, node_command, wait_for
import yaml

CLOCK = 'rosgraph_msgs/msg/Clock'
T0 = 1_700_000_000_000_000_000
N = 1000


@pytest.fixture(scope='module')
def pristine(tmp_path_factory):
    """Return a finished bag: /clock and /other at 1 kHz for 1 s, 4 KiB chunks."""
    directory = tmp_path_factory.mktemp('pristine') / 'bag'
    clock = serialize_dynamic(CLOCK, message_definition(CLOCK))[CLOCK]
    bag = BagWriter(str(directory), chunk_size=4096, compression='zstd',
                    custom_data={'saw_ros.lost_messages': '{"/clock": 0, "/other": 0}'})
    bag.add_topic('/clock', CLOCK, [qos_profile_dict()])
    bag.add_topic('/other', CLOCK, [qos_profile_dict(history='keep_last', depth=7)])
    for i in range(N):
        t = T0 + i * 10**6
        data = clock({'clock': {'sec': i // 1000, 'nanosec': (i % 1000) * 10**6}})
        bag.write('/clock', data, t, t, i + 1)
        bag.write('/other', data, t + 1, t - 5, i + 1)
    bag.close()
    return directory


def reindex(capsys, directory):
    code = main(['bag', 'reindex', str(directory)])
    out = capsys.readouterr()
    return code, out.out, out.err


def standard_read(directory):
    """Return what mcap's seeking reader reads, and the message count of the summary."""
    files = yaml.safe_load((directory / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']['relative_file_paths']
    assert len(files) == 1
    with open(directory / files[0], 'rb') as f:
        reader = make_reader(f)
        assert type(reader).__name__ == 'SeekingReader'
        summary = reader.get_summary()
        messages = [(c.topic, m.log_time, m.publish_time, m.sequence, m.data)
                    for _, c, m in reader.iter_messages()]
    return messages, summary.statistics.message_count


def ours(directory):
    return [(m.topic, m.log_time, m.publish_time, m.sequence, m.data)
            for m in BagReader(str(directory), salvage=True).messages()]


def check_reindexed(directory, before, out):
    """Check a reindexed bag against the messages read from it before (``before``)."""
    messages, count = standard_read(directory)
    assert messages == before and count == len(before)
    meta = yaml.safe_load((directory / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']
    assert meta['message_count'] == len(before)
    counts = {e['topic_metadata']['name']: e['message_count']
              for e in meta['topics_with_message_count']}
    for topic, n in counts.items():
        assert n == sum(1 for m in before if m[0] == topic)
        assert f'{topic}: {n}' in out
    assert f'reindexed: {len(before)} messages' in out
    reader = BagReader(str(directory))
    assert reader.info()['complete'] and reader.shortfall() is None
    assert os.path.isfile(directory / (meta['relative_file_paths'][0] + SUFFIX))
    assert [p for p in os.listdir(directory) if p.startswith('.')] == []
    return meta


@pytest.mark.parametrize('fraction', [0.05, 0.4, 0.93])
def test_killed_recording_is_reindexed_for_the_standard_reader(
        pristine, tmp_path, capsys, fraction):
    directory = tmp_path / 'bag'
    shutil.copytree(pristine, directory)
    os.remove(directory / 'metadata.yaml')              # as after kill -9
    path = directory / 'bag_0.mcap'
    with open(path, 'r+b') as f:
        f.truncate(int(os.path.getsize(path) * fraction))
    before = ours(directory)
    with pytest.raises(Exception):                      # what the issue measured
        with open(path, 'rb') as f:
            list(make_reader(f).iter_messages())
    code, out, err = reindex(capsys, directory)
    assert code == 0, err
    meta = check_reindexed(directory, before, out)
    assert 'is unfinished' in meta['custom_data']['saw_ros.reindexed']
    assert meta['topics_with_message_count'][1]['topic_metadata']['offered_qos_profiles'][0][
        'depth'] == 7
    # Twice is harmless.
    code, out, _ = reindex(capsys, directory)
    assert code == 0 and 'is a finished bag' in out and 'nothing to reindex' in out
    assert standard_read(directory)[0] == before


def test_copy_cut_short_keeps_its_metadata_custom_data(pristine, tmp_path, capsys):
    directory = tmp_path / 'bag'
    shutil.copytree(pristine, directory)
    path = directory / 'bag_0.mcap'
    with open(path, 'r+b') as f:
        f.truncate(os.path.getsize(path) // 2)
    before = ours(directory)
    code, out, err = reindex(capsys, directory)
    assert code == 0, err
    meta = check_reindexed(directory, before, out)
    assert meta['custom_data']['saw_ros.lost_messages'] == '{"/clock": 0, "/other": 0}'
    said = meta['custom_data']['saw_ros.reindexed']
    assert f'of {2 * N} (metadata.yaml); missing {2 * N - len(before)}' in said
    assert said in out


def test_refusals_are_one_line(pristine, tmp_path, capsys):
    directory = tmp_path / 'bag'
    shutil.copytree(pristine, directory)
    os.remove(directory / 'metadata.yaml')
    (directory / ('bag_0.mcap' + SUFFIX)).write_bytes(b'earlier')
    code, out, err = reindex(capsys, directory)
    assert code == 2 and out == '' and len(err.strip().splitlines()) == 1
    assert 'exists (an earlier reindex' in err
    code, _, err = reindex(capsys, directory / 'bag_0.mcap')
    assert code == 2 and 'is not a bag directory' in err
    code, _, err = reindex(capsys, tmp_path / 'nothing')
    assert code == 2 and len(err.strip().splitlines()) == 1


@pytest.mark.ros
@pytest.mark.slow
def test_recorder_killed_at_random_moments_is_reindexed(tmp_path, capsys):
    """Three recorders on one load, each killed with SIGKILL at its own random moment."""
    rng = random.Random()
    outs = [tmp_path / f'bag{k}' for k in range(3)]
    recs = [ManagedProcess(f'recorder{k}', node_command('recorder', params={
        'output': str(out), 'chunk_size': 65536}), os.environ, tmp_path / 'logs')
        for k, out in enumerate(outs)]
    for rec in recs:
        assert wait_for(lambda rec=rec: 'recording to' in rec.output(), 30), rec.output()
    gen = ManagedProcess('loadgen', node_command('loadgen', params={
        'rate': 1000.0, 'duration': 2.5, 'streams': 6, 'wait_subscribers': 3},
        package='saw_ros.bench'), os.environ, tmp_path / 'logs')
    for rec in recs:
        assert wait_for(lambda rec=rec: rec.output().count('recording /saw/') >= 5, 30), \
            rec.output()
    began = time.monotonic()
    # (2.5 s of load, 15 000 messages: chunks closed and one open at any moment of it)
    moments = sorted(rng.uniform(0.3, 2.2) for _ in recs)
    for rec, moment in zip(recs, moments):
        time.sleep(max(0.0, began + moment - time.monotonic()))   # the random moment itself
        rec.signal(signal.SIGKILL)
        assert rec.wait(10) == -signal.SIGKILL
    assert gen.wait(60) == 0, gen.output()
    for out, moment in zip(outs, moments):
        assert not (out / 'metadata.yaml').exists()
        before = ours(out)
        code, said, err = reindex(capsys, out)
        assert code == 0, (moment, err)
        check_reindexed(out, before, said)
        print(f'killed at {moment:.2f} s: {len(before)} messages, reindexed')
