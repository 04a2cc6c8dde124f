"""Walls that bend (issue 23): closed forms, limits, the coupling, and rigid walls unchanged."""
import math

import numpy as np
import pytest

from saw_ros.core import walls as walls_module
from saw_ros.core.dynamics import DivergenceError, Simulator
from saw_ros.core.params import ParameterError, Scenario
from saw_ros.core.walls import decay, DECAY_END, DECAY_ERROR, deflection
from saw_ros.core.walls import finite_difference_deflection, point_deflection, solve_in_place
from saw_ros.core.walls import TOLERANCE, Walls

K, EI, B = 1.5e5, 6.25e-4, 0.005          # the silicone sheet of docs/walls.md
SHEET = Scenario().with_values({'surface.foundation_stiffness': K,
                                'surface.bending_stiffness': EI})
TISSUE = Scenario().with_values({'surface.foundation_stiffness': 9e3,       # docs/walls.md
                                 'surface.bending_stiffness': 1.2e-5})


def table_bound(gaps, foundation=K, width=B):
    """Return how far (m/N) a compliance across ``gaps`` gaps may be from the closed form."""
    return 2.0 * gaps * DECAY_ERROR / (2.0 * foundation * width)      # walls.DECAY_ERROR's note


def test_the_tabled_decay_is_within_its_stated_error_and_exact_past_the_table():
    u = np.linspace(0.0, DECAY_END + 2.0, 36_001)
    exact = np.exp(-u) * np.exp(1j * u)
    tabled = np.array([complex(*decay(x)) for x in u])
    error = np.abs(tabled - exact) / np.exp(-u)
    assert error.max() <= DECAY_ERROR
    assert error.max() > 0.5 * DECAY_ERROR                  # the bound is the error's size
    assert error[u >= DECAY_END].max() < 1e-15              # computed there
    assert np.isnan(decay(math.nan)).all()


def test_the_unpivoted_elimination_solves_the_walls_newton_systems():
    """I + G S, G a wall's compliance and S >= 0 the law's slopes: pivots >= 1, no pivoting."""
    walls = Walls([SHEET], Simulator(SHEET).table.side)
    rng = np.random.default_rng(5)
    for count in range(1, 9):
        x = np.sort(rng.uniform(-0.05, 0.05, count))
        g = walls.compliance(x[None, None, :])[0, 0]
        slopes = rng.uniform(0.0, 1e5, count) * (rng.uniform(size=count) > 0.2)  # some free
        a = np.eye(count) + g * slopes[None, :]
        b = rng.normal(size=count)
        y = b.copy()
        solve_in_place(a.copy(), y, count)
        np.testing.assert_allclose(a @ y, b, rtol=0.0, atol=1e-12 * np.abs(b).max())


def test_a_narrow_patch_is_hetenyis_point_load():
    r = np.linspace(0.0, 0.08, 400)
    narrow = deflection(r, 2.0, K, EI, 1e-6)
    exact = point_deflection(r, 2.0, K, EI)
    # Hetenyi: w(0) = P beta / 2k, and the uplift beyond 3 pi / (4 beta).
    beta = (K / (4 * EI)) ** 0.25
    assert exact[0] == pytest.approx(2.0 * beta / (2 * K))
    assert exact[r > 3 * math.pi / (4 * beta) + 1e-3].min() < 0.0
    np.testing.assert_allclose(narrow, exact, atol=1e-9 * exact.max())


def test_the_patch_formula_is_the_point_load_integrated_over_the_patch():
    r = np.array([0.0, 0.001, 0.0024, 0.003, 0.01, 0.03])
    s = np.linspace(-B / 2, B / 2, 20001)
    quadrature = [np.trapezoid(point_deflection(x - s, 1.0 / B, K, EI), s) for x in r]
    np.testing.assert_allclose(deflection(r, 1.0, K, EI, B), quadrature, rtol=1e-6)


def test_finite_differences_converge_to_the_closed_form_for_several_loads():
    loads, at = [1.0, 0.6, 0.3], [0.0, 0.011, 0.025]
    errors = []
    # (a dense solve: h = 5e-5 alone took 8 s of CPU for a smaller error than this one asks)
    for h in (4e-4, 2e-4, 1e-4):
        x, w = finite_difference_deflection(loads, at, K, EI, B, 0.4, h)
        exact = sum(deflection(x - c, f, K, EI, B) for f, c in zip(loads, at))
        errors.append(np.abs(w - exact).max() / exact.max())
    assert errors[0] > errors[1] > errors[2]
    assert errors[-1] < 1e-5


def test_the_finite_differences_hold_a_simply_supported_span():
    """P L^3 / (48 EI) at the centre of a span without foundation; second order in h."""
    span, load = 0.2, 1.0
    exact = load * span ** 3 / (48 * EI)
    errors = []
    for h in (4e-3, 2e-3, 1e-3):
        x, w = finite_difference_deflection([load], [0.0], 0.0, EI, h / 2, span, h, 'simple')
        errors.append(abs(w[len(x) // 2] - exact) / exact)
    assert errors[-1] < 1e-4
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.1)
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.1)


def test_compliance_is_superposition_and_symmetric():
    walls = Walls([SHEET], Simulator(SHEET).table.side)
    n = walls.n
    x = np.concatenate([np.linspace(0.0, 0.2, n), np.linspace(0.003, 0.2, n)])[None, :]
    g = walls.compliance(x)
    np.testing.assert_allclose(g, np.swapaxes(g, -1, -2), rtol=1e-12)  # Betti's reciprocity
    forces = np.linspace(0.5, 2.0, n)
    expected = sum(deflection(x[0, :n] - x[0, j], forces[j], K, EI, B) for j in range(n))
    np.testing.assert_allclose(g[0, 0] @ forces, expected, rtol=0.0,
                               atol=table_bound(n - 1) * forces.sum())
    assert np.all(np.linalg.eigvalsh(g[0, 0]) > 0.0)          # elastic: energy stored > 0


def test_the_compliance_is_one_matrix_whatever_the_order_of_the_tips():
    """Tips in their order along a wall (a decay per gap) or not (a decay per pair): one G."""
    walls = Walls([SHEET], Simulator(SHEET).table.side)
    rng = np.random.default_rng(3)
    along = np.sort(rng.uniform(-0.1, 0.1, 8))
    along[3] = along[2] + 0.001                             # two tips under one patch
    exact = deflection(along[:, None] - along[None, :], 1.0, K, EI, B)
    for order in (np.arange(8), np.arange(8)[::-1], rng.permutation(8)):
        g = walls.compliance(along[order][None, None, :])[0, 0]
        np.testing.assert_allclose(g, exact[np.ix_(order, order)], rtol=0.0,
                                   atol=table_bound(7))


def test_a_patch_far_wider_than_the_decay_length_keeps_its_compliance_finite():
    # beta b/2 near 1000: exp(beta b/2) overflows, the pairs are taken one by one.
    wide = Scenario().with_values({'surface.foundation_stiffness': 1e10,
                                   'surface.bending_stiffness': 1e-9,
                                   'surface.contact_width': 0.05})
    s = wide.surface
    walls = Walls([wide], Simulator(wide).table.side)
    along = np.array([0.0, 0.01, 0.0249, 0.0251, 0.06])
    g = walls.compliance(along[None, None, :])[0, 0]
    exact = deflection(along[:, None] - along[None, :], 1.0, s.foundation_stiffness,
                       s.bending_stiffness, s.contact_width)
    assert np.isfinite(g).all()
    np.testing.assert_allclose(g, exact, rtol=0.0,
                               atol=table_bound(1, s.foundation_stiffness, s.contact_width))


def test_a_foundation_alone_is_a_spring_of_k_times_the_contact_width():
    tiny = 1e-12
    w0 = deflection(0.0, 1.0, K, tiny, B)
    assert 1.0 / w0 == pytest.approx(K * B, rel=1e-6)
    assert deflection(0.02, 1.0, K, tiny, B) == pytest.approx(0.0, abs=1e-12)


def test_stored_energy_is_the_work_of_the_loads_along_any_path():
    """A conservative wall: the work of loading equals 1/2 F.G.F, whatever the order."""
    walls = Walls([SHEET], Simulator(SHEET).table.side)
    x = np.concatenate([np.arange(walls.n) * 0.011, np.arange(walls.n) * 0.011])[None, :]
    g = walls.compliance(x)[0, 0]
    final = np.zeros(walls.n)
    final[[3, 4, 6]] = [2.0, 1.0, 0.5]
    stored = 0.5 * final @ g @ final

    def work(path):
        total, steps = 0.0, 2000
        for a, b in zip(path[:-1], path[1:]):
            for s in range(steps):
                f = a + (b - a) * (s + 0.5) / steps
                total += f @ g @ ((b - a) / steps)
        return total
    together = work([np.zeros(walls.n), final])
    one_by_one = [np.zeros(walls.n)]
    for i in (6, 3, 4):
        nxt = one_by_one[-1].copy()
        nxt[i] = final[i]
        one_by_one.append(nxt)
    assert together == pytest.approx(stored, rel=1e-9)
    assert work(one_by_one) == pytest.approx(stored, rel=1e-9)


@pytest.mark.parametrize('walls', [SHEET, TISSUE], ids=['sheet', 'tissue'])
def test_the_coupled_step_balances_the_walls_with_the_contact_law(walls):
    sim = Simulator(walls)
    worst = 0.0
    for _ in range(1500):
        sim.step()
        x, loads, solved = sim._x.ravel(), sim.contacts.normal.ravel(), sim.walls.solved.ravel()
        for tips in sim.walls.solved_tips:                  # those each wall solved for
            g = sim.walls.compliance(x[tips][None, None, :])[0, 0]
            worst = max(worst, np.abs(g @ loads[tips] - solved[tips]).max(initial=0.0))
    assert worst < TOLERANCE                                # m, against mm deflections
    assert sim.walls.unconverged == 0
    assert sim.walls.deflection.max() > 5e-4                # the walls did bend


def test_the_solver_tolerance_moves_the_robot_far_less_than_the_time_step_does():
    def poses(tolerance, dt=0.001):
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(walls_module, 'TOLERANCE', tolerance)
            sim = Simulator(SHEET.with_values({'integration.dt': dt}))
            every = int(round(0.001 / dt))
            out = []
            for k in range(int(round(1.5 / dt))):
                sim.step()
                if (k + 1) % every == 0:
                    out.append(sim.q[:3, 0].copy())
        return np.array(out)

    reference = poses(TOLERANCE / 100.0)
    solver = np.abs(poses(TOLERANCE) - reference).max()
    time_step = np.abs(poses(TOLERANCE / 100.0, dt=0.0005) - reference).max()
    assert solver < time_step / 100.0


def test_rigid_walls_are_the_default_and_untouched():
    assert Scenario().surface.foundation_stiffness == 0.0
    plain = Simulator(Scenario())
    other = Simulator(Scenario().with_values({'surface.bending_stiffness': 3.0,
                                              'surface.contact_width': 0.01}))
    assert plain.walls is None and other.walls is None
    for _ in range(1500):
        plain.step()
        other.step()
    assert np.array_equal(plain.q, other.q)                  # bit for bit


def test_very_stiff_walls_are_the_rigid_ones():
    rigid = Simulator(Scenario())
    stiff = Simulator(Scenario().with_values({'surface.foundation_stiffness': 1e10,
                                              'surface.bending_stiffness': 1e4}))
    worst = 0.0
    for _ in range(2000):
        rigid.step()
        stiff.step()
        worst = max(worst, np.abs(rigid.q[:3] - stiff.q[:3]).max())
    assert worst < 1e-6


def test_soft_walls_give_way_and_the_depth_stays_below_its_limit():
    tissue = TISSUE
    sim = Simulator(tissue)
    for _ in range(3000):
        sim.step()
    assert sim.walls.deflection.max() > 5e-3                # walls pushed centimetre-wide
    assert sim.depth.max() < tissue.surface.max_penetration
    assert np.isfinite(sim.q).all()


@pytest.mark.parametrize('name, value', [('surface.foundation_stiffness', -1.0),
                                         ('surface.bending_stiffness', 0.0),
                                         ('surface.contact_width', 0.0),
                                         ('surface.contact_width', 0.06)])
def test_wall_parameters_out_of_range_are_refused(name, value):
    with pytest.raises(ParameterError, match=name.split('.')[1]):
        Scenario().with_values({name: value})


def test_over_a_run_the_work_done_on_the_walls_is_the_energy_they_store():
    # A quasi-static elastic wall neither makes nor loses energy: the work of the tips' loads
    # on it, F . dw at the tips (the shape's change between steps, where the tips are now),
    # sums to the energy 1/2 F . w it holds at the end (none at the start).
    s = SHEET.surface
    sim = Simulator(SHEET)
    side = np.where(sim.table.side > 0, 1, 0)

    def field(at, x, loads):
        """Return the deflection at ``at`` under ``loads`` at ``x`` (same surface only)."""
        same = side[:, None] == side[None, :]
        g = deflection(at[:, None] - x[None, :], 1.0, s.foundation_stiffness,
                       s.bending_stiffness, s.contact_width) * same
        return g @ loads

    x0, f0 = sim._x[0].copy(), np.zeros(sim.table.count)
    work, done = 0.0, 0.0
    for _ in range(1500):
        sim.step()
        x1, f1 = sim._x[0].copy(), sim.contacts.normal[0].copy()
        change = field(x1, x1, f1) - field(x1, x0, f0)
        step_work = 0.5 * (f0 + f1) @ change
        work += step_work
        done += abs(step_work)
        x0, f0 = x1, f1
    stored = 0.5 * f0 @ field(x0, x0, f0)
    assert stored > 1e-3                                      # J: the walls hold some
    assert abs(work - stored) < 2e-3 * done                   # of all the work done on them


def test_the_published_shape_is_the_deflection_under_the_tips():
    sim = Simulator(SHEET)
    for _ in range(300):
        sim.step()
    tips = sim._x[0]
    shape = sim.walls.shape(sim._x, np.sort(tips))[0]         # (2, P) sampled where tips are
    order = np.argsort(tips)
    under = sim.walls.deflection[0][order]                      # each tip on its own wall
    side = sim.table.side[order]
    # (the simulation's compliance from the tabled decays, the shape's from numpy's exp)
    bound = table_bound(sim.walls.n - 1) * sim.walls.forces[0].sum(axis=1).max()
    assert shape[0][side < 0] == pytest.approx(under[side < 0], abs=bound)
    assert shape[1][side > 0] == pytest.approx(under[side > 0], abs=bound)
    assert shape.max() > 5e-4


def test_walls_too_soft_to_hold_the_robot_are_refused_with_the_reason():
    # 100 N/m^2 and almost no bending stiffness: the linear wall would give way by a metre.
    sim = Simulator(Scenario().with_values({'surface.foundation_stiffness': 100.0,
                                            'surface.bending_stiffness': 1e-9}))
    with pytest.raises(DivergenceError, match=r'a wall gave way by \d+ mm, more than the gap '
                                              r'of 45 mm: walls this soft do not hold'):
        for _ in range(2000):
            sim.step()
    assert sim.walls.largest.max() <= 2 * 0.045          # refused as soon as it went past
