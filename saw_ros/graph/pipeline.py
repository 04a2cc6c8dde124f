"""
The whole ROS graph as separate processes: simulator, camera, vision, comparison, recorder.

Used by the main job (``saw-ros demo``), the full-graph integration test and the pipeline
benchmark. No rclpy import here: each node is its own process (``saw_ros.graph.process``), in a
private DDS domain; the simulator starts stepping only once every one of its topics has a
subscriber (the recorder subscribes to all of them), so nothing is missed at the start. The run
ends when the simulator reaches its duration and the comparison node has published its final
summary.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import json
from pathlib import Path
import time
from typing import Any, Dict, List, Optional

from saw_ros.graph.process import isolated_ros_env, ManagedProcess, node_command
from saw_ros.interface import topics


MATCH_TIMEOUT = 20.0     # s; then the run goes on anyway (and the bench reports what was lost)
# The speed controller in the graph (docs/drive.md): the motor's voltage until its first command,
# and how long the simulator waits for commands before handing the helix back to motor.voltage.
CONTROLLER_START_VOLTAGE = 6.0
CONTROLLER_TIMEOUT = 2.0
# Nodes whose readiness (saw_ros.ros.ready, on /saw/ready) the recorder waits for.
READY_NODES = ('camera', 'comparison', 'vision')


class PipelineError(RuntimeError):
    """A node of the graph failed (the message names it and quotes its log)."""


@dataclass
class PipelineRun:
    out_dir: Path
    bag_dir: Optional[Path]
    comparison: Dict[str, object]
    exit_codes: Dict[str, int]
    wall_s: float
    logs: Dict[str, Path] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return all(code == 0 for code in self.exit_codes.values())


def _tail(path: Path, lines: int = 15) -> str:
    try:
        return '\n'.join(path.read_text(errors='replace').splitlines()[-lines:])
    except OSError:
        return ''


# What the graph's recorder records by default: every topic but the raw camera frames (the
# compressed ones are recorded; why: docs/measurements.md). ``record_topics=ALL_TOPICS`` keeps
# them too.
RECORDED_TOPICS = topics.recorded_topics()
ALL_TOPICS = [t.name for t in topics.TOPICS]


def node_parameters(duration: float = 10.0, real_time_factor: float = 0.5,
                    scenario: Optional[Dict[str, Any]] = None, record: bool = True,
                    camera: Optional[Dict[str, object]] = None,
                    report_path: Optional[Path] = None,
                    reference_file: Optional[Path] = None,
                    controller: Optional[Dict[str, object]] = None,
                    foxglove: Optional[Dict[str, object]] = None
                    ) -> Dict[str, Dict[str, object]]:
    """
    Return the main job's nodes in start order, each with its ROS parameters.

    Simulator, comparison, vision and camera start together; the recorder (not listed: its
    ``output`` and ``topics`` are the caller's) starts once READY_NODES said ready. One table for
    ``run_pipeline`` and launch/saw.launch.py.

    ``controller``: also the speed controller, with these parameters (its ``target_speed``...),
    closing the loop through the camera (docs/drive.md): the simulator then models the motor
    (at CONTROLLER_START_VOLTAGE until the first command, unless the scenario sets
    motor.voltage) and hands the helix back to it only after CONTROLLER_TIMEOUT without
    commands, which covers the tracker's first frames.

    ``foxglove``: also the Foxglove bridge (saw_ros.ros.nodes.foxglove_bridge), with these
    parameters (``port``...); it subscribes to a topic only while a client watches it, and with
    a recorder only once the simulator runs (``hold_until_clock``): a client subscribed through
    it would otherwise give the simulator the subscribers it waits for before the recorder
    matched (the bench's recorder lost the first 2.4 s).
    """
    scenario = dict(scenario or {})
    if controller is not None:
        if float(scenario.get('motor.voltage', 0.0)) <= 0.0:
            scenario['motor.voltage'] = CONTROLLER_START_VOLTAGE
        scenario['command_timeout'] = CONTROLLER_TIMEOUT
    # The level camera sees the surfaces at the run's slope; the tracker must know it too.
    slope = float(scenario.get('conditions.slope', 0.0))
    return {
        # Every topic needs a subscriber before the first step: the recorder's, or with no
        # recorder the camera's and comparison's (then only /saw/pose and /saw/joint_states).
        'simulator': dict(duration=float(duration), real_time_factor=float(real_time_factor),
                          wait_for_subscribers=1 if record else 0, **scenario),
        # An empty value ('-p reference_file:=') is a parse error for rcl: leave it out.
        'comparison': dict(exit_when_done=True, idle_timeout=2.0,
                           **({'report_path': str(report_path)} if report_path else {}),
                           **({'reference_file': str(reference_file)} if reference_file
                              else {})),
        # The tracker reads the JPEG stream the recorder keeps: the camera then publishes no raw
        # frames at all (12 ms each; decoding costs the tracker less, and JPEG quality 90 tracks
        # within the raw tolerances: tests/ros/test_vision_nodes.py).
        # Neither runs on use_sim_time: their outputs carry the frames' stamps anyway, and a
        # use_sim_time node takes every /clock tick in Python (1000 callbacks a second each).
        'vision': {'slope': slope, 'image_transport': 'compressed'},
        'camera': dict(slope=slope, **dict(camera or {})),
        **({'speed_controller': dict(controller)} if controller is not None else {}),
        **({'foxglove_bridge': dict(hold_until_clock=bool(record), **foxglove)}
           if foxglove is not None else {}),
    }


def run_pipeline(out_dir: Path, duration: float = 10.0, real_time_factor: float = 1.0,
                 scenario: Optional[Dict[str, object]] = None, record: bool = True,
                 bag_dir: Optional[Path] = None, camera: Optional[Dict[str, object]] = None,
                 reference_file: Optional[Path] = None, timeout: Optional[float] = None,
                 progress=None, record_topics: Optional[List[str]] = None,
                 env: Optional[Dict[str, str]] = None,
                 hosts: Optional[Dict[str, List[str]]] = None,
                 controller: Optional[Dict[str, object]] = None,
                 foxglove: Optional[Dict[str, object]] = None) -> PipelineRun:
    """
    Run the graph once; always stops every process it started (also on Ctrl-C).

    ``record_topics``: what the recorder records (default ``RECORDED_TOPICS``). ``env``: the
    processes' environment (default ``isolated_ros_env()``: this host only); ``hosts``: per
    node name (and 'ready', the readiness probe) a command prefix that runs it elsewhere, such
    as another network namespace (tests/graph/test_two_hosts.py).
    """
    out_dir = Path(out_dir)
    logs = out_dir / 'logs'
    out_dir.mkdir(parents=True, exist_ok=True)
    env = env if env is not None else isolated_ros_env()
    hosts = hosts or {}
    report_path = out_dir / 'comparison.json'
    if report_path.exists():
        report_path.unlink()
    # No video file from the camera: the recording holds the frames (compressed), and encoding
    # an mp4 beside the JPEGs cost the live graph real time (saw-ros bag video makes it after).
    node_params = node_parameters(duration, real_time_factor, scenario, record, camera,
                                  report_path, reference_file, controller, foxglove)
    nodes: List[ManagedProcess] = []
    codes: Dict[str, int] = {}
    start = time.monotonic()

    def launch(name, **params):
        # The simulator sets the pace; the others consume its messages in batches
        # (process.batch_policy: their wake-ups would preempt it).
        p = ManagedProcess(name, hosts.get(name, []) + node_command(name, params=params), env,
                           logs, batch=name != 'simulator')
        nodes.append(p)
        return p

    def check_alive():
        for p in nodes:
            if p.returncode not in (None, 0):
                raise PipelineError(f'{p.name} exited with {p.returncode}:\n{_tail(p.log_path)}')

    probe = None
    try:
        if record:
            # Readiness from the graph: camera, comparison and vision say ready on /saw/ready
            # (saw_ros.ros.ready); a probe process waits for them (no rclpy here). Started
            # first, it discovers the graph while the nodes start.
            probe_command = hosts.get('ready', []) + node_command(
                'ready', package='saw_ros.ros') + [
                '--nodes', ','.join(READY_NODES), '--timeout', f'{3 * MATCH_TIMEOUT:g}']
            probe = ManagedProcess('ready', probe_command, env, logs)
        started = {name: launch(name, **values) for name, values in node_params.items()}
        simulator, comparison = started['simulator'], started['comparison']
        if record:
            # With a recorder the simulator starts stepping once the recorder has matched its
            # topics (/saw/twist & co. have no other subscriber). So the recorder comes last:
            # once camera and comparison have matched the simulator (their status on /saw/ready;
            # started together, the camera or comparison sometimes matched 0.25-0.5 s after the
            # recorder: their first poses were lost) and the tracker is up. The recorder matches
            # the camera's and tracker's topics (published from the first frame on) in the same
            # discovery pass as the simulator's. (Not ready within MATCH_TIMEOUT: the probe
            # exits 1 and the run goes on.)
            while probe is not None and probe.returncode is None:
                check_alive()
                time.sleep(0.05)
            if bag_dir is None:
                bag_dir = Path('bags') / time.strftime('%Y-%m-%d_%H-%M-%S_demo')
            extra = {'topics': '[' + ','.join(f"'{t}'" for t in (
                record_topics or RECORDED_TOPICS)) + ']'}
            launch('recorder', output=str(bag_dir), **extra)
        limit = timeout if timeout is not None else 60.0 + 3.0 * duration / max(
            real_time_factor, 0.1)
        deadline = time.monotonic() + limit
        while simulator.returncode is None or comparison.returncode is None:
            check_alive()
            if time.monotonic() > deadline:
                raise PipelineError(f'the run did not finish within {limit:.0f} s; see {logs}')
            if progress is not None:
                progress()
            time.sleep(0.2)
    finally:
        if probe is not None:
            probe.stop(timeout=5.0)
        # Downstream first, the recorder last so that it keeps every message until the end.
        for p in sorted(nodes, key=lambda p: p.name == 'recorder'):
            codes[p.name] = p.stop(timeout=10.0)
    comparison_values = json.loads(report_path.read_text()) if report_path.exists() else {}
    return PipelineRun(out_dir, Path(bag_dir) if record and bag_dir is not None else None,
                       comparison_values, codes,
                       time.monotonic() - start, {p.name: p.log_path for p in nodes})
