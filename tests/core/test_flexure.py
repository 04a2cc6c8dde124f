"""A compliant robot's flexures (issue 31): exact oscillator, series contact, rigid limit."""
import math

import numpy as np
import pytest

from saw_ros.core.contact import ContactLaw, NORMAL
from saw_ros.core.dynamics import Simulator
from saw_ros.core.flexure import balance_links, contact_law, elastic_law, Flexures, replay_links
from saw_ros.core.flexure import transmissibility
from saw_ros.core.params import FlexureParams, ParameterError, Scenario, SurfaceParams

TPU = FlexureParams(stiffness=2000.0, damping=0.5, link_mass=0.004)     # docs/model.md, TPU
KN, EXPONENT = 15500.0, 1.5                                              # the paper's contact


def drive(flexures, bottom, top, law=None, before=None):
    """One step: the links balanced against their contacts at the step's end, then advanced."""
    n = len(bottom)
    e, fb, ft = np.empty(n), np.empty(n), np.empty(n)
    before = (np.zeros(n), np.zeros(n)) if before is None else before
    balance_links(bottom, top, *before, flexures.prepare(), flexures.compliance,
                  elastic_law(KN, EXPONENT) if law is None else law, e, fb, ft)
    flexures.advance(fb - ft)
    return e, fb, ft


def test_a_free_link_rings_at_sqrt_k_over_m_and_decays_at_c_over_2m():
    dt = 1e-4
    flexures = Flexures(TPU, 1, dt)
    flexures.deflection[0] = 1e-4
    e = []
    for _ in range(400):
        flexures.advance(np.zeros(1))
        e.append(flexures.deflection[0])
    t = dt * np.arange(1, 401)
    decay = TPU.damping / (2 * TPU.link_mass)
    omega = math.sqrt(TPU.stiffness / TPU.link_mass - decay ** 2)
    exact = 1e-4 * np.exp(-decay * t) * (np.cos(omega * t) + decay / omega * np.sin(omega * t))
    np.testing.assert_allclose(e, exact, atol=1e-13)


def test_a_pressed_link_settles_where_flexure_and_contact_balance():
    """At rest k e = kn (d - e)^p: the flexure in series with the Hertz contact."""
    flexures = Flexures(TPU, 2, 1e-3)
    bottom, top = np.array([0.002, -0.01]), np.array([-0.01, 0.003])
    for _ in range(300):
        e, fb, ft = drive(flexures, bottom, top)
    # Link 0 pressed up from below, link 1 down from above.
    assert e[0] > 0 > e[1]
    assert TPU.stiffness * e[0] == pytest.approx(KN * (0.002 - e[0]) ** 1.5, rel=1e-8)
    assert -TPU.stiffness * e[1] == pytest.approx(KN * (0.003 + e[1]) ** 1.5, rel=1e-8)
    np.testing.assert_allclose(flexures.reaction, [fb[0], -ft[1]], rtol=1e-6)


def test_both_tips_touching_balance_one_link():
    """A link squeezed between both walls: one deflection, both contacts, exact balance."""
    flexures = Flexures(TPU, 1, 1e-3)
    e, fb, ft = np.empty(1), np.empty(1), np.empty(1)
    free = np.array([2e-4])
    balance_links(np.array([0.002]), np.array([0.001]), np.zeros(1), np.zeros(1), free,
                  flexures.compliance, elastic_law(KN, EXPONENT), e, fb, ft)
    assert fb[0] > 0 and ft[0] > 0
    assert e[0] == pytest.approx(free[0] + flexures.compliance * (fb[0] - ft[0]), abs=1e-12)


def test_a_link_on_the_hysteresis_kink_of_a_linear_law_converges():
    """
    A step of the TPU robot on hertz_exponent 1 whose Newton hopped between two points.

    Recorded from a run (the 0.69 mm depth the law last saw sits on the hysteresis band's
    end): both points were already the bracket's ends, so no bisection broke the cycle, and
    all 60 iterations ended 12.5 um from the root (residual 4.3e-5 m). Now the root's residual
    is rounding.
    """
    compliance = 3.988264395363909e-05
    law = np.array([14725.0, 775.0, 77500000.0, 1.0])
    bottom, top, before, free = 0.00540912771168749, -0.0316, 0.000689090902300995, 0.00431843
    e, fb, ft = np.empty(1), np.empty(1), np.empty(1)
    balance_links(np.array([bottom]), np.array([top]), np.array([before]), np.zeros(1),
                  np.array([free]), compliance, law, e, fb, ft)
    assert fb[0] > 0.0 and ft[0] == 0.0
    assert abs(e[0] - free - compliance * fb[0]) < 1e-12


@pytest.mark.parametrize('frequency', [12.0, 60.0])
def test_a_harmonically_pressed_link_follows_the_closed_form(frequency):
    """
    Target d0 + a sin(w t) into a linear contact: steady e and reaction against the closed form.

    The only error is holding the contact load over a step: first order in dt, so halving the
    step halves it (the measured error at the simulator's 1 ms is the docs' figure).
    """
    contact, d0, a = 1000.0, 0.002, 0.0005
    errors = []
    for dt in (1e-3, 5e-4, 2.5e-4):
        flexures = Flexures(TPU, 1, dt)
        steps = int(round(1.0 / dt))
        w = 2 * math.pi * frequency
        t = dt * np.arange(1, steps + 1)
        e_out, r_out = np.empty(steps), np.empty(steps)
        for i in range(steps):
            drive(flexures, np.array([d0 + a * math.sin(w * t[i])]), np.array([-1.0]),
                  elastic_law(contact, 1.0))
            e_out[i], r_out[i] = flexures.deflection[0], flexures.reaction[0]
        late = t > 0.5              # the transient has decayed (c / 2m = 62 /s)
        basis = np.exp(-1j * w * t[late])
        amplitude = 2 * np.mean(e_out[late] * basis) / a / 1j * -1
        e_ratio, _ = transmissibility(frequency, TPU.stiffness, TPU.damping, TPU.link_mass,
                                      contact)
        errors.append(abs(amplitude - e_ratio) / abs(e_ratio))
        # The reaction's mean is the contact's static share: k e = kc (d0 - e).
        static = contact * d0 / (TPU.stiffness + contact)
        assert np.mean(r_out[late]) == pytest.approx(TPU.stiffness * static, rel=1e-3)
    assert errors[-1] < 0.01
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.25)
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.25)


def test_rigid_flexures_pass_the_contact_load_as_rigid_links():
    """At the top of the range the link does not move and the backbone feels the Hertz load."""
    rigid = FlexureParams(stiffness=1e9, damping=0.0, link_mass=0.004)
    flexures = Flexures(rigid, 1, 1e-3)
    for i in range(200):
        depth = 0.002 + 0.0005 * math.sin(2 * math.pi * 12 * i * 1e-3)
        e, fb, _ = drive(flexures, np.array([depth]), np.array([-1.0]))
        assert abs(flexures.deflection[0]) < 1e-8
        assert flexures.reaction[0] == pytest.approx(KN * depth ** 1.5, rel=2e-4)


def test_the_backbone_gets_the_loads_impulse_less_the_links_momentum():
    dt = 1e-3
    flexures = Flexures(TPU, 3, dt)
    loads = np.array([0.3, -0.2, 0.0])
    impulse = np.zeros(3)
    for i in range(50):
        flexures.advance(loads * math.cos(0.3 * i))
        impulse += flexures.reaction * dt
        if i == 0:
            first_rate = flexures.rate.copy()
    held = sum(loads * math.cos(0.3 * i) * dt for i in range(50))
    np.testing.assert_allclose(impulse, held - TPU.link_mass * flexures.rate, atol=1e-15)
    assert np.abs(first_rate).max() > 0
    assert flexures.energy() > 0


def test_rigid_links_are_not_flexures():
    with pytest.raises(ValueError, match='rigid links'):
        Flexures(FlexureParams(), 19, 1e-3)


def test_replaying_penetrations_matches_the_stepped_flexures_and_rigid_links():
    """The compiled replay is the Flexures class step by step; rigid, it returns the loads."""
    t = 1e-3 * np.arange(300)
    phase = 2 * math.pi * 12 * t[:, None] + np.linspace(0, 2 * math.pi, 4)[None, :]
    bottom = np.ascontiguousarray(0.002 * np.sin(phase))
    top = np.ascontiguousarray(0.002 * np.sin(phase + math.pi))
    reaction, deflection = np.empty_like(bottom), np.empty_like(bottom)
    law = contact_law(SurfaceParams(), 1e-3)             # the paper's, with its hysteresis
    replay_links(bottom, top, np.zeros(4), np.zeros(4), TPU.stiffness, TPU.damping,
                 TPU.link_mass, 1e-3, law, reaction, deflection)
    flexures = Flexures(TPU, 4, 1e-3)
    before = (np.zeros(4), np.zeros(4))
    for i in range(len(t)):
        drive(flexures, bottom[i], top[i], law, before)
        np.testing.assert_allclose(flexures.reaction, reaction[i], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(flexures.deflection, deflection[i], rtol=1e-9, atol=1e-15)
    replay_links(bottom, top, np.zeros(4), np.zeros(4), 1e9, 0.0, TPU.link_mass, 1e-3,
                 elastic_law(KN, EXPONENT), reaction, deflection)
    loads = KN * np.maximum(bottom, 0) ** 1.5 - KN * np.maximum(top, 0) ** 1.5
    np.testing.assert_allclose(reaction, loads, atol=2e-3 * np.abs(loads).max())


def test_the_link_solve_uses_the_contact_laws_own_constants():
    surface = SurfaceParams(restitution=0.7, hysteresis_speed=0.02)
    core = ContactLaw.from_values(surface.normal_stiffness, surface.tangential_stiffness,
                                  surface.friction_coefficient, surface.hertz_exponent,
                                  surface.restitution, surface.hysteresis_speed, 1e-3)
    np.testing.assert_allclose(contact_law(surface, 1e-3),
                               [core.kn_mean, core.kn_half, core.kn_rate, core.exponent])


def test_rigid_flexures_in_the_step_give_todays_trajectory():
    """The stiffest flexures the range allows follow the rigid robot within 1e-6 m over 4 s."""
    base = Scenario()
    rigid, stiff = Simulator(base), Simulator(base.with_values({'flexure.stiffness': 1e9}))
    deviation = 0.0
    for _ in range(40):
        rigid.run(0.1)
        stiff.run(0.1)
        deviation = max(deviation, float(np.abs(rigid.q[:3] - stiff.q[:3]).max()))
    assert deviation < 1e-6


def test_flexures_in_the_step_deflect_and_keep_the_bodys_momentum():
    """A TPU robot: links deflect as the flexure and the contact balance; the body is held."""
    scenario = Scenario().with_values({'flexure.stiffness': TPU.stiffness,
                                       'flexure.damping': TPU.damping})
    sim = Simulator(scenario)
    sim.run(0.5)
    state = sim._flex_state[0]
    n = state.shape[1]
    # Each link's deflection balances its flexure against its tips' loads (to the hold's
    # error: the rate term is small at rest-like steady crawling).
    load = sim.tips[0, NORMAL, :n] - sim.tips[0, NORMAL, n:]
    assert np.abs(state[0]).max() > 1e-4
    np.testing.assert_allclose(state[2], load, atol=1e-12)
    # Pressed up by its bottom tip, a link deflects up, and the other way round.
    pressed = np.abs(load) > 0.2
    assert (np.sign(state[0][pressed]) == np.sign(load[pressed])).all()
    # The depth the law saw is the penetration less the deflection.
    np.testing.assert_allclose(sim.depth[0, :n], sim.penetration[0, :n] - state[0], atol=1e-12)


def test_the_deflections_and_the_tips_the_simulator_shows_are_the_flexures():
    """Simulator.deflection (joint states, TF) is the links' e; the tips sit where pressed."""
    scenario = Scenario().with_values({'flexure.stiffness': TPU.stiffness,
                                       'flexure.damping': TPU.damping})
    sim, rigid = Simulator(scenario), Simulator(Scenario())
    sim.run(0.3)
    rigid.run(0.3)
    e, n = sim.deflection[0], scenario.robot.wave_links
    assert e.shape == (n,) and np.abs(e).max() > 1e-4
    assert (e == sim._flex_state[0, 0]).all() and (sim.deflection_rate[0] ==
                                                   sim._flex_state[0, 1]).all()
    # Both tips of a link move with it: each as deep in its wall as the contact law saw it.
    tips = sim.tip_positions[0]
    depth = np.concatenate([-tips[:n].imag, tips[n:].imag - scenario.conditions.gap])
    np.testing.assert_allclose(depth, sim.depth[0], atol=1e-15)
    assert not rigid.deflection.any() and not rigid.deflection_rate.any()
    # Switched off, the flexures keep their state unstepped: the links are rigid, e = 0.
    sim.set_scenarios([Scenario()])
    assert not sim.deflection.any() and sim._flex_state[0, 0].any()


def test_flexures_switched_on_during_a_run_start_at_rest():
    scenario = Scenario().with_values({'flexure.stiffness': TPU.stiffness})
    sim = Simulator(scenario)
    sim.run(0.2)
    assert np.abs(sim._flex_state[0, 0]).max() > 0
    sim.set_scenarios([Scenario()])                  # rigid links: the flexures stop
    sim.run(0.05)
    sim.set_scenarios([scenario])                    # and come back at rest
    assert not sim._flex_state.any()
    sim.run(0.05)
    assert np.abs(sim._flex_state[0, 0]).max() > 0


@pytest.mark.parametrize('values, message', [
    ({'flexure.stiffness': 1e-300}, 'at least 1 N/m'),
    ({'flexure.link_mass': 1e-300}, 'flexure.link_mass = 1e-300 is out of range'),
])
def test_flexures_beyond_the_model_are_refused(values, message):
    """Found at the ranges' ends: 1 / k and -c / 2m overflowed in the kernel."""
    with pytest.raises(ParameterError, match=message):
        Scenario().with_values(values)
