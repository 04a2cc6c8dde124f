"""A batch spread over threads (core.dynamics.spread) gives the numbers of one thread."""
import threading

import numba
import numpy as np
import pytest

from saw_ros.bench.core import one_thread
from saw_ros.core import DivergenceError, Scenario, Simulator
from saw_ros.core import dynamics

# Rigid walls at three slopes and frictions, the silicone sheet, a motor, both together.
MIXED = [{'conditions.slope': 0.3}, {'surface.friction_coefficient': 0.4},
         {'conditions.gap': 0.05, 'conditions.slope': 0.6},
         {'surface.foundation_stiffness': 1.5e5}, {'motor.voltage': 6.0},
         {'surface.foundation_stiffness': 1.5e5, 'motor.voltage': 6.0}, {},
         {'conditions.frequency': 1.7}, {'conditions.slope': -0.2}]
STEPS = 300          # 9 scenarios x 300 steps: more than PARALLEL_WORK, spread


@pytest.fixture
def calls(monkeypatch):
    """Record (thread, first scenario, last + 1) of every ``advance`` call, then make it."""
    made = []
    kernel = dynamics.advance

    def recorded(start, stop, *arguments):
        made.append((threading.get_ident(), start, stop))
        kernel(start, stop, *arguments)
    monkeypatch.setattr(dynamics, 'advance', recorded)
    return made


def run(contacts=True):
    scenarios = [Scenario().with_values(v) for v in MIXED]
    return Simulator(scenarios).run(STEPS * scenarios[0].integration.dt, contacts=contacts)


@pytest.mark.skipif(numba.get_num_threads() < 2, reason='one core: nothing to spread over')
def test_a_spread_batch_gives_one_threads_numbers_bit_for_bit(calls):
    spread = run()
    # It was spread: cut into parts for the threads to take. (Which threads took them is the
    # scheduler's: under a CPU cap one thread took them all.)
    assert len(calls) >= 2
    covered = sorted((start, stop) for _, start, stop in calls)
    assert [a for a, _ in covered] == [0] + [b for _, b in covered[:-1]]    # each part once
    assert covered[-1][1] == len(MIXED)
    calls.clear()
    alone = one_thread(run)
    assert calls == [(threading.get_ident(), 0, len(MIXED))]
    for name in ('q', 'omega', 'normal', 'tangential', 'torque', 'current'):
        np.testing.assert_array_equal(getattr(spread, name), getattr(alone, name), err_msg=name)


def test_a_thread_of_a_pool_steps_its_batch_on_that_thread(calls):
    # Dask's workers step batches on their threads, each already one core's worth of work.
    done = []
    worker = threading.Thread(target=lambda: done.append(run(contacts=False)))
    worker.start()
    worker.join()
    assert done and {thread for thread, _, _ in calls} == {worker.ident}


def test_a_scenario_leaving_the_model_in_a_spread_batch_is_named_with_its_time():
    # The tether drags scenario 5 past MAX_SPEED: the spread batch stops at the same step as
    # the scenario alone and names it.
    tether = Scenario().with_values({'conditions.external_force': 100.0})
    with pytest.raises(DivergenceError) as alone:
        Simulator(tether).run(2.0)
    scenarios = [Scenario().with_values(v) for v in MIXED[:5]] + [tether] + [Scenario()] * 3
    with pytest.raises(DivergenceError) as batch:
        Simulator(scenarios).run(2.0)
    assert str(batch.value) == str(alone.value).replace('(scenario 0)', '(scenario 5)')
