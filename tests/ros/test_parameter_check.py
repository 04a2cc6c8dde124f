"""
The one parameter check (issue 25) and the nodes' command line, without starting a node.

``core.params.check_value`` is the rule of every spec() entry, the Scenario's fields and the
nodes' own; ``ros.params.check_parameter`` adds the kind of a ROS value; ``runtime`` reads the
command line before rcl does. tests/ros/test_node_inputs.py runs the same through the nodes.
"""
import pytest

from saw_ros.core.params import check_value, ParameterError, Scenario, spec_meta

SLOPE = dict(next(m for n, _, m in Scenario().describe() if n == 'conditions.slope'))
RATE = spec_meta('Hz', 'rate of something', 0.0, 100.0, low_open=True)
COUNT = spec_meta('', 'how many', 1, None)


def refused(*args) -> str:
    with pytest.raises(ParameterError) as exc:
        check_value(*args)
    return str(exc.value)


def test_check_value_takes_values_in_range_and_integers_for_floats():
    assert check_value('rate', 100, RATE, 1.0) == 100.0
    assert isinstance(check_value('rate', 3, RATE, 1.0), float)
    assert check_value('n', 7, COUNT, 1) == 7 and isinstance(check_value('n', 7, COUNT, 1), int)
    assert check_value('anything', None, RATE, 1.0) is None


def test_check_value_states_the_range_with_its_unit():
    assert refused('conditions.slope', 2.0, SLOPE, 0.0).startswith(
        'conditions.slope = 2 is out of range: allowed [-1.5708, 1.5708] rad')
    assert 'rate = 0 is out of range: allowed (0, 100] Hz' in refused('rate', 0.0, RATE, 1.0)
    assert 'allowed (0, 100] Hz' in refused('rate', 100.5, RATE, 1.0)
    assert refused('rate', float('nan'), RATE, 1.0) == \
        'rate = nan is invalid: must be finite, in (0, 100] Hz'
    assert refused('n', 2.5, COUNT, 1) == 'n = 2.5 is invalid: must be an integer in [1, inf)'
    assert refused('rate', 'fast', RATE, 1.0) == \
        "rate = 'fast' is invalid: must be a number in (0, 100] Hz"


def test_check_value_choices():
    meta = spec_meta('', 'how', choices=('raw', 'compressed'))
    assert check_value('image_transport', 'raw', meta, 'raw') == 'raw'
    assert refused('image_transport', 'jpeg', meta, 'raw') == \
        "image_transport = 'jpeg' is invalid: must be one of raw, compressed"


def test_the_scenario_uses_the_same_check():
    with pytest.raises(ParameterError) as exc:
        Scenario().with_values({'conditions.slope': 2.0})
    assert str(exc.value) == refused('conditions.slope', 2.0, SLOPE, 0.0)


def test_check_parameter_kinds():
    from saw_ros.ros.params import check_parameter
    text = spec_meta('', 'a name')
    flag = spec_meta('', 'on or off')
    matrix = spec_meta('px', 'four numbers')
    assert check_parameter('camera_matrix', [1200, 1200, 640, 360], [0.0], matrix) == \
        [1200.0, 1200.0, 640.0, 360.0]
    assert check_parameter('topics', ['/a'], [''], text) == ['/a']
    for name, value, default, meta, kind in (
            ('loop', 'maybe', False, flag, 'true or false'),
            ('loop', 1, False, flag, 'true or false'),
            ('frame_id', 3, 'x', text, 'a string'),
            ('topics', '/a', [''], text, 'a list of strings'),
            ('camera_matrix', ['a'], [0.0], matrix, 'a list of numbers'),
            ('rate', True, 1.0, RATE, 'a number in (0, 100] Hz')):
        with pytest.raises(ParameterError) as exc:
            check_parameter(name, value, default, meta)
        assert str(exc.value) == f'{name} = {value!r} is invalid: must be {kind}'


def test_descriptors_carry_the_range_as_text_not_as_a_ros_range():
    from saw_ros.ros.params import descriptor
    d = descriptor('conditions.slope', 0.0, SLOPE)
    assert not d.floating_point_range and not d.integer_range
    assert d.additional_constraints == 'allowed [-1.5708, 1.5708] rad'
    assert '[rad]' in d.description


def test_command_line_help_and_unknown_arguments():
    from saw_ros.ros.runtime import check_command_line
    assert check_command_line(['simulator', '--help'])
    assert check_command_line(['simulator', '-h', '--ros-args', '-p', 'duration:=1.0'])
    assert check_command_line(['simulator', '--ros-args', '-p', 'duration:=1.0', '--help'])
    assert not check_command_line(['simulator', '--ros-args', '-p', 'duration:=1.0'])
    for argv, text in (
            (['simulator', 'fast'], 'unknown argument fast: parameters go after --ros-args'),
            (['simulator', '--ros-args', '--fast'], 'unknown ROS argument --fast'),
            (['simulator', '--ros-args', '-p', 'duration'],
             "invalid ROS arguments: Couldn't parse parameter override rule: '-p duration'")):
        with pytest.raises(ParameterError) as exc:
            check_command_line(argv)
        assert str(exc.value).startswith(text), str(exc.value)
        assert '.c:' not in str(exc.value) and '\n' not in str(exc.value), str(exc.value)


@pytest.mark.parametrize('content, text', [
    (None, 'does not exist'),
    ('simulator:\n  ros__parameters: {a: [1\n', 'is not YAML: '),
    (b'\xff\xfe', 'is not YAML: not UTF-8 text'),
    ('- 1\n- 2\n', 'is not a ROS parameters file: expected "<node name>: ros__parameters: ..." '
                   'at its top, found list'),
    ('', 'is not a ROS parameters file'),
])
def test_params_files_that_rcl_would_refuse(tmp_path, content, text):
    from saw_ros.ros.runtime import check_command_line
    path = tmp_path / 'params.yaml'
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        path.write_text(content)
    with pytest.raises(ParameterError) as exc:
        check_command_line(['camera', '--ros-args', '--params-file', str(path)])
    assert str(exc.value).startswith(f'params file {path} {text}'), str(exc.value)


def test_a_params_file_of_ros2_launch_with_a_list_parameter_is_taken(tmp_path):
    """launch_ros writes a list as !!python/tuple; rcl takes it, so must our check (issue 34)."""
    import yaml
    from saw_ros.ros.runtime import check_command_line
    path = tmp_path / 'launch_params.yaml'
    with open(path, 'w', encoding='utf-8') as f:
        yaml.dump({'/**': {'ros__parameters': {'topics': ('/saw/pose', '/tf')}}}, f)
    assert '!!python/tuple' in path.read_text()
    check_command_line(['recorder', '--ros-args', '--params-file', str(path)])


def test_help_text_lists_every_entry_with_type_unit_range_default():
    from saw_ros.ros.runtime import help_text
    entries = [('rate', 1.0, RATE), ('count', 3, COUNT), ('topics', [''], spec_meta('', 'what')),
               ('mode', 'raw', spec_meta('', 'how', choices=('raw', 'compressed'))),
               ('loop', False, spec_meta('', 'again'))]
    text = help_text('node', lambda: entries, 'The node: what it does.\n\nMore.')
    lines = text.splitlines()
    assert lines[0].startswith('usage: node [-h] [--ros-args') and lines[2] == \
        'The node: what it does.'
    for line in ('  rate: double [Hz] in (0, 100], default 1.0', '      rate of something',
                 '  count: integer in [1, inf), default 3', "  topics: string[], default ['']",
                 "  mode: string, one of raw, compressed, default 'raw'",
                 '  loop: bool, default false'):
        assert line in lines, text
