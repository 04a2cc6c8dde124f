"""
The bench's ladders climb until a rung fails: their top is not what they measure (issue 20).

A machine that sustains every rung gets the top rung flagged as a lower bound in the JSON.
The rungs here are stand-ins for the graph (a threshold), the ladder logic is the bench's.
"""
import json

import pytest


def _sustains_up_to(limit, calls):
    def measure(rtf, duration, work, *args, **kwargs):
        calls.append(rtf)
        return {'sustained': rtf <= limit, 'lost': 0 if rtf <= limit else 7,
                'cpu_share': {'simulator': 0.5}}
    return measure


@pytest.mark.parametrize('limit', [0.6, 0.77, 1.0, 1.5, 2.0, 4.3, 4.45, 7.0, 1e9])
def test_pipeline_ladder_finds_the_limit_or_says_it_is_a_lower_bound(
        tmp_path, monkeypatch, limit):
    from saw_ros.bench import pipeline
    calls = []
    monkeypatch.setattr(pipeline, 'measure', _sustains_up_to(limit, calls))
    best, lost, cpu, capped, first = pipeline.ladder(1.0, tmp_path, [])
    assert first['sustained'] == (limit >= 1.0)
    rungs = sorted(pipeline.UP + pipeline.DOWN)
    held = max(r for r in rungs if r <= limit)
    assert lost == 0 and cpu == {'simulator': 0.5}
    assert capped == (limit >= pipeline.UP[-1])
    assert pipeline.UP[-1] >= 10 * 2.0    # far above the 2.0 the old ladder stopped at
    if capped:
        assert best == pipeline.UP[-1] and calls[-1] == best
        return
    # The coarse ladder stopped at the first rung that failed, then bisected the step below it
    # REFINE times: the figure is held and the limit lies within an eighth of that step above it.
    failed = min(r for r in rungs if r > limit)
    step = (failed - held) / 2 ** pipeline.REFINE
    assert held <= best <= limit < best + step + 1e-9, (best, calls)
    assert sorted(calls[-pipeline.REFINE:]) == sorted(set(calls[-pipeline.REFINE:]))
    assert all(held < r < failed for r in calls[-pipeline.REFINE:]), calls


@pytest.mark.parametrize('limit', [3.0, 7.0, 1e9])
def test_simulator_node_ladder_climbs_past_5(tmp_path, monkeypatch, limit):
    from saw_ros import bench
    from saw_ros.bench import simulator_node
    calls = []
    monkeypatch.setenv(bench.LOGS_ENV, str(tmp_path))
    monkeypatch.setattr(simulator_node, 'measure', _sustains_up_to(limit, calls))
    out = simulator_node.run(quick=True)
    assert set(out) == set(simulator_node.KEYS)
    held = [r for r in simulator_node.LADDER if r <= limit]
    assert out['sim_max_realtime_factor'] == max(held)
    assert out['sim_max_realtime_factor_is_lower_bound'] is (limit >= simulator_node.LADDER[-1])
    assert simulator_node.LADDER[-1] >= 10 * 5.0
    json.dumps(out)


class _Hog:
    """Stands in for a CPU hog process: it must be killed and waited for."""

    running = []

    def __init__(self, argv, **kwargs):
        assert 'while True: pass' in argv[-1]
        _Hog.running.append(self)

    def kill(self):
        _Hog.running.remove(self)

    def wait(self):
        assert self not in _Hog.running


@pytest.mark.parametrize('limit', [0, 1, 3, 8])
def test_recorder_foreign_hogs_is_the_last_rung_without_loss(tmp_path, monkeypatch, limit):
    from saw_ros.bench import recorder
    rungs = []

    def trial(work, name, env, **load):
        n = int(name[len('hogs'):])
        rungs.append(n)
        # the default load, with n hogs running beside it
        assert len(_Hog.running) == n and load == dict(recorder.DEFAULT_LOAD, duration=1.5)
        return 1000, 1.0, 0 if n <= limit else 3, 0.2

    _Hog.running = []
    monkeypatch.setattr(recorder.subprocess, 'Popen', _Hog)
    monkeypatch.setattr(recorder, '_trial', trial)
    held = recorder.foreign_hogs(tmp_path, {}, 1.5)
    assert held == max([0] + [n for n in recorder.HOGS if n <= limit]) and not _Hog.running
    below = [n for n in recorder.HOGS if n <= limit]
    assert rungs == below + [n for n in recorder.HOGS if n > limit][:1]   # stops at a loss
