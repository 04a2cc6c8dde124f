import math

import numpy as np
import pytest

from saw_ros.core import DivergenceError, Scenario, simulate, Simulator
from saw_ros.core.dynamics import GRAVITY
from saw_ros.core.metrics import analyse
from saw_ros.core.params import ParameterError


def metrics(scenario, duration=4.0):
    tr = simulate(scenario, duration)
    return analyse(tr.t, tr.q[:, 0], scenario.robot, scenario.frequency)


@pytest.mark.parametrize('slope_deg', [0.0, 30.0, -20.0])
def test_robot_at_rest_settles_with_normal_forces_carrying_m_g_cos_alpha(slope_deg):
    alpha = math.radians(slope_deg)
    s = Scenario().with_values({'conditions.frequency': 0.0, 'conditions.slope': alpha})
    sim = Simulator(s)
    sim.run(3.0)
    fn = sim.contacts.normal[0]
    side = sim.table.side
    weight = s.robot.mass * GRAVITY
    assert -(fn @ side) == pytest.approx(weight * math.cos(alpha), rel=1e-3)
    assert sim.contacts.tangential[0].sum() == pytest.approx(weight * math.sin(alpha), abs=1e-3)
    assert np.abs(sim.q[3:, 0]).max() < 1e-4      # at rest


def test_default_case_crawls_head_first_with_the_papers_advance_ratio():
    level = metrics(Scenario())
    vertical = metrics(Scenario().with_values({'conditions.slope': math.pi / 2}))
    # Paper (Figure 21, Conclusions): 0.72 level, 0.61 vertical.
    assert level.advance_ratio == pytest.approx(0.72, rel=0.10)
    assert vertical.advance_ratio == pytest.approx(0.61, rel=0.16)
    assert 0 < vertical.advance_ratio < level.advance_ratio


def test_velocities_converge_cycle_to_cycle_as_figure_8():
    m = metrics(Scenario(), 4.0)
    # Paper: every CCI under 2 % after 0.4 s and under 0.2 % after 1.2 s.
    assert m.cci_2pct_after is not None and m.cci_2pct_after < 1.0
    assert m.cci_02pct_after is not None and m.cci_02pct_after < 1.5


@pytest.mark.parametrize('slope_deg', [0.0, 90.0])
def test_halving_dt_changes_ar_by_under_2_percent(slope_deg):
    s = Scenario().with_values({'conditions.slope': math.radians(slope_deg)})
    coarse = metrics(s, 3.0).advance_ratio
    fine = metrics(s.with_values({'integration.dt': 0.0005}), 3.0).advance_ratio
    assert abs(coarse - fine) / fine < 0.02


def test_very_stiff_surfaces_and_high_cof_approach_the_rigid_surface_speed():
    # A rigid surface is touched only at the crests: the gap just under the robot's height.
    def ar(scale):
        s = Scenario().with_values({
            'conditions.gap': 0.056, 'surface.friction_coefficient': 1.5,
            'surface.normal_stiffness': 15500.0 * scale,
            'surface.tangential_stiffness': 1082.0 * scale,
            'integration.dt': 0.001 / math.sqrt(scale)})
        return metrics(s, 3.0).advance_ratio
    soft, stiff = ar(1.0), ar(50.0)
    assert stiff > 0.9 and stiff > soft


def test_scenarios_stepped_together_match_each_stepped_alone():
    scenarios = [Scenario().with_values(v) for v in (
        {'conditions.slope': 0.3}, {'surface.friction_coefficient': 0.4, 'conditions.gap': 0.05},
        {'conditions.frequency': 1.7, 'surface.tangential_stiffness': 500.0})]
    together = simulate(scenarios, 1.0).q
    for i, s in enumerate(scenarios):
        alone = simulate(s, 1.0).q[:, 0]
        np.testing.assert_allclose(together[:, i], alone, rtol=0, atol=1e-12)


def test_diverging_simulation_stops_with_when_and_why():
    # Too stiff for the step is refused up front now (tests/core/test_stability.py); what can
    # still leave the model: a robot bouncing off the surfaces deeper than max_penetration (a
    # fast wave in a wide gap), or one dragged past MAX_SPEED by the strongest tether allowed.
    s = Scenario().with_values({'conditions.gap': 0.08, 'conditions.frequency': 5.0})
    with pytest.raises(DivergenceError, match=r'diverged at t = \d+\.\d+ s .* pressed'):
        simulate(s, 2.0)
    s = Scenario().with_values({'conditions.external_force': 100.0})
    with pytest.raises(DivergenceError, match=r'diverged at t = \d+\.\d+ s .* beyond 100 m/s'):
        simulate(s, 2.0)


def test_set_scenarios_changes_conditions_at_once_and_keeps_the_state():
    sim = Simulator(Scenario())
    sim.run(1.0)
    x = sim.q[0, 0]
    with pytest.raises(ParameterError, match='cannot change during a run'):
        sim.set_scenarios([Scenario().with_values({'robot.mass': 0.5})])
    sim.set_scenarios([Scenario().with_values({'conditions.frequency': 0.0})])
    assert sim.q[0, 0] == x
    sim.run(1.0)
    assert abs(sim.q[3, 0]) < 0.01       # the wave stopped: the robot stops


def test_batch_may_differ_in_the_hertz_exponent():
    # The exponent is then an (S, P) array in the contact law, not a scalar.
    scenarios = [Scenario(), Scenario().with_values({'surface.hertz_exponent': 1.2})]
    together = simulate(scenarios, 0.5).q
    np.testing.assert_allclose(together[:, 0], simulate(scenarios[0], 0.5).q[:, 0], rtol=0,
                               atol=1e-9)
