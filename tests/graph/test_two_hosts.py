"""
The graph split over two hosts loses nothing: the simulator on one, the other nodes on the other.

Camera, vision, comparison and recorder run on the second host. The hosts are two network
namespaces joined by a virtual Ethernet pair, each with a /dev/shm and a machine id of its own
(Fast DDS uses shared memory between processes of one machine: without them the data would not
cross the network). Discovery is Fast DDS's own multicast, with msg_config/fastdds_hosts.xml and
no peer list. Needs root (the tests skip, with the reason, where namespaces cannot be made).
"""
import os
from pathlib import Path
import shutil
import subprocess
import uuid

import pytest
from saw_ros.bench.loadgen import published_counts
from saw_ros.graph.process import isolated_ros_env, ManagedProcess, node_command, wait_for
from saw_ros.interface import topics
from saw_ros.interface.config import config_path

CONFIG = Path(config_path('fastdds.xml')).parent
SUBNET = '10.213.{}.{}'


def _ip(*args):
    subprocess.run(['ip', *args], check=True, capture_output=True, text=True)


@pytest.fixture
def hosts():
    """Yield two network namespaces joined by a veth pair, each its own machine id; removed."""
    if os.geteuid() != 0:
        pytest.skip('network namespaces need root')
    if not (shutil.which('ip') and shutil.which('unshare')):
        pytest.skip('needs ip (iproute2) and unshare (util-linux)')
    tag = uuid.uuid4().hex[:6]
    names = [f'saw{tag}a', f'saw{tag}b']
    net = int(tag[:2], 16)
    made = []
    try:
        for name in names:
            _ip('netns', 'add', name)
            made.append(name)
        _ip('link', 'add', f'v{tag}a', 'type', 'veth', 'peer', 'name', f'v{tag}b')
        for k, name in enumerate(names):
            link = f'v{tag}{"ab"[k]}'
            _ip('link', 'set', link, 'netns', name)
            _ip('-n', name, 'addr', 'add', SUBNET.format(net, k + 1) + '/24', 'dev', link)
            _ip('-n', name, 'link', 'set', link, 'up', 'multicast', 'on')
            _ip('-n', name, 'link', 'set', 'lo', 'up')
            _ip('-n', name, 'route', 'add', 'default', 'dev', link)   # as a host's own
            # ip netns exec binds /etc/netns/<name>/* over /etc: a machine id per host.
            etc = Path('/etc/netns') / name
            etc.mkdir(parents=True, exist_ok=True)
            (etc / 'machine-id').write_text(uuid.uuid4().hex + '\n')
    except (subprocess.CalledProcessError, OSError) as exc:
        _remove(made)
        reason = getattr(exc, 'stderr', '') or exc
        pytest.skip(f'cannot make network namespaces here: {str(reason).strip()}')
    yield names
    _remove(made)


def _remove(names):
    for name in names:
        subprocess.run(['ip', 'netns', 'del', name], capture_output=True)
        shutil.rmtree(Path('/etc/netns') / name, ignore_errors=True)
        shutil.rmtree(Path('/dev/shm') / f'{name}.shm', ignore_errors=True)
    try:
        os.rmdir('/etc/netns')      # made for the tests (ip netns exec reads it), if now empty
    except OSError:
        pass


def on_host(name):
    """
    Return the command prefix that runs a process on host ``name``.

    Its network namespace, and the host's own /dev/shm (a directory per host, bound over
    /dev/shm in the process's mount namespace): the processes of one host share memory as on
    one machine, those of the other host cannot.
    """
    shm = Path('/dev/shm') / f'{name}.shm'
    shm.mkdir(exist_ok=True)
    return ['ip', 'netns', 'exec', name, 'unshare', '--mount', '--propagation', 'private',
            'sh', '-c', f'mount --bind {shm} /dev/shm && exec "$@"', 'sh']


def sent_bytes(name):
    """Return the bytes host ``name`` has sent on its end of the veth pair."""
    link = f'v{name[3:9]}{name[-1]}'
    return int(subprocess.run(['ip', 'netns', 'exec', name, 'cat',
                               f'/sys/class/net/{link}/statistics/tx_bytes'],
                              check=True, capture_output=True, text=True).stdout)


def hosts_env(profile):
    env = isolated_ros_env()
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SUBNET'     # the hosts' network, not localhost
    env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(CONFIG / profile)
    return env


def test_hosts_profile_is_the_default_one_open_to_other_hosts():
    def profiles(name):
        text = (CONFIG / name).read_text()
        return text[text.index('<profiles'):]
    default, hosts = profiles('fastdds.xml'), profiles('fastdds_hosts.xml')
    loopback = '      <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>\n'
    buffers = ('      <sendBufferSize>4194304</sendBufferSize>\n'
               '      <receiveBufferSize>4194304</receiveBufferSize>\n')
    assert loopback in default and buffers in hosts
    assert default.replace(loopback, '') == hosts.replace(buffers, '')


def _loadgen_to_recorder(hosts, env, tmp_path, timeout):
    out = tmp_path / 'bag'
    rec = ManagedProcess('recorder', on_host(hosts[1]) + node_command(
        'recorder', params={'output': str(out)}), env, tmp_path / 'logs')
    assert wait_for(lambda: 'recording to' in rec.output(), 30), rec.output()
    gen = ManagedProcess('loadgen', on_host(hosts[0]) + node_command('loadgen', params={
        'rate': 1000.0, 'duration': 3.0, 'streams': 6, 'wait_subscribers': 1},
        package='saw_ros.bench'), env, tmp_path / 'logs')
    matched = wait_for(lambda: rec.output().count('recording /saw/') >= 5, timeout)
    return rec, gen, matched, out


def test_the_default_profile_keeps_to_one_host(hosts, tmp_path):
    # msg_config/fastdds.xml is loopback-only: the other host is never found.
    rec, gen, matched, _ = _loadgen_to_recorder(hosts, hosts_env('fastdds.xml'), tmp_path, 5)
    assert not matched, rec.output()
    gen.stop(timeout=5)
    rec.stop(timeout=10)


def test_loadgen_and_recorder_on_two_hosts_lose_nothing(hosts, tmp_path):
    rec, gen, matched, out = _loadgen_to_recorder(hosts, hosts_env('fastdds_hosts.xml'),
                                                  tmp_path, 30)
    assert matched, rec.output()
    assert gen.wait(60) == 0, gen.output()
    published = published_counts(gen.output())
    assert rec.stop(timeout=30) == 0
    final = [line for line in rec.output().splitlines() if 'finished:' in line][0]
    assert final.endswith('; lost 0'), final
    from saw_ros.bag import BagReader
    counts = {n: t.count for n, t in BagReader(str(out)).topics().items()}
    # Every message the generator published is in the bag. (How many it published in its 3 s
    # is the machine's: 3000 a stream quiet, 2707 beside two CPU hogs on the slower kind; half
    # is plenty to say that a 1 kHz stream crossed.)
    assert counts == published and min(counts.values()) >= 1500, (counts, published)


@pytest.mark.slow
def test_the_graph_split_over_two_hosts_loses_nothing(hosts, tmp_path):
    from saw_ros.bench.pipeline import check
    from saw_ros.graph.pipeline import run_pipeline
    # At half real time: what this test asks is whether the network loses anything, and the
    # slowest 2-core machine measured keeps the whole graph without loss up to 0.9 x real time
    # on one host (pipeline_max_realtime_factor, docs/measurements.md): at 1.0 there the vision
    # node, on the same host as the camera, falls behind its frames.
    duration, factor = 4.0, 0.5      # (6 s sent 29 MB over the veth: 4 s are plenty)
    here, there = on_host(hosts[0]), on_host(hosts[1])
    run = run_pipeline(tmp_path / 'out', duration=duration, real_time_factor=factor,
                       bag_dir=tmp_path / 'bag', env=hosts_env('fastdds_hosts.xml'),
                       hosts={'simulator': here, 'camera': there, 'vision': there,
                              'comparison': there, 'recorder': there, 'ready': there})
    result = check(run, duration, factor)
    # Nothing lost on the network: the simulator's streams reach the other host whole (in the
    # bag, and every pose and phase in the camera and the comparison). Between camera and vision,
    # on one host, frames can be lost when a shared machine starves the tracker: the check
    # counts them (the tracker's own status against the camera's frames), the pace is the
    # bench's figure (saw-ros bench), neither is what this test is about.
    crossing = set(topics.step_topics()) | {topics.JOINT_STATES, 'camera inputs',
                                            'comparison truth'}
    lost = {t: n for t, n in result['lost_by_topic'].items() if t in crossing and n}
    problems = [p for p in result['problems'] if not p.startswith((
        'simulated time ran at', 'simulator fell behind', 'last tracking status'))]
    assert not lost and not problems, (result['lost_by_topic'], problems)
    print(f"two hosts at {factor}: lost {result['lost']}, simulated time at "
          f"{result['achieved_rtf']} x real time, {sent_bytes(hosts[0]) / 1e6:.1f} MB sent")
    # Over the network: 4 s of the simulator's streams are several MB (0.9 MB/s in the bag, the
    # pose three times over: recorder, camera, comparison).
    assert sent_bytes(hosts[0]) > 3e6, sent_bytes(hosts[0])
    final = [line for line in run.logs['recorder'].read_text().splitlines()
             if 'finished:' in line][0]
    assert final.endswith('; lost 0'), final
