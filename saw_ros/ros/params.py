"""
ROS parameters from spec() tables: the model's (``core.params.Scenario``), each node's own.

Every ``Scenario.describe()`` entry becomes a parameter with the same dotted name
(``surface.normal_stiffness``), a node's own ``spec_meta`` entries likewise; the
ParameterDescriptor carries the description, unit and allowed range. One check for all of them:
``check_parameter`` (the kind, then ``core.params.check_value``, the rule the Scenario's own
fields follow), before a start-up value (YAML, ``-p``) is declared and on every run-time change,
so that a refusal always names the parameter, the value and the range with its unit.

A set-parameters request for the Scenario is validated by building ``scenario.with_values(...)``
(ranges and the relations between fields): an invalid value is refused with the ParameterError
text, and the node keeps its previous Scenario. Names listed in ``frozen`` are refused at run
time with the given reason (the simulator freezes the robot geometry and the time step).
Accepted changes reach the node through ``on_change(scenario)``, after rclpy has stored them
(post-set callback), so that a request refused by another callback never half-applies.
"""
from __future__ import annotations

from typing import Callable, Dict, Iterable, List, Optional, Tuple

from rcl_interfaces.msg import ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.parameter import Parameter

from saw_ros.core.params import check_value, ParameterError, range_text, Scenario


_TYPES = ((bool, ParameterType.PARAMETER_BOOL), (int, ParameterType.PARAMETER_INTEGER),
          (float, ParameterType.PARAMETER_DOUBLE), (str, ParameterType.PARAMETER_STRING),
          (list, ParameterType.PARAMETER_STRING_ARRAY))
_ARRAY_TYPES = ((bool, ParameterType.PARAMETER_BOOL_ARRAY),
                (int, ParameterType.PARAMETER_INTEGER_ARRAY),
                (float, ParameterType.PARAMETER_DOUBLE_ARRAY),
                (str, ParameterType.PARAMETER_STRING_ARRAY))


def descriptor(name: str, value, meta: Dict, read_only: bool = False) -> ParameterDescriptor:
    """
    Return the ParameterDescriptor for one spec() entry.

    The entry is a Scenario's, a vision dataclass's or a node's own; the descriptor has its
    description [unit] and, as text, its allowed range with the unit. No ROS range
    (FloatingPointRange, IntegerRange): rclpy would check it before our check and refuse with a
    message of its own, without the unit; ROS ranges are closed, where ours can be open.
    """
    unit = meta.get('unit') or ''
    kind = next(t for cls, t in _TYPES if isinstance(value, cls))
    if kind == ParameterType.PARAMETER_STRING_ARRAY and value:
        kind = next(t for cls, t in _ARRAY_TYPES if isinstance(value[0], cls))
    numeric = kind in (ParameterType.PARAMETER_INTEGER, ParameterType.PARAMETER_DOUBLE)
    return ParameterDescriptor(
        name=name, type=kind, read_only=read_only,
        description=meta.get('description', '') + (f' [{unit}]' if unit else '')
        + (' (start-up only)' if read_only else ''),
        additional_constraints=f'allowed {range_text(meta)}' if numeric and 'low' in meta
        else f'one of {", ".join(meta["choices"])}' if meta.get('choices') else '')


_KINDS = ((bool, 'true or false', 'booleans'), (int, 'an integer', 'integers'),
          (float, 'a number', 'numbers'), (str, 'a string', 'strings'))


def _kind_name(default) -> str:
    """Return what a value of the kind of ``default`` is called in a refusal."""
    if isinstance(default, (list, tuple)):
        sample = default[0] if default else ''
        return 'a list of ' + next(many for cls, _, many in _KINDS if isinstance(sample, cls))
    return next(one for cls, one, _ in _KINDS if isinstance(default, cls))


def _same_kind(value, default) -> bool:
    """``value`` may stand for ``default``: same type, or an integer for a float (not a bool)."""
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(value, bool) and isinstance(default, bool)
    if isinstance(default, float):
        return isinstance(value, (int, float))
    return isinstance(value, type(default))


def check_parameter(name: str, value, default, meta: Dict):
    """
    Return ``value`` for the spec() entry (``name``, ``default``, ``meta``), or ParameterError.

    Its kind must be the default's (an integer is taken for a floating-point number, alone or in
    a list), then ``core.params.check_value``: finite, in range, among the choices. The same
    check at start (YAML, ``-p``) and for a run-time change, with one kind of message.
    """
    if value is None:
        return value
    if isinstance(default, (list, tuple)):
        if not isinstance(value, (list, tuple)) or (default and not all(
                _same_kind(v, default[0]) for v in value)):
            raise ParameterError(f'{name} = {value!r} is invalid: must be {_kind_name(default)}')
        return [float(v) for v in value] if default and isinstance(default[0], float) \
            else list(value)
    if not _same_kind(value, default):
        numeric = isinstance(default, (int, float)) and not isinstance(default, bool)
        raise ParameterError(f'{name} = {value!r} is invalid: must be {_kind_name(default)}'
                             + (f' in {range_text(meta)}' if numeric else ''))
    return check_value(name, value, meta, default)


def _overrides(node) -> Dict[str, Parameter]:
    """Return the node's start-up values (YAML, ``-p``) by name, kept by rclpy until declared."""
    overrides = getattr(node, '_parameter_overrides', None)
    return overrides if isinstance(overrides, dict) else {}


def check_start_values(node, entries: Iterable[Tuple[str, object, Dict]]) -> Dict[str, object]:
    """
    Check the start-up values of ``entries`` (``check_parameter``) before they are declared.

    Returns {name: value} of those given. An integer given for a floating-point parameter
    (``-p fps:=30``, ``slope: 0`` in YAML) is turned into one, which rclpy would refuse.
    Raises ParameterError (the first value refused), so that the node's one line is ours, with
    the range and its unit, instead of rclpy's.
    """
    overrides = _overrides(node)
    given = {}
    for name, default, meta in entries:
        p = overrides.get(name)
        if p is None or p.type_ == Parameter.Type.NOT_SET:
            continue
        value = check_parameter(name, p.value, default, meta)
        if isinstance(default, float) and p.type_ == Parameter.Type.INTEGER:
            overrides[name] = Parameter(name, Parameter.Type.DOUBLE, value)
        elif (isinstance(default, (list, tuple)) and default and isinstance(default[0], float)
              and p.type_ == Parameter.Type.INTEGER_ARRAY):
            overrides[name] = Parameter(name, Parameter.Type.DOUBLE_ARRAY, value)
        given[name] = value
    return given


def unknown_start_values(node) -> List[str]:
    """Return the names given at start (YAML, ``-p``) that ``node`` did not declare."""
    return sorted(n for n in _overrides(node) if not node.has_parameter(n))


def declare_spec(node, entries: Iterable[Tuple[str, object, Dict]], read_only: bool = True
                 ) -> Dict[str, object]:
    """
    Declare spec() entries (name, default, metadata) on ``node`` with their descriptors.

    Read-only by default (read at start-up only); an entry's ``read_only`` metadata decides for
    it. Returns {name: value}. Start-up values are checked first (``check_start_values``: raises
    ParameterError); run-time changes of the others are checked the same way, refused with the
    reason.
    """
    entries = list(entries)
    check_start_values(node, entries)
    declared = node.declare_parameters('', [(n, v, descriptor(n, v, m,
                                                              m.get('read_only', read_only)))
                                            for n, v, m in entries])
    live = {n: (v, m) for n, v, m in entries if not m.get('read_only', read_only)}
    if live:
        def validate(parameters) -> SetParametersResult:
            for p in parameters:
                if p.name in live:
                    try:
                        check_parameter(p.name, p.value, *live[p.name])
                    except ParameterError as exc:
                        node.get_logger().warning(f'parameter change refused: {exc}')
                        return SetParametersResult(successful=False, reason=str(exc))
            return SetParametersResult(successful=True)
        node.add_on_set_parameters_callback(validate)
    return {p.name: p.value for p in declared}


# Scenario names the simulator node does not declare, taking them from its own parameters
# instead (the comparison asks the simulator for every other Scenario name).
SIMULATOR_EXCLUDED = ('integration.duration',)        # replaced by `duration` (0 = until stopped)


class ScenarioParameters:
    """
    Declares a Scenario's parameters on ``node`` and keeps ``self.scenario`` in step with them.

    ``exclude``: Scenario names not declared (their default/base value is kept).
    ``frozen``: {name prefix: reason} refused at run time (after the declaration).
    ``on_change(new_scenario)``: called after an accepted change.
    Raises ParameterError if the overrides (YAML, ``-p``) at start-up give an invalid Scenario.
    """

    def __init__(self, node, base: Optional[Scenario] = None, exclude: Iterable[str] = (),
                 frozen: Optional[Dict[str, str]] = None,
                 on_change: Optional[Callable[[Scenario], None]] = None):
        self.node = node
        self.on_change = on_change
        self.frozen = dict(frozen or {})
        base = base if base is not None else Scenario()
        exclude = set(exclude)
        entries = [(n, v, m) for n, v, m in base.describe() if n not in exclude]
        self.names: Tuple[str, ...] = tuple(n for n, _, _ in entries)
        # The start-up values (YAML, -p) are checked one by one, then as a whole before they
        # are declared: the Scenario checks every range and the relations between fields.
        self.scenario = base.with_values(check_start_values(node, entries))
        node.declare_parameters('', [(n, v, descriptor(n, v, m)) for n, v, m in entries])
        node.add_on_set_parameters_callback(self._validate)
        node.add_post_set_parameters_callback(self._apply)

    def owns(self, name: str) -> bool:
        return name in self.names

    def frozen_reason(self, name: str) -> Optional[str]:
        for prefix, reason in self.frozen.items():
            if name == prefix or name.startswith(prefix.rstrip('.') + '.'):
                return reason
        return None

    def check(self, parameters) -> Tuple[Optional[Scenario], str]:
        """Return (new Scenario, '') if the parameters are acceptable, else (None, reason)."""
        values = {}
        for p in parameters:
            if not self.owns(p.name):
                continue
            reason = self.frozen_reason(p.name)
            if reason is not None and p.value != self.scenario.flat()[p.name]:
                return None, f'{p.name} cannot change while the node runs: {reason}'
            values[p.name] = p.value
        if not values:
            return self.scenario, ''
        try:
            return self.scenario.with_values(values), ''
        except ParameterError as exc:
            return None, str(exc)

    def _validate(self, parameters) -> SetParametersResult:
        scenario, reason = self.check(parameters)
        if scenario is None:
            self.node.get_logger().warning(f'parameter change refused: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _apply(self, parameters) -> None:
        values = {p.name: p.value for p in parameters if self.owns(p.name)}
        if not values:
            return
        self.scenario = self.scenario.with_values(values)
        if self.on_change is not None:
            self.on_change(self.scenario)


def spec_comment(value, meta: Dict) -> str:
    """
    Return the YAML comment of a spec() entry.

    Range and unit of a number, then its description.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)) or 'low' not in meta:
        unit = meta.get('unit') or ''
        return meta['description'] + (f' [{unit}]' if unit else '')
    return f'{range_text(meta)}: {meta["description"]}'


def _yaml_value(value) -> str:
    return ('true' if value else 'false') if isinstance(value, bool) else repr(value)


def yaml_text(node_name: str, header: str, own: Iterable[Tuple[str, object, object]] = (),
              scenario: Optional[Scenario] = None, exclude: Iterable[str] = (),
              with_scenario: bool = True) -> str:
    """
    Return a parameters file for ``--ros-args --params-file``.

    ``own`` (name, value, comment or spec() metadata) entries first, then (``with_scenario``) every
    Scenario parameter, nested by section, each with its unit, range and description in a comment.
    One generator for every msg_config/<node>.yaml: regenerate them with it (each node's
    ``--write-yaml``) when a dataclass gains fields.
    """
    import textwrap
    scenario = scenario if scenario is not None else Scenario()
    exclude = set(exclude)
    lines = [f'# {line}' if line else '#' for line in header.splitlines()]
    lines += [f'{node_name}:', '  ros__parameters:']
    for name, value, comment in own:
        if isinstance(comment, dict):
            comment = spec_comment(value, comment)
        lines += textwrap.wrap(str(comment), 95, initial_indent='    # ',
                               subsequent_indent='    # ')
        lines.append(f'    {name}: {_yaml_value(value)}')
    section = None
    for name, value, meta in (scenario.describe() if with_scenario else ()):
        if name in exclude:
            continue
        sec, key = name.split('.', 1)
        if sec != section:
            lines.append(f'    {sec}:')
            section = sec
        comment = spec_comment(value, meta)
        lines += textwrap.wrap(comment, 93, initial_indent='      # ',
                               subsequent_indent='      #   ')
        lines.append(f'      {key}: {value!r}')
    return '\n'.join(lines) + '\n'
