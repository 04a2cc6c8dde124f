"""
No hidden environment.

What we ship finds message definitions, type hashes and our own msg_config files from the installed
packages themselves, without AMENT_PREFIX_PATH (a shell with only `source .venv/bin/activate`,
`.venv/bin/saw-ros` called directly, a colcon install sourced without its underlay). Where nothing
can be found, the recorder refuses before creating anything, with one line saying what to source.
"""
import os
from pathlib import Path
import subprocess
import sys
import textwrap

import pytest

from saw_ros.bag import BagReader
from saw_ros.bag import schema
from saw_ros.bench.loadgen import published_counts
from saw_ros.graph.process import isolated_ros_env, ManagedProcess, node_command, wait_for
from saw_ros.interface import share


def without_ament(env=None):
    env = dict(os.environ if env is None else env)
    env.pop('AMENT_PREFIX_PATH', None)
    return env


@pytest.fixture
def no_ament(monkeypatch):
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    for cached in (schema.message_definition, schema._msg_text, schema.type_hash):
        cached.cache_clear()
    yield
    for cached in (schema.message_definition, schema._msg_text, schema.type_hash):
        cached.cache_clear()


def fake_install(prefix: Path, site: str, package: str, python=True) -> Path:
    """Return an install prefix holding one interface package, as ament installs it."""
    (prefix / 'share' / package / 'msg').mkdir(parents=True)
    (prefix / 'share' / package / 'package.xml').write_text('<package format="3"/>')
    (prefix / 'share' / package / 'msg' / 'Thing.msg').write_text('float64 x\n')
    index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True, exist_ok=True)
    (index / package).write_text('')
    if python:
        (prefix / site / package).mkdir(parents=True)
        (prefix / site / package / '__init__.py').write_text('')
    return prefix / site


# Where each kind of install puts Python packages, relative to its prefix.
LAYOUTS = {
    'pip_venv': ('venv', 'lib/python3.11/site-packages'),
    'opt_ros_jazzy': ('opt/ros/jazzy', 'local/lib/python3.12/dist-packages'),
    'colcon_isolated': ('ws/install/fake_pkg', 'lib/python3.11/site-packages'),
    'colcon_merged': ('ws/install', 'lib/python3.11/site-packages'),
}


@pytest.mark.parametrize('layout', sorted(LAYOUTS))
def test_share_found_beside_the_python_package_in_every_layout(layout, tmp_path, monkeypatch,
                                                               no_ament):
    prefix_rel, site = LAYOUTS[layout]
    package = f'saw_fake_{layout}_msgs'
    prefix = tmp_path / prefix_rel
    monkeypatch.syspath_prepend(str(fake_install(prefix, site, package)))
    found = share.share_file(package, 'msg', 'Thing.msg')
    assert Path(found) == prefix / 'share' / package / 'msg' / 'Thing.msg'


def test_colcon_symlink_install_prefix_is_where_the_link_is(tmp_path, monkeypatch, no_ament):
    prefix = tmp_path / 'install' / 'saw_fake_sym_msgs'
    fake_install(prefix, 'lib/python3.11/site-packages', 'saw_fake_sym_msgs', python=False)
    build = tmp_path / 'build' / 'saw_fake_sym_msgs' / 'saw_fake_sym_msgs'
    build.mkdir(parents=True)
    (build / '__init__.py').write_text('')
    site = prefix / 'lib/python3.11/site-packages'
    site.mkdir(parents=True)
    (site / 'saw_fake_sym_msgs').symlink_to(build)
    monkeypatch.syspath_prepend(str(site))
    assert Path(share.share_directories('saw_fake_sym_msgs')[0]) == (
        prefix / 'share' / 'saw_fake_sym_msgs')


def test_ament_index_is_the_fallback_and_the_error_says_what_to_source(tmp_path, monkeypatch,
                                                                       no_ament):
    prefix = tmp_path / 'prefix'
    fake_install(prefix, 'unused', 'saw_fake_nopy_msgs', python=False)
    with pytest.raises(share.PackageNotFound) as missing:
        share.share_file('saw_fake_nopy_msgs', 'msg', 'Thing.msg')
    message = str(missing.value)
    assert '\n' not in message and 'source' in message and 'AMENT_PREFIX_PATH not set' in message
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(prefix))
    assert Path(share.share_file('saw_fake_nopy_msgs', 'msg', 'Thing.msg')) == (
        prefix / 'share' / 'saw_fake_nopy_msgs' / 'msg' / 'Thing.msg')


def test_python_package_location_comes_before_the_ament_index(tmp_path, monkeypatch, no_ament):
    site = fake_install(tmp_path / 'used', 'lib/python3.11/site-packages', 'saw_fake_both_msgs')
    fake_install(tmp_path / 'other', 'unused', 'saw_fake_both_msgs', python=False)
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'other'))
    assert share.share_directories('saw_fake_both_msgs') == [
        str(tmp_path / 'used' / 'share' / 'saw_fake_both_msgs'),
        str(tmp_path / 'other' / 'share' / 'saw_fake_both_msgs')]


def test_installed_message_definitions_and_hashes_without_ament_prefix_path(no_ament):
    import geometry_msgs
    path = Path(schema._share_file('geometry_msgs/msg/PoseStamped', '.msg'))
    prefix = path.parents[3]     # <prefix>/share/geometry_msgs/msg/PoseStamped.msg
    assert Path(geometry_msgs.__file__).is_relative_to(prefix)
    text = schema.message_definition('geometry_msgs/msg/PoseStamped')
    assert 'MSG: builtin_interfaces/Time' in text
    assert schema.type_hash('rosgraph_msgs/msg/Clock').startswith('RIHS01_')
    schema.check_definitions()


def test_config_files_found_by_the_installed_package_without_ament_prefix_path(tmp_path):
    """
    Run from elsewhere: config_path and the recorder's default topics find msg_config/.

    In a colcon workspace this imports the installed saw_ros, not the source.
    """
    code = textwrap.dedent("""
        import saw_ros
        from saw_ros.interface.config import config_path
        from saw_ros.ros.nodes.recorder import default_topics
        print(saw_ros.__file__)
        print(config_path('record_topics.yaml'))
        print(default_topics())
    """)
    out = subprocess.run([sys.executable, '-c', code], cwd=tmp_path, env=without_ament(),
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    module, config, topics = out.stdout.splitlines()[-3:]
    assert Path(config).is_file()
    assert "'/clock'" in topics
    # Compared resolved: under colcon --symlink-install the package is imported through the
    # build folder's symlinks while config_path resolves its own location to the source tree.
    package_root = Path(module).resolve().parents[1]  # source tree, or an install's site-packages
    config = Path(config).resolve()
    if (package_root / 'msg_config').is_dir():
        assert config.parent == (package_root / 'msg_config').resolve()
    else:  # an install: <prefix>/share/saw_ros/msg_config of the same prefix
        assert config.parent.parent.name == 'saw_ros'
        assert package_root.is_relative_to(config.parents[3])


@pytest.mark.ros
@pytest.mark.slow
def test_recorder_writes_a_full_bag_without_ament_prefix_path(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    env = without_ament(isolated_ros_env())
    out = tmp_path / 'bag'
    # Default topics (msg_config/record_topics.yaml), run from outside the source tree.
    rec = ManagedProcess('recorder', node_command('recorder', params={'output': str(out)}),
                         env, tmp_path / 'logs', cwd=tmp_path)
    assert wait_for(lambda: 'recording to' in rec.output() or rec.returncode is not None, 30), \
        rec.output()
    gen = ManagedProcess('loadgen', node_command('loadgen', params={
        'rate': 1000.0, 'duration': 1.0, 'streams': 6, 'wait_subscribers': 1},
        package='saw_ros.bench'), env,
        tmp_path / 'logs', cwd=tmp_path)
    assert gen.wait(90) == 0, gen.output()
    published = published_counts(gen.output())
    assert rec.stop(30) == 0, rec.output()
    assert 'AMENT_PREFIX_PATH' not in rec.output()
    reader = BagReader(str(out))
    assert reader.complete
    assert {name: t.count for name, t in reader.topics().items()} == published
    assert len(published) == 6 and min(published.values()) > 0
    with open(out / 'bag_0.mcap', 'rb') as f:
        mcap = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = mcap.get_summary()
        schemas = {s.name: s for s in summary.schemas.values()}
        assert len(schemas) == 6   # one per type: Clock, Pose/Twist/WrenchStamped, ...
        for name, found in schemas.items():
            assert found.encoding == 'ros2msg'
            assert found.data.decode() == schema.message_definition(name), name
        for channel in summary.channels.values():
            assert channel.metadata['topic_type_hash'].startswith('RIHS01_'), channel.topic
        decoded = sum(1 for _ in mcap.iter_decoded_messages())
    assert decoded == sum(published.values())


@pytest.mark.ros
def test_recorder_without_definitions_refuses_before_creating_the_bag(tmp_path):
    """
    Nothing beside the Python packages and no AMENT_PREFIX_PATH.

    One line saying what to source, exit code 1, no bag directory.
    """
    out = tmp_path / 'bag'
    code = textwrap.dedent(f"""
        import sys
        import saw_ros.interface.share
        # as if nothing were found there
        saw_ros.interface.share.python_locations = lambda package: []
        from saw_ros.ros.nodes.recorder import main
        sys.exit(main(['recorder', '--ros-args', '-p', 'output:={out}']))
    """)
    proc = subprocess.run([sys.executable, '-c', code], cwd=tmp_path,
                          env=without_ament(isolated_ros_env()), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = [line for line in (proc.stdout + proc.stderr).splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert 'refusing to record' in lines[0] and 'source' in lines[0], lines[0]
    assert not out.exists()
