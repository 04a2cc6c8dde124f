"""
launch/saw.launch.py against the main job's tables, without ``launch`` (not among the wheels).

The file is read with ast: it takes its nodes and parameters from
saw_ros.graph.pipeline.node_parameters (what run_pipeline starts), its defaults are the demo's,
and every parameter it gives a node is one that node declares.
"""
import ast
import inspect
from pathlib import Path

from saw_ros.cli.commands import demo
from saw_ros.core.params import Scenario
from saw_ros.graph import pipeline
from saw_ros.interface import topics

ROOT = Path(__file__).resolve().parents[2]
LAUNCH = ROOT / 'launch' / 'saw.launch.py'


def _tree():
    return ast.parse(LAUNCH.read_text(encoding='utf-8'))


def _arguments():
    for node in _tree().body:
        if isinstance(node, ast.Assign) and getattr(node.targets[0], 'id', '') == 'ARGUMENTS':
            return {name: default for name, default, _ in ast.literal_eval(node.value)}
    raise AssertionError('no ARGUMENTS table in the launch file')


def test_the_launch_file_starts_the_pipelines_nodes_with_the_pipelines_readiness_order():
    tree = _tree()
    imported = {(n.module, a.name) for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                for a in n.names}
    assert {('saw_ros.graph.pipeline', 'node_parameters'),
            ('saw_ros.graph.pipeline', 'READY_NODES'),
            ('launch.event_handlers', 'OnProcessExit'),
            ('saw_ros.interface.config', 'config_path')} <= imported
    text = LAUNCH.read_text(encoding='utf-8')
    # The recorder starts when the readiness probe exits; the run ends with the comparison.
    assert "'saw_ros.ros.ready'" in text and 'OnProcessExit(target_action=probe' in text
    assert "nodes['comparison']" in text and 'topics.recorded_topics()' in text
    # Issue 34's arguments: the camera (with vision and comparison), the controller, Foxglove.
    assert {'camera', 'controller', 'target_speed', 'foxglove'} <= set(_arguments())
    assert "executable='foxglove_bridge'" in text
    assert "config_path('fastdds.xml')" in text and 'FASTRTPS_DEFAULT_PROFILES_FILE' in text
    assert compile(text, str(LAUNCH), 'exec')


def test_its_defaults_are_the_demos():
    args = _arguments()
    defaults = inspect.signature(pipeline.node_parameters).parameters
    assert float(args['duration']) == defaults['duration'].default
    assert float(args['real_time_factor']) == defaults['real_time_factor'].default
    import argparse
    parser = argparse.ArgumentParser()
    demo.add_arguments(parser)
    cli = parser.parse_args([])
    demo_defaults = (cli.duration, cli.real_time_factor)
    assert demo_defaults == (float(args['duration']), float(args['real_time_factor']))
    assert float(args['slope']) == Scenario().conditions.slope


def _declared(name):
    """Parameter names a node declares, from its own tables."""
    import importlib
    module = importlib.import_module(f'saw_ros.ros.nodes.{name}')
    names = {entry[0] for entry in getattr(module, 'PARAMETERS', ())}
    names |= {entry[0] for entry in getattr(module, 'OWN_PARAMETERS', ())}
    if name in ('simulator', 'camera'):
        names |= set(Scenario().flat())
    return names


def test_every_parameter_given_is_declared_by_its_node_and_every_node_is_installed():
    setup = ast.parse((ROOT / 'setup.py').read_text(encoding='utf-8'))
    (nodes,) = [ast.literal_eval(n.value) for n in setup.body
                if isinstance(n, ast.Assign) and getattr(n.targets[0], 'id', '') == 'NODES']
    params = pipeline.node_parameters(scenario={'conditions.slope': 0.1}, camera={'fps': 30.0},
                                      report_path=Path('r.json'), reference_file=Path('f.csv'))
    assert list(params) == ['simulator', 'comparison', 'vision', 'camera']
    for name, values in params.items():
        assert name in nodes
        assert set(values) <= _declared(name), (name, set(values) - _declared(name))
    assert {'topics', 'output', 'label'} <= _declared('recorder')
    assert set(pipeline.READY_NODES) <= set(params)
    assert all(t in topics.BY_NAME for t in topics.recorded_topics())
