"""
The model's parameters (``core.params.Scenario``) as ROS 2 parameters, for any saw_ros node.

Every ``Scenario.describe()`` entry becomes a parameter with the same dotted name
(``surface.normal_stiffness``), its unit and description in the ParameterDescriptor and a
FloatingPointRange / IntegerRange where both bounds exist (ROS ranges are closed; open bounds,
one-sided bounds and checks between several fields are enforced by the Scenario itself).

A set-parameters request is validated by building ``scenario.with_values(...)``: an invalid value
is refused with the ParameterError text, and the node keeps its previous Scenario. Names listed in
``frozen`` are refused at run time with the given reason (the simulator freezes the robot
geometry and the time step). Accepted changes reach the node through ``on_change(scenario)``,
after rclpy has stored them (post-set callback), so that a request refused by another callback
never half-applies.
"""
from __future__ import annotations

from typing import Callable, Dict, Iterable, Optional, Tuple

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.parameter import Parameter

from saw_ros.core.params import ParameterError, range_text, Scenario


_TYPES = ((bool, ParameterType.PARAMETER_BOOL), (int, ParameterType.PARAMETER_INTEGER),
          (float, ParameterType.PARAMETER_DOUBLE), (str, ParameterType.PARAMETER_STRING),
          (list, ParameterType.PARAMETER_STRING_ARRAY))


def descriptor(name: str, value, meta: Dict, read_only: bool = False) -> ParameterDescriptor:
    """
    Return the ParameterDescriptor for one spec() entry.

    The entry is a Scenario's, a vision dataclass's or a node's own; the descriptor has its
    description [unit], range, constraints.
    ``ros_range=False`` in the metadata: no ROS range, the node checks the bounds itself (with its
    own message).
    """
    unit = meta.get('unit') or ''
    kind = next(t for cls, t in _TYPES if isinstance(value, cls))
    is_int = kind == ParameterType.PARAMETER_INTEGER
    numeric = kind in (ParameterType.PARAMETER_INTEGER, ParameterType.PARAMETER_DOUBLE)
    desc = ParameterDescriptor(
        name=name, type=kind, read_only=read_only,
        description=meta.get('description', '') + (f' [{unit}]' if unit else '')
        + (' (start-up only)' if read_only else ''),
        additional_constraints=f'allowed {range_text(meta)}' if numeric and 'low' in meta
        else '')
    low, high = meta.get('low'), meta.get('high')
    if numeric and low is not None and high is not None and meta.get('ros_range', True):
        if is_int:
            desc.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
        else:
            desc.floating_point_range = [FloatingPointRange(from_value=float(low),
                                                            to_value=float(high), step=0.0)]
    return desc


def accept_integers_for_doubles(node, names: Iterable[str], defaults: Dict) -> None:
    """
    ``-p conditions.slope:=0`` or ``slope: 0`` in YAML arrive as INTEGER overrides.

    Which rclpy refuses for a DOUBLE parameter: turn them into doubles before declaring.
    """
    overrides = getattr(node, '_parameter_overrides', None)
    if not isinstance(overrides, dict):
        return
    for name in names:
        p = overrides.get(name)
        if (p is not None and p.type_ == Parameter.Type.INTEGER
                and isinstance(defaults[name], float)):
            overrides[name] = Parameter(name, Parameter.Type.DOUBLE, float(p.value))


def declare_spec(node, entries: Iterable[Tuple[str, object, Dict]], read_only: bool = True
                 ) -> Dict[str, object]:
    """
    Declare spec() entries (name, default, metadata) on ``node`` with their descriptors.

    (read-only by default: read at start-up only; an entry's ``read_only`` metadata decides for it)
    and returns {name: value}. An integer given for a double (``-p fps:=30``) is taken as a double.
    Raises rclpy's ParameterException (an out-of-range value: InvalidParameterValueException) for
    an invalid start-up value.
    """
    entries = list(entries)
    defaults = {n: v for n, v, _ in entries}
    accept_integers_for_doubles(node, defaults, defaults)
    declared = node.declare_parameters('', [(n, v, descriptor(n, v, m,
                                                              m.get('read_only', read_only)))
                                            for n, v, m in entries])
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
        accept_integers_for_doubles(node, self.names, {n: v for n, v, _ in entries})
        declared = node.declare_parameters('', [(n, v, descriptor(n, v, m))
                                                for n, v, m in entries])
        # Validate the start-up values (YAML, -p) as a whole: the Scenario checks every range and
        # the relations between fields.
        self.scenario = base.with_values({p.name: p.value for p in declared})
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
        lines += textwrap.wrap(comment, 95, initial_indent='    # ', subsequent_indent='    # ')
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
