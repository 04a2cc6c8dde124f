"""
The simulator's parameters, for every node that needs them (comparison, camera): one way.

No node repeats the simulator's robot or conditions by hand. ``SimulatorParameters`` asks the
simulator node for the names it is given (its get_parameters service, once that answers: call
``request`` from a timer until ``known``) and follows their changes on /parameter_events.
``on_values`` gets the names with the values the simulator runs, at the answer and at every
change; it returns False to refuse a set, and the last accepted one stays.
"""
from __future__ import annotations

import time
from typing import Any, Callable, Dict, Optional, Sequence

from rcl_interfaces.msg import ParameterEvent, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters
from rclpy.node import Node
from rclpy.qos import QoSProfile
from saw_ros.core.params import Scenario
from saw_ros.interface.message_checks import Refused
from saw_ros.ros.guard import InputGuard
from saw_ros.ros.params import SIMULATOR_EXCLUDED

# Every Scenario name the simulator declares (it replaces integration.duration by its own
# `duration`): rclpy answers nothing at all if one name asked for is not declared.
# s a request for the simulator's values may go unanswered before it is asked again: a request
# sent before the service's side of the match was complete is lost, and its future never done
# (the comparison never learned the values and ignored /parameter_events for the whole run).
REQUEST_RETRY_S = 2.0
SCENARIO_NAMES = tuple(n for n in Scenario().flat() if n not in SIMULATOR_EXCLUDED)


def value_of(p: ParameterValue) -> Any:
    """Return a rcl_interfaces/ParameterValue as Python (only the types we declare; else None)."""
    return {ParameterType.PARAMETER_DOUBLE: p.double_value,
            ParameterType.PARAMETER_INTEGER: p.integer_value,
            ParameterType.PARAMETER_BOOL: p.bool_value,
            ParameterType.PARAMETER_STRING: p.string_value}.get(p.type)


class SimulatorParameters:
    """The values of ``names`` as the simulator node ``simulator`` runs them (module docstring)."""

    def __init__(self, node: Node, simulator: str, names: Sequence[str],
                 on_values: Callable[[Dict[str, Any]], bool], guard: InputGuard):
        self.simulator = simulator.strip('/')
        self.names = list(names)
        self.values: Dict[str, Any] = {}        # the last set on_values accepted
        self._on_values = on_values
        self._client = node.create_client(GetParameters, f'/{self.simulator}/get_parameters')
        self._pending: Optional[Any] = None
        self._asked_at = 0.0
        # Any participant can publish a ParameterEvent naming the simulator: on_values checks the
        # values (a Scenario refuses what the simulator would), the guard what cannot be read.
        guard.subscribe(ParameterEvent, '/parameter_events', self._on_event,
                        QoSProfile(depth=100))

    @property
    def known(self) -> bool:
        """Return whether the simulator's values have been received (and accepted)."""
        return bool(self.values)

    def available(self) -> bool:
        """Return whether the simulator's parameter service answers."""
        return bool(self._client.service_is_ready())

    def request(self) -> None:
        """Ask the simulator, unless its values are known, asked for lately or it is not there."""
        if self.values or not self._client.service_is_ready():
            return
        if self._pending is not None:
            if time.monotonic() - self._asked_at < REQUEST_RETRY_S:
                return
            self._client.remove_pending_request(self._pending)
        self._asked_at = time.monotonic()
        self._pending = self._client.call_async(GetParameters.Request(names=self.names))
        self._pending.add_done_callback(self._on_answer)

    def _on_answer(self, future: Any) -> None:
        self._pending = None
        result = future.result()
        if result is None:
            return
        values = {n: value_of(v) for n, v in zip(self.names, result.values)}
        self._update({k: v for k, v in values.items() if v is not None})

    def _on_event(self, event: ParameterEvent) -> None:
        if event.node.strip('/') != self.simulator or not self.values:
            return
        changed = {p.name: value_of(p.value) for p in list(event.changed_parameters)
                   + list(event.new_parameters)}
        if not self._update({k: v for k, v in changed.items() if k in self.values}):
            raise Refused('parameters refused', f'{self.simulator} values '
                          f'{", ".join(sorted(changed))} not taken')

    def _update(self, values: Dict[str, Any]) -> bool:
        merged = dict(self.values, **values)
        if not self._on_values(merged):
            return False
        self.values = merged
        return True
