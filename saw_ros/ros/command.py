"""
The simulator's command input (issue 22): drive the helix from your own node.

Convention: ros2_control's forward command controllers. A controller named ``motor_controller``
takes ``std_msgs/Float64MultiArray`` on ``<controller>/commands``, one value per joint it
drives; ours drives one joint (the helix), so a command is one value:

- the motor voltage, V, where the motor is modelled (motor.voltage > 0 in the parameters);
- the helix frequency, Hz, where it is not (the paper's constant-speed helix).

A command takes effect at the next step and stays until the next command. The simulator steps in
bursts (a few milliseconds of steps per wake-up); ``poll`` takes what arrived before each step,
so a command that arrives during a burst is not held until the burst ends. When commands stop
for ``command_timeout`` seconds of simulated time, the drive returns to its parameter
(motor.voltage / conditions.frequency), as cmd_vel consumers stop a robot whose commands stopped;
0 keeps the last command for ever. A command that is not one finite value inside the parameter's
range (wrong length, NaN, out of range) is refused through the node's ``InputGuard``
(saw_ros.ros.guard: counted on /diagnostics, said in a warning at most once per WARN_EVERY
seconds of wall time); it is never applied. ``refused`` and ``applied`` count them.
"""
from __future__ import annotations

from typing import Optional

from saw_ros.core.dynamics import Simulator
from saw_ros.core.params import ParameterError
from saw_ros.interface import topics
from saw_ros.interface.message_checks import Refused
from saw_ros.ros.guard import InputGuard
from saw_ros.ros.qos import message_class, profile


class CommandInput:
    """Subscribes to the command topic of ``node`` and drives ``sim`` with what arrives."""

    def __init__(self, node, sim: Simulator, timeout: float):
        self.node, self.sim, self.timeout = node, sim, timeout
        self.applied = 0
        self.active = False
        self.last_step: Optional[int] = None     # the sim's step count at the last command
        self.last_value: Optional[float] = None
        self.guard = InputGuard(node)
        entry = topics.topic(topics.MOTOR_COMMANDS)
        self._type = message_class(entry.type)
        self._guarded = self.guard.guarded(entry.name, self._on_command)
        self.subscription = node.create_subscription(
            self._type, entry.name, self._guarded, profile(entry.qos))
        self._take = self.subscription.handle.take_message
        node.get_logger().info(
            f'commands on {entry.name}: ' + ('[motor voltage, V]' if sim.motor_on else
                                             '[helix frequency, Hz] (no motor modelled: '
                                             'motor.voltage = 0)'))

    @property
    def refused(self) -> int:
        return self.guard.refused

    @property
    def unit(self) -> str:
        return 'V' if self.sim.motor_on else 'Hz'

    def poll(self) -> None:
        """Take and apply the commands that arrived since the last step (before stepping)."""
        # rclpy's own wait_for_message takes from a subscription's handle the same way; the
        # executor's later attempt then finds the queue empty.
        taken = self._take(self._type, False)
        while taken is not None:
            self._guarded(taken[0])
            taken = self._take(self._type, False)

    def _on_command(self, msg) -> None:
        values = list(msg.data)
        if len(values) != 1:
            raise Refused('mis-sized arrays', f"expected one value (the helix's {self.unit}), "
                                              f'got {len(values)}')
        value = float(values[0])
        try:
            if self.sim.motor_on:
                self.sim.command_voltage(value)
            else:
                self.sim.command_frequency(value)
        except ParameterError as exc:
            raise Refused('out of range', str(exc)) from None
        self.applied += 1
        self.active = True
        self.last_step = self.sim.steps
        self.last_value = value

    def check_timeout(self) -> None:
        """Return the drive to its parameter once commands stopped for ``timeout`` (sim time)."""
        if not self.active or self.last_step is None or self.timeout <= 0.0:
            return
        if (self.sim.steps - self.last_step) * self.sim.dt < self.timeout:
            return
        self.release(f'no command for {self.timeout:g} s')

    def release(self, why: str) -> None:
        """Hand the drive back to the parameters."""
        if self.sim.motor_on:
            self.sim.command_voltage(None)
        self.sim.command_frequency(None)
        self.active = False
        self.node.get_logger().info(f'{why}: the helix is driven by its parameter again')
