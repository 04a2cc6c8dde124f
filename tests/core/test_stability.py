"""The integrator's limit (saw_ros/core/stability.py) and the Scenario's checks across fields."""
import dataclasses

import numpy as np
import pytest

from saw_ros.core import Scenario, Simulator
from saw_ros.core import stability
from saw_ros.core.dynamics import DivergenceError, simulate
from saw_ros.core.params import IntegrationParams, ParameterError


def _omega(s):
    return stability.contact_omega(s.robot, s.surface.normal_stiffness, s.surface.hertz_exponent,
                                   s.surface.tangential_stiffness, s.conditions.gap)


def _limit_kn(s):
    """Return the stiffest surface.normal_stiffness the check takes with the rest of ``s``."""
    dt = s.integration.dt
    return stability._largest(
        lambda k: _omega(s.with_values({'surface.normal_stiffness': k})) * dt
        <= stability.OMEGA_DT_MAX, 1e8)


def test_the_bound_is_the_stiffness_a_running_simulation_meets():
    # The trace over the touching tips of a running simulation, at its deepest moment, against
    # the bound from the start position: within 10 %, and never far below it.
    s = Scenario()
    sim = Simulator(s)
    m, inertia = s.robot.mass, s.robot.inertia
    p, kn, kt = 1.5, s.surface.normal_stiffness, s.surface.tangential_stiffness
    worst = 0.0
    for _ in range(2000):
        sim.step()
        depth = np.maximum(sim.penetration[0], 0.0)
        rx = sim._x[0] - sim.q[0, 0]
        ry = sim.tip_positions[0].imag - sim.q[1, 0]
        touching = depth > 0
        k = p * kn * np.sqrt(depth)
        worst = max(worst, float(np.where(touching, k * (1 / m + rx ** 2 / inertia)
                                          + kt * (1 / m + ry ** 2 / inertia), 0).sum()))
    assert np.sqrt(worst) == pytest.approx(_omega(s), rel=0.1)


def test_just_inside_the_limit_runs_and_just_outside_is_refused_with_what_is_allowed():
    s = Scenario()
    kn = _limit_kn(s)
    assert 4e5 < kn < 4.5e5                          # 336 rad/s at 15 500: (1.5 / 0.336)^2 x
    inside = s.with_values({'surface.normal_stiffness': 0.99 * kn})
    tr = simulate(inside, 3.0)
    assert np.isfinite(tr.q).all() and abs(tr.q[-1, 0, 1] - 0.0225) < 0.005
    outside = s.with_values({'surface.normal_stiffness': 1.01 * kn})
    with pytest.raises(ParameterError, match=r'too stiff for integration.dt = 0.001 s .* '
                                             r'surface.normal_stiffness <= 4\.\d+e\+05'):
        Simulator(outside)


def test_beyond_the_step_limit_the_simulation_does_diverge(monkeypatch):
    # What the check prevents: at kn = 1e6 (omega dt 2.3 > 2) the unchecked step blows up.
    monkeypatch.setattr(stability, 'check', lambda scenario: None)
    with pytest.raises(DivergenceError):
        simulate(Scenario().with_values({'surface.normal_stiffness': 1e6}), 1.0)


def test_declared_dt_range_ends_where_the_default_robot_is_still_stable():
    high = dataclasses.fields(IntegrationParams)[0].metadata['high']
    s = Scenario().with_values({'integration.dt': high})
    assert _omega(s) * high <= stability.OMEGA_DT_MAX < _omega(s) * high * 1.25
    tr = simulate(s, 3.0)
    assert np.isfinite(tr.q).all()
    # A smaller gap squeezes the robot harder: refused with the dt it would need.
    with pytest.raises(ParameterError, match=r'integration.dt <= 0.00\d+ s'):
        Simulator(s.with_values({'conditions.gap': 0.035}))


def test_tangential_stiffness_counts_and_the_worm_model_still_takes_any():
    with pytest.raises(ParameterError, match=r'surface.tangential_stiffness <= 7\.\d+e\+04'):
        Simulator(Scenario().with_values({'surface.tangential_stiffness': 1e5}))
    Scenario().with_values({'surface.tangential_stiffness': 1e6})     # no simulator: taken


def test_surfaces_too_soft_for_the_weight_are_refused_at_the_edge():
    # 19 bottom tips at 15 mm: kn * 19 * 0.015^1.5 must carry 0.313 * 9.81 N.
    edge = 0.313 * 9.81 / (19 * 0.015 ** 1.5)
    Scenario().with_values({'surface.normal_stiffness': edge * 1.001})
    with pytest.raises(ParameterError, match=r'too soft: .* allowed above 87\.9\d N/m\^1\.5'):
        Scenario().with_values({'surface.normal_stiffness': edge * 0.999})
    with pytest.raises(ParameterError, match=r'too soft'):
        Scenario().with_values({'surface.hertz_exponent': 3.0})


def test_a_motor_faster_than_the_frequency_range_is_refused():
    s = Scenario().with_values({'motor.voltage': 20.0})
    assert s.frequency < 5.0
    with pytest.raises(ParameterError, match=r'motor.voltage = 19 V .* 18 Hz .* up to 6\.\d+ V'):
        Scenario().with_values({'motor.voltage': 19.0, 'motor.hz_per_volt': 1.0})


def test_a_narrower_gap_that_the_state_cannot_take_is_named():
    sim = Simulator(Scenario())
    sim.run(1.0)
    sim.set_scenarios([Scenario().with_values({'conditions.gap': 0.040})])
    assert sim.placement_error() is None
    sim.set_scenarios([Scenario().with_values({'conditions.gap': 0.035})])
    assert 'mm deep in the top surface' in sim.placement_error()
    t = sim.t
    sim.reset()                          # the node's answer: time goes on, the robot restarts
    assert sim.t == t and sim.placement_error() is None
    sim.run(1.0)


def test_a_motor_too_light_for_the_step_is_refused_with_the_inertia_it_needs(monkeypatch):
    # A quasi-static rotor (J = 0) behind a weak, resistive motor: the helix's inertia is then
    # only k^2 dt / R (8e-10 kg m^2), and the explicit load torque makes it ring.
    weak = {'motor.hz_per_volt': 10.0, 'motor.resistance': 320.0, 'motor.voltage': 0.5,
            'motor.friction_torque': 0.0, 'motor.inertia': 0.0}
    with pytest.raises(ParameterError, match=r'motor.inertia >= ') as refused:
        Simulator(Scenario().with_values(weak))
    needed = float(str(refused.value).split('motor.inertia >= ')[1].split()[0])
    just_inside = Scenario().with_values({**weak, 'motor.inertia': needed * 1.01})
    sim = Simulator(just_inside)
    sim.run(2.0)
    assert np.isfinite(sim.omega).all() and abs(sim.omega[0]) < 100.0
    # Without the check, a tenth of it runs away at once: the limit is where the step fails.
    monkeypatch.setattr(stability, 'check', lambda scenario: None)
    with pytest.raises(DivergenceError, match='helix turned at'):
        simulate(Scenario().with_values({**weak, 'motor.inertia': needed * 0.1}), 0.5)
    # The paper's motor, even quasi-static (J = 0), is far inside the limit.
    default = Scenario().with_values({'motor.voltage': 6.0, 'motor.inertia': 0.0})
    assert stability._motor_margin(default, 0.0) < 0.05
