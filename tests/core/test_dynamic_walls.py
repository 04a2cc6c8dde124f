"""Walls with mass and damping (issue 31): moving load, critical speed, ring-down, energy."""
import math

import numpy as np
import pytest

from saw_ros.core.dynamic_walls import critical_speed, DynamicWall, DynamicWalls, WALL_STATE
from saw_ros.core.dynamic_walls import mode_propagator, moving_load_deflection, ring_down
from saw_ros.core.dynamics import Simulator
from saw_ros.core.params import ParameterError, Scenario, SurfaceParams, WallDynamicsParams
from saw_ros.core.walls import CHOSEN, deflection, point_deflection, SOLVED, SOLVED_COUNT
from saw_ros.core.walls import TOLERANCE, TOLERANCE_COLUMN, Walls

K, EI, M = 9e3, 1.2e-5, 0.13                # the soft-tissue set of docs/walls.md, 0.13 kg/m
BETA = (K / (4 * EI)) ** 0.25
DAMPING = 0.1 * 2 * math.sqrt(K * M)        # a tenth of the foundation's critical damping
TISSUE = {'surface.foundation_stiffness': K, 'surface.bending_stiffness': EI}
TISSUE_WITH_MASS = {**TISSUE, 'walls.mass': M, 'walls.damping': DAMPING}


def run_moving_load(fraction, dt=5e-5, duration=0.3, damping=DAMPING):
    """Cross the tissue wall with a unit load at ``fraction`` of v_cr: return (xi, w, exact)."""
    speed = fraction * critical_speed(K, EI, M)
    wall = DynamicWall(K, EI, 1e-4, M, damping, dt)
    steps = int(round(duration / dt))
    for i in range(1, steps + 1):
        wall.step([1.0], [speed * i * dt - 0.3])
    xi = np.linspace(-6 / BETA, 6 / BETA, 241)
    w = wall.deflection(speed * steps * dt - 0.3 + xi)
    return xi, w, moving_load_deflection(xi, 1.0, speed, K, EI, M, damping)


def test_the_closed_form_at_rest_is_hetenyis_point_load():
    r = np.linspace(-0.05, 0.05, 101)
    np.testing.assert_allclose(moving_load_deflection(r, 2.0, 0.0, K, EI, M, DAMPING),
                               point_deflection(r, 2.0, K, EI), atol=1e-12)


@pytest.mark.parametrize('fraction', [0.5, 0.9])
def test_a_moving_load_settles_to_the_closed_form(fraction):
    """Steady deflection around the load within 1 % of its peak (issue: <= 1 %)."""
    xi, w, exact = run_moving_load(fraction)
    error = np.abs(w - exact).max() / np.abs(exact).max()
    assert error < 0.01
    # The wall's inertia matters here: the deflection is not the quasi-static one.
    static = point_deflection(xi, 1.0, K, EI)
    assert np.abs(exact - static).max() > 10 * error * np.abs(exact).max()


def test_the_closed_form_resonates_at_the_critical_speed():
    """Lightly damped, the deflection under the load peaks at (4 k EI / m^2)^(1/4)."""
    critical = critical_speed(K, EI, M)
    assert critical == pytest.approx((4 * K * EI / M ** 2) ** 0.25)
    speeds = critical * np.linspace(0.8, 1.2, 401)
    xi = np.linspace(-3 / BETA, 3 / BETA, 121)

    def peaks(share):
        damping = share * 2 * math.sqrt(K * M)
        return np.array([moving_load_deflection(xi, 1.0, v, K, EI, M, damping).max()
                         for v in speeds])

    light, lighter = peaks(0.01), peaks(0.005)
    assert speeds[int(np.argmax(light))] == pytest.approx(critical, rel=0.01)
    assert speeds[int(np.argmax(lighter))] == pytest.approx(critical, rel=0.005)
    # A resonance: the peak grows as the damping goes, as 1 / sqrt(damping) at the critical
    # speed (the load feeds a wave whose group velocity equals its own: Fryba, ch. 6).
    assert light.max() > 5 * point_deflection(0.0, 1.0, K, EI)
    assert lighter.max() / light.max() == pytest.approx(math.sqrt(2.0), rel=0.02)


def test_a_free_uniform_wall_rings_at_sqrt_k_over_m_and_decays_at_c_over_2m():
    dt = 1e-4
    wall = DynamicWall(K, EI, 0.005, M, DAMPING, dt)
    wall.z_re[0] = 1e-3
    w = []
    for _ in range(2000):
        wall.step([], [])
        w.append(wall.deflection([0.3])[0])
    w = np.array(w)
    t = dt * np.arange(1, len(w) + 1)
    omega, decay = ring_down(K, M, DAMPING)
    # Upward zero crossings, interpolated: the period.
    up = np.flatnonzero((w[:-1] < 0) & (w[1:] >= 0))
    crossings = t[up] - w[up + 1] * dt / (w[up + 1] - w[up])
    assert 2 * math.pi / np.diff(crossings).mean() == pytest.approx(omega, rel=1e-3)
    # The envelope: exactly the damped oscillator (the mode is stepped exactly).
    exact = 1e-3 * np.exp(-decay * t) * (np.cos(omega * t) + decay / omega * np.sin(omega * t))
    np.testing.assert_allclose(w, exact, atol=1e-9)


def test_the_energy_of_a_run_balances_the_work_of_the_loads():
    """Work in = energy held + dissipated, for a pulsing load and one that moves."""
    dt = 1e-4
    wall = DynamicWall(K, EI, 0.005, M, DAMPING, dt)
    for i in range(1, 3001):
        t = i * dt
        wall.step([1.0 + 0.5 * math.sin(2 * math.pi * 12 * t), 0.8],
                  [0.0, 0.011 + 0.02 * t])
    assert wall.work > 0
    assert wall.energy() + wall.dissipated == pytest.approx(wall.work, rel=2e-3)
    # Undamped, all the work is held (the work is taken at each step's mean load: second order
    # in dt over a run, 2e-4 of it here, 1.7e-2 at a step ten times as long).
    wall = DynamicWall(K, EI, 0.005, M, 0.0, dt)
    for i in range(1, 501):
        wall.step([1.0 + 0.5 * math.sin(2 * math.pi * 12 * i * dt)], [0.0])
    assert wall.energy() == pytest.approx(wall.work, rel=5e-4)


def test_a_massless_wall_is_the_quasi_static_wall():
    """Without mass no correction at all: the deflection is core.walls' closed form."""
    wall = DynamicWall(K, EI, 0.005, 0.0, 0.0, 1e-3)
    loads, at = [1.0, 0.6, 0.3], [0.0, 0.011, 0.025]
    wall.step(loads, at)
    x = np.linspace(-0.05, 0.08, 131)
    exact = sum(deflection(x - c, f, K, EI, 0.005) for f, c in zip(loads, at))
    assert np.array_equal(wall.correction(x), np.zeros_like(x))
    np.testing.assert_allclose(wall.deflection(x), exact, rtol=0, atol=1e-15)
    # And a very light, barely damped wall follows its loads as the quasi-static one does (its
    # modes overdamped, relaxing in c / K <= 0.1 ms; undamped, a load put on at once would set
    # it ringing about the quasi-static shape, as it should).
    light = DynamicWall(K, EI, 0.005, 1e-9, 1.0, 1e-3)
    for _ in range(3):
        light.step(loads, at)
    np.testing.assert_allclose(light.deflection(x), exact, atol=1e-6 * exact.max())


def test_a_massless_damped_wall_relaxes_to_the_quasi_static_one_at_k_over_c():
    """No mass, damping c: the uniform mode follows k w + c w_t = q, exactly."""
    dt = 2e-5
    wall = DynamicWall.of(SurfaceParams(foundation_stiffness=K, bending_stiffness=EI),
                          WallDynamicsParams(mass=0.0, damping=DAMPING), dt)
    wall.z_re[0] = 1e-3
    wall.v_re[0] = -K / DAMPING * 1e-3          # its rate, for the dissipation's first step
    for _ in range(50):
        wall.step([], [])
    assert wall.deflection([0.2])[0] == pytest.approx(1e-3 * math.exp(-K * 50 * dt / DAMPING))
    # Energy: what the foundation held went into its damping (trapezoid in time).
    assert wall.energy() + wall.dissipated == pytest.approx(K * 1e-3 ** 2, rel=3e-3)


def test_the_deflection_after_a_step_is_free_plus_compliance_times_the_held_loads():
    """The implicit coupling's linear map (what the contact solve uses) equals a real step."""
    wall = DynamicWall(K, EI, 0.005, M, DAMPING, 1e-3)
    for i in range(20):
        wall.step([0.7, 0.4 + 0.01 * i], [0.0, 0.012])
    x = np.array([0.001, 0.013, 0.03])
    loads = np.array([0.9, 0.5, 0.2])
    predicted = wall.free_deflection(x) + wall.compliance(x) @ loads
    wall.step(loads, x)
    np.testing.assert_allclose(wall.deflection(x), predicted, rtol=1e-10, atol=1e-15)
    g = wall.compliance(x)
    np.testing.assert_allclose(g, g.T)
    assert np.all(np.linalg.eigvalsh(g) > 0)


def test_the_propagator_is_the_oscillators_exact_step_at_any_stiffness():
    dt = 1e-3
    stiffness = np.array([1.0, 1e4, 1e8, 1e12])
    for damping in (0.0, 1.0, 2 * math.sqrt(1e4 * M), 1e6):
        phi = mode_propagator(stiffness, M, damping, dt)
        assert np.isfinite(phi).all()
        # Columns of exp(A dt) by a fine RK4 of the same oscillator, at K = 1e4.
        a = np.array([[0.0, 1.0], [-1e4 / M, -damping / M]])
        if damping > 1e3:
            continue
        state = np.eye(2)
        h = dt / 2000
        for _ in range(2000):
            k1 = a @ state
            k2 = a @ (state + h / 2 * k1)
            k3 = a @ (state + h / 2 * k2)
            k4 = a @ (state + h * k3)
            state = state + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        np.testing.assert_allclose(phi[:, 1], state.ravel(), rtol=1e-8, atol=1e-12)
        # Stable: no mode grows.
        for n in range(stiffness.size):
            assert np.abs(np.linalg.eigvals(phi[:, n].reshape(2, 2))).max() <= 1.0 + 1e-12


def test_walls_too_light_for_the_step_are_refused():
    with pytest.raises(ParameterError, match='at least 1e-06 kg/m'):
        WallDynamicsParams(mass=1e-300)
    assert WallDynamicsParams(mass=0.0).mass == 0.0


# -- in the simulator's step (swing_walls) -------------------------------------------------------
def test_massless_walls_in_the_step_are_the_quasi_static_walls():
    """
    Mass 0, or too light for the step to resolve any mode, steps as the quasi-static walls.

    In a batch with walls with mass every bending wall goes through the modes' solve: the
    massless one, and one of 1 g/m (its slowest mode rings at 420 Hz), follow the quasi-static
    step alone within 1e-6 m over 4 s (the issue's bound; 4e-15 m measured).
    """
    quasi = Scenario().with_values(TISSUE)
    light = quasi.with_values({'walls.mass': 1e-3, 'walls.damping': 0.1 * 2 * math.sqrt(K * 1e-3)})
    sim = Simulator([quasi, light, Scenario().with_values(TISSUE_WITH_MASS)])
    assert isinstance(sim.walls, DynamicWalls)
    assert list(sim.walls.resolved[:2]) == [0, 0] and sim.walls.resolved[2] > 50
    batch = sim.run(4.0, record_every=10)
    alone = Simulator(quasi)
    assert type(alone.walls) is Walls                 # no mass anywhere: today's kernel
    reference = alone.run(4.0, record_every=10)
    for s in (0, 1):
        assert np.abs(batch.q[:, s, :3] - reference.q[:, 0, :3]).max() <= 1e-6
    # The tissue's own mass does move the robot (the test can fail).
    assert np.abs(batch.q[:, 2, :2] - reference.q[:, 0, :2]).max() > 1e-4


@pytest.mark.parametrize('tolerance', [TOLERANCE, 1e-14])
def test_the_step_balances_the_dynamic_walls_with_the_contact_law(tolerance):
    """
    After a step the walls' shape (closed form + modes) is what the solve balanced.

    The walls take the forces the law put on the tips (what the body gets): their shape then
    differs from the solved deflection by the solve's residual, within its tolerance; solved
    a million times tighter, to 1e-12 m (the algebra of free + G F).
    """
    sim = Simulator(Scenario().with_values(TISSUE_WITH_MASS))
    sim.walls.constants[:, TOLERANCE_COLUMN] = tolerance
    sim.run(0.4)
    walls = sim.walls
    atol = max(10 * tolerance, 1e-12)
    shape = walls.shape_by_surface[0]
    n = walls.n
    for wall in range(2):
        count = int(walls.constants[0, SOLVED_COUNT + wall])
        assert count > 0
        chosen = walls.state[0, CHOSEN, wall, :count].astype(int)
        solved = walls.state[0, SOLVED, wall, chosen]
        np.testing.assert_allclose(shape[wall, chosen], solved, rtol=0, atol=atol)
        p = wall * n + chosen
        np.testing.assert_allclose(sim.depth[0, p], sim.penetration[0, p] - solved, rtol=0,
                                   atol=1e-15)
        # The tips not solved for are clear of the moving wall (no contact missed).
        others = np.setdiff1d(np.arange(n), chosen)
        assert (sim.penetration[0, wall * n + others] - shape[wall, others] < 0).all()
    # The modes carry a correction of their own: the wall is not the quasi-static one.
    quasi = Walls.shape(walls, sim.tip_positions.real, np.linspace(-0.2, 0.4, 61))
    full = walls.shape(sim.tip_positions.real, np.linspace(-0.2, 0.4, 61))
    assert np.abs(full - quasi).max() > 1e-2 * np.abs(quasi).max()


def test_the_walls_share_beyond_the_quasi_static_shape_falls_with_their_mass():
    """
    The modes' share of the walls' shape (beside the closed form of the same loads) over a run.

    A tenth of critical damping at every mass: the share falls with the mass and is none once
    the step resolves no mode (1.3 g/m); the quasi-static shape stays about the same.
    """
    along = np.linspace(-0.3, 0.5, 161)
    shares, resolved = [], []
    for mass in (1.3, 0.13, 0.013, 0.0013):
        sim = Simulator(Scenario().with_values({**TISSUE, 'walls.mass': mass,
                                                'walls.damping': 0.2 * math.sqrt(K * mass)}))
        share = quasi = 0.0
        for _ in range(6):
            sim.run(0.1)
            full = sim.walls.shape(sim.tip_positions.real, along)
            static = Walls.shape(sim.walls, sim.tip_positions.real, along)
            share = max(share, np.abs(full - static).max())
            quasi = max(quasi, np.abs(static).max())
        assert quasi > 5e-3                           # the robot presses the walls
        shares.append(share / quasi)
        resolved.append(int(sim.walls.resolved[0]))
    assert shares[0] > 3 * shares[1] > 0 and shares[1] > shares[2] > 0
    assert resolved[-1] == 0 and shares[-1] == 0.0


def test_a_batch_with_walls_with_mass_equals_each_run_alone():
    """Four scenarios in one parallel call (the modes are each scenario's own): as alone."""
    masses_slopes = [(M, 0.0), (10 * M, 0.3), (0.0, 0.1), (0.05, 0.0)]
    scenarios = [Scenario().with_values({**TISSUE, 'walls.mass': m, 'conditions.slope': a,
                                         'walls.damping': 0.2 * math.sqrt(K * m)})
                 for m, a in masses_slopes]
    batch = Simulator(scenarios).run(1.0, record_every=100)
    for i, scenario in enumerate(scenarios):
        alone = Simulator(scenario).run(1.0, record_every=100)
        # (the massless one goes through the modes in the batch, the quasi-static solve alone)
        np.testing.assert_allclose(batch.q[:, i], alone.q[:, 0], rtol=0, atol=1e-12)


def test_new_parameters_mid_run_keep_the_walls_with_mass_moving():
    """
    Parameters set while a run goes on (the node's ros2 param set) rebuild the walls.

    The same parameters: the run goes on as if nothing happened. Other walls: they start at
    rest in the quasi-static shape of the last loads, not flat (flat, the robot drops into them:
    here fifteen times the change of the state over the next 50 ms).
    """
    scenario = Scenario().with_values(TISSUE_WITH_MASS)
    other = scenario.with_values({'walls.damping': 1.01 * DAMPING})
    runs = [Simulator(scenario) for _ in range(4)]
    for sim in runs:
        sim.run(0.5)
    runs[1].set_scenarios([scenario])
    runs[2].set_scenarios([other])
    runs[3].set_scenarios([other])
    runs[3].walls.modes[:, WALL_STATE:] = 0.0           # as if from flat
    for sim in runs:
        sim.run(0.05)
    assert np.array_equal(runs[1].q, runs[0].q)
    carried, flat = (np.abs(sim.q - runs[0].q).max() for sim in runs[2:])
    assert 0.0 < carried < 0.1 * flat


@pytest.mark.parametrize('name, value', [('walls.mass', -1e-9), ('walls.mass', 100.000001),
                                         ('walls.damping', -1e-9), ('walls.damping', 1.000001e6),
                                         ('walls.mass', 1e-7)])
def test_wall_dynamics_past_their_ranges_are_refused_in_one_line(name, value):
    with pytest.raises(ParameterError) as refused:
        Scenario().with_values({**TISSUE, name: value})
    assert name in str(refused.value) and '\n' not in str(refused.value)


@pytest.mark.parametrize('mass, damping', [(100.0, 0.0), (100.0, 1e6), (1e-6, 0.0), (0.0, 1e6)])
def test_the_ends_of_the_wall_dynamics_ranges_step(mass, damping):
    """The heaviest, most damped and lightest walls the ranges allow step stably, 0.3 s."""
    sim = Simulator(Scenario().with_values({**TISSUE, 'walls.mass': mass,
                                            'walls.damping': damping}))
    sim.run(0.3)
    assert np.isfinite(sim.q).all() and sim.walls.unconverged == 0
