"""
A benchmark rung whose processes hang is a failed rung with its logs kept.

And a module that fails anyway does not take the bench (and the other modules' figures) down with
it.
"""
import argparse
import json
import sys

import pytest


@pytest.mark.ros
def test_a_hanging_simulator_is_a_failed_rung_with_its_logs_kept(tmp_path, monkeypatch):
    from saw_ros.graph import process
    from saw_ros.bench import simulator_node
    real = process.node_command

    def hanging(executable, *args, **kwargs):
        if executable != 'simulator':
            return real(executable, *args, **kwargs)
        # A simulator that never gets its subscribers: the hang of the issue, in 0 CPU.
        return [sys.executable, '-c', 'import time\n'
                'print("[simulator]: waiting for 1 subscriber(s) on every topic", flush=True)\n'
                'time.sleep(600)']
    monkeypatch.setattr(process, 'node_command', hanging)
    result = simulator_node.measure(1.5, 1.0, tmp_path, timeout=2.0)
    assert result['sustained'] is False
    assert result['hung'].startswith('simulator did not exit within 2 s'), result
    assert result['simulator_state'].startswith('never started stepping'), result
    assert result['simulator_cpu_at_timeout'] < 0.5      # asleep: stuck, not slow
    logs = tmp_path / 'rtf_1.5'
    assert result['logs'] == str(logs)
    assert 'waiting for 1 subscriber' in (logs / 'simulator.log').read_text()
    assert (logs / 'subscriber.log').is_file()
    assert result['lost'] == simulator_node.expected_messages(1000)     # nothing received
    json.dumps(result)                   # what the bench prints


def test_simulator_state_from_its_log():
    from saw_ros.bench.simulator_node import simulator_state
    assert 'discovery' in simulator_state('waiting for 1 subscriber(s) on every topic')
    assert simulator_state('waiting for 1 ...\nsubscribers present: starting') == \
        'stepping, duration not reached'
    assert 'stop path' in simulator_state('subscribers present: starting\nduration 10 s reached '
                                          'after 10000 steps: stopping')


def test_a_failing_module_gives_null_figures_and_the_bench_goes_on(tmp_path, monkeypatch,
                                                                   capsys):
    from saw_ros.bench import core, figures
    from saw_ros.cli.commands import bench

    def broken(quick=False):
        raise TimeoutError('a subprocess hung')
    monkeypatch.setenv('SAW_BENCH_LOGS', str(tmp_path / 'logs'))     # restored afterwards
    monkeypatch.setattr(core, 'run', broken)
    monkeypatch.setattr(figures, 'run', lambda quick=False: {'figures_s': 1.0})
    args = argparse.Namespace(only='core,figures', quick=True, json=True,
                              logs=str(tmp_path / 'logs'))
    assert bench.run(args) == 1
    out = json.loads(capsys.readouterr().out)
    assert out['figures_s'] == 1.0
    assert all(out[key] is None for key in core.KEYS)
    assert 'TimeoutError: a subprocess hung' in out['bench_errors']['core']
    assert 'a subprocess hung' in (tmp_path / 'logs' / 'core.error').read_text()


@pytest.mark.ros
@pytest.mark.slow
def test_one_real_rung_passes_through_measure(tmp_path):
    from saw_ros.bench import simulator_node
    result = simulator_node.measure(1.0, 1.0, tmp_path)
    assert 'hung' not in result, result
    assert result['simulator_exit'] == 0, result
    assert result['received'] > 0


@pytest.mark.ros
@pytest.mark.slow
def test_a_domain_another_run_publishes_in_is_left_for_another(tmp_path, monkeypatch):
    """
    A domain another graph uses (not one of ours: those are reserved).

    Another simulator's messages counted as ours and kept the bench's subscriber alive past the
    rung (the TimeoutExpired of issue 10). The subscriber finds the other publishers first; the
    rung is run in another domain.
    """
    from saw_ros.graph import process
    from saw_ros.bench import simulator_node
    from saw_ros.graph.process import ManagedProcess, isolated_ros_env, node_command, wait_for
    env = isolated_ros_env()
    taken = int(env['ROS_DOMAIN_ID'])
    other = ManagedProcess('other_run', node_command('simulator', params={
        'real_time_factor': 0.1}), env, tmp_path / 'other')
    try:
        assert wait_for(lambda: 'simulating at' in other.output(), 30), other.output()
        # Our own runs never share a domain (reserve_domain's locks); a foreign graph can still
        # be there: hand the rung the busy domain first.
        picks = iter([taken])
        reserve = process.reserve_domain
        monkeypatch.setattr(process, 'reserve_domain', lambda: next(picks, None) or reserve())
        result = simulator_node.measure(1.0, 1.0, tmp_path)
    finally:
        other.stop()
    assert result['busy_domains'] == [taken], result
    assert result['domain'] != taken
    assert result['publishers'] == 1 and result['simulator_exit'] == 0, result
    assert result['received'] <= 6000 and result['bad'] == 0, result
