"""
The whole graph as separate processes, and the in-process campaign: the same numbers.

Simulator, camera, vision, comparison and recorder on a short run; the campaign on the same
condition.
"""
import math

from diagnostic_msgs.msg import DiagnosticArray
import pytest
from rclpy.serialization import deserialize_message

from saw_ros.analysis.campaign import run_campaign
from saw_ros.bag.reader import BagReader
from saw_ros.graph.pipeline import run_pipeline
from saw_ros.interface import topics

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SLOPE_DEG, VOLTS = 10.0, 6.0


@pytest.fixture(scope='module')
def graph_run(tmp_path_factory):
    out = tmp_path_factory.mktemp('graph')
    run = run_pipeline(out, duration=4.0, real_time_factor=0.5,
                       bag_dir=out / 'bag',
                       scenario={'conditions.slope': math.radians(SLOPE_DEG),
                                 'motor.voltage': VOLTS})
    return run


def test_every_node_exits_cleanly_and_the_comparison_arrives_on_its_topic(graph_run):
    assert graph_run.ok, {name: path.read_text()[-1500:] for name, path in graph_run.logs.items()
                          if graph_run.exit_codes.get(name)}
    reports = [deserialize_message(m.data, DiagnosticArray)
               for m in BagReader(str(graph_run.bag_dir)).messages([topics.COMPARISON])]
    final = [r for r in reports if r.status[0].name.endswith('(final)')]
    assert final, [r.status[0].message for r in reports]
    values = {kv.key: kv.value for kv in final[-1].status[0].values}
    assert values['status'] == 'steady'
    ar_sim, ar_tracked = float(values['ar_sim']), float(values['ar_tracked'])
    assert 0.5 < ar_sim < 0.9 and 0.5 < ar_tracked < 0.9
    assert float(values['relative_error']) < 0.02
    # Nothing lost on the way: every step reached the comparison.
    assert int(float(values['truth_samples'])) == 4000


def test_in_process_campaign_gives_the_same_numbers_as_the_nodes_over_dds(graph_run):
    dds = graph_run.comparison
    (inproc,) = run_campaign([SLOPE_DEG], [VOLTS], workers=1)
    assert inproc.ar_sim == pytest.approx(dds['ar_sim'], rel=0.005)
    assert inproc.ar_tracked == pytest.approx(dds['ar_tracked'], rel=0.005)
    # The helix's mean frequency over whole turns: the node interpolates the turns' ends between
    # joint states 10 ms apart (100 Hz), the campaign between steps: 8e-8 apart.
    assert inproc.v_theory == pytest.approx(dds['v_theory_m_s'], rel=1e-6)


def test_the_bag_opens_in_a_viewer_and_gives_back_the_camera_video(graph_run, tmp_path):
    """What docs/viewers.md promises of the main job's recording, and saw-ros bag video."""
    from saw_ros.analysis.bag_frames import bag_video
    from saw_ros.vision.video import video_info
    counts = {name: t.count for name, t in BagReader(str(graph_run.bag_dir)).info()[
        'topics'].items()}
    frames = counts[topics.IMAGE_COMPRESSED]
    assert frames == 4 * 60 and topics.IMAGE not in counts       # frames k / 60 s, k = 1..240
    # The robot at 60 Hz of simulated time (stamps 1 ms .. 4 s: 241 slots), the estimate every
    # frame.
    assert counts[topics.MARKERS] == 4 * 60 + 1
    assert counts[topics.TRACKING_MARKERS] == frames
    written, fps = bag_video(graph_run.bag_dir, tmp_path / 'camera.mp4')
    assert (written, fps) == (frames, 60.0)
    assert video_info(tmp_path / 'camera.mp4')[:2] == (60.0, frames)


def test_every_frame_id_in_the_bag_is_reachable_from_surface_through_tf(graph_run):
    """Issue 26: /tf and /tf_static recorded with their schemas, and one tree from surface."""
    from saw_ros.ros import tf
    from saw_ros.ros.qos import message_class
    reader = BagReader(str(graph_run.bag_dir))
    summary = reader.info()['topics']
    assert summary[topics.TF].count > 0 and summary[topics.TF_STATIC].count == 1
    children = {}                 # parent -> child frames, from /tf and /tf_static
    used = {}                     # frame id -> a topic that uses it
    seen = {}
    for m in reader.messages():
        if m.topic in (topics.TF, topics.TF_STATIC):
            assert m.schema.name == 'tf2_msgs/msg/TFMessage' and m.schema.data
            for t in deserialize_message(m.data, tf.TFMessage).transforms:
                children.setdefault(t.header.frame_id, set()).add(t.child_frame_id)
                used.setdefault(t.header.frame_id, m.topic)
            continue
        if seen.get(m.topic, 0) >= 3:     # frame ids are constant per topic: a few suffice
            continue
        seen[m.topic] = seen.get(m.topic, 0) + 1
        msg = deserialize_message(m.data, message_class(m.type))
        for header in [getattr(msg, 'header', None)] + [
                marker.header for marker in getattr(msg, 'markers', [])]:
            if header is not None and header.frame_id:
                used.setdefault(header.frame_id, m.topic)
    reachable, todo = {'surface'}, ['surface']
    while todo:
        for child in children.get(todo.pop(), ()):
            if child not in reachable:
                reachable.add(child)
                todo.append(child)
    assert {'base_link', 'saw_camera', 'base_link_tracked'} <= reachable
    assert set(used) <= reachable, {f: used[f] for f in set(used) - reachable}


def test_the_tracker_reads_the_recorded_jpeg_stream_offline(graph_run, capsys):
    """saw-ros track on the bag: every frame tracked, the speed the nodes measured live."""
    from saw_ros.cli.main import main
    assert main(['track', str(graph_run.bag_dir), '--px-per-m', '1200',
                 '--slope-deg', str(SLOPE_DEG)]) == 0
    out = capsys.readouterr().out
    assert f'{graph_run.bag_dir}: 240 frames' in out and 'ok 240,' in out
    steady = float(out.split('steady-state speed (last 4 s):')[1].split('cm/s')[0])
    assert steady == pytest.approx(100 * graph_run.comparison['v_tracked_m_s'], rel=0.02)
