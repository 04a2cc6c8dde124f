"""
Issue 22 figures: the command input, the speed controller, the shaped drive.

- ``command_latency_steps`` (median) and ``command_latency_steps_max``: steps from a command's
  publication to the helix reacting, at real-time factor 1. The simulator runs as a subprocess;
  a probe in this process publishes a voltage step (alternately 6 and 10 V) right after the
  newest /clock it has received, which names the step k the command is published at, and finds
  in /saw/joint_states the first step whose motor torque (the helix's effort) jumps by the
  step's expected k dV / R: latency = that step - k. ``command_latency_samples`` commands.
- ``speed_hold_error_pct``: the speed controller on the camera's tracked speed holding 5 cm/s
  while the slope steps 0 -> 20 -> -20 degrees (analysis.speed_hold: rendered frames, the
  tracker, the PI of the node); mean absolute error of the turn-mean speed after 2 s at each
  slope. ``speed_hold_open_loop_error_pct``: the same steps at the fixed voltage that gives 5
  cm/s on the level.
- ``vibration_reduction_pct``: the committed profile of docs/shape_drive/result.json against
  the constant voltage that gives its speed, both measured now (analysis.shape_drive);
  ``vibration_motor_response_link_passing``: the motor's response at the link-passing
  harmonic (9 per turn), the reason the reduction stops where it does (docs/drive.md).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import random
import struct
from typing import Dict, List

import numpy as np

from saw_ros.analysis import shape_drive, speed_hold
from saw_ros.bench import log_dir
from saw_ros.core.params import Scenario
from saw_ros.graph.process import isolated_ros_env, ManagedProcess, node_command, wait_for

KEYS = ('command_latency_steps', 'command_latency_steps_max', 'command_latency_samples',
        'speed_hold_error_pct', 'speed_hold_open_loop_error_pct', 'vibration_reduction_pct',
        'vibration_motor_response_link_passing')
PROFILE = ('docs', 'shape_drive', 'result.json')
VOLTS = (6.0, 10.0)
NS = 1_000_000_000


def _stamp(raw: bytes) -> int:
    sec, nanosec = struct.unpack_from('<iI', raw, 4)
    return sec * NS + nanosec


def command_latency(samples: int) -> list:
    """Return the latency in steps of ``samples`` voltage steps (docstring of the module)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.serialization import deserialize_message

    from saw_ros.interface import topics
    from saw_ros.ros.runtime import make_executor
    from saw_ros.ros.qos import message_class, profile, with_depth

    env = isolated_ros_env()
    for key in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE',
                'FASTRTPS_DEFAULT_PROFILES_FILE', 'RMW_IMPLEMENTATION'):
        os.environ[key] = env[key]
    duration = 2.0 + 0.15 * samples
    sim = ManagedProcess('simulator', node_command('simulator', params={
        'motor.voltage': VOLTS[0], 'real_time_factor': 1.0, 'duration': duration,
        'command_timeout': 0.0, 'joint_states_rate': 1000.0}), env, log_dir('drive'))
    context = Context()
    rclpy.init(context=context)
    node = Node('latency_probe', context=context)
    # The C++ events executor, and only the two topics it needs: the probe's newest /clock must
    # be the simulator's newest step, not a queue behind it.
    executor = make_executor(context)
    executor.add_node(node)
    raw: Dict[str, List[bytes]] = {name: [] for name in (topics.CLOCK, topics.JOINT_STATES)}
    for name in raw:
        node.create_subscription(message_class(topics.topic(name).type), name, raw[name].append,
                                 with_depth(profile('stream'), 5000), raw=True)
    entry = topics.topic(topics.MOTOR_COMMANDS)
    command_type = message_class(entry.type)
    publisher = node.create_publisher(command_type, entry.name, profile(entry.qos))
    spin = lambda t: executor.spin_once(timeout_sec=t)  # noqa: E731
    sent = []
    try:
        if not wait_for(lambda: publisher.get_subscription_count() > 0
                        and bool(raw[topics.CLOCK]) and bool(raw[topics.JOINT_STATES]), 30,
                        spin=spin):
            raise RuntimeError(f'the simulator did not start: {sim.output()[-300:]}')
        wait_for(lambda: _stamp(raw[topics.CLOCK][-1]) > 1.0 * NS, 30, spin=spin)
        rng = random.Random(1)
        for i in range(samples):
            wait_for(lambda: False, rng.uniform(0.05, 0.12), spin=spin)
            step = _stamp(raw[topics.CLOCK][-1]) * 1000 // NS
            publisher.publish(command_type(data=[VOLTS[(i + 1) % 2]]))
            sent.append((step, VOLTS[(i + 1) % 2] - VOLTS[i % 2]))
        wait_for(lambda: sim.returncode is not None, duration + 30, spin=spin)
        wait_for(lambda: False, 0.5, spin=spin)
    finally:
        executor.shutdown(timeout_sec=1)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        if sim.returncode is None:
            sim.stop(timeout=5)
    joint_type = message_class(topics.topic(topics.JOINT_STATES).type)
    steps = np.array([_stamp(r) for r in raw[topics.JOINT_STATES]]) * 1000 // NS
    effort = np.array([deserialize_message(r, joint_type).effort[0]
                       for r in raw[topics.JOINT_STATES]])
    motor = Scenario().motor
    latencies = []
    for step, dv in sent:
        # The torque k i jumps by k dV / R at the step that takes the command (the helix speed
        # cannot move within a step); look for half of that between consecutive steps.
        jump = np.diff(effort) * np.sign(dv)
        after = np.flatnonzero((steps[1:] > step) & (np.diff(steps) == 1) &
                               (jump > 0.5 * motor.torque_constant * abs(dv) / motor.resistance))
        if len(after):
            latencies.append(int(steps[after[0] + 1] - step))
    return latencies


def run(quick: bool = False) -> dict:
    latencies = command_latency(8 if quick else 20)
    closed = speed_hold.hold('tracking')
    open_loop = speed_hold.hold('open_loop')
    # The committed profile of the checkout (saw-ros shape-drive --out docs/shape_drive).
    path = Path(__file__).resolve().parents[2].joinpath(*PROFILE)
    if not path.is_file():
        raise FileNotFoundError(f'{path}: no shaped profile to measure (a checkout has it; '
                                f'saw-ros shape-drive --out docs/shape_drive makes it)')
    saved = shape_drive.ShapeResult(**json.loads(path.read_text())['result'])
    base = Scenario().with_values({'motor.voltage': saved.base_voltage})
    shaped = shape_drive.evaluate(base, [saved.mean_voltage], [saved.coefficients],
                                  saved.harmonics)
    curve = shape_drive.ConstantCurve(base, saved.harmonics, points=5)
    _, matched = shape_drive.matched_constant(base, float(shaped.speed[0]), curve,
                                              saved.harmonics)
    response = shape_drive.motor_bandwidth(base, [9])[9]
    return {'command_latency_steps': float(np.median(latencies)) if latencies else None,
            'command_latency_steps_max': max(latencies) if latencies else None,
            'command_latency_samples': len(latencies),
            'speed_hold_error_pct': round(closed.error_pct, 3),
            'speed_hold_open_loop_error_pct': round(open_loop.error_pct, 3),
            'vibration_reduction_pct': round(
                100.0 * (1.0 - float(shaped.vibration[0]) / matched['vibration']), 2),
            'vibration_motor_response_link_passing': round(response, 4)}
