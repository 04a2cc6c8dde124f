"""Flexures on bending walls (issue 31): one solve of walls, links and contact law."""
import math

import numpy as np
import pytest

from saw_ros.core.contact import EXPONENT, KN_HALF, KN_MEAN, KN_RATE, LAW_FIELDS, NORMAL
from saw_ros.core.contact import PENETRATION, SEEN, TIP_FIELDS
from saw_ros.core.dynamic_walls import DynamicWalls, TABLE
from saw_ros.core.dynamics import Simulator
from saw_ros.core.flexure import balance_link, contact_law, FLEX_COMPLIANCE, flex_walls
from saw_ros.core.flexure import FLEX_ROWS, FLEX_WORK_ROWS, flexure_constants
from saw_ros.core.params import FlexureParams, Scenario
from saw_ros.core.walls import CHOSEN, GAIN, ITSELF, PATCH_IM, PATCH_RE, SOLVED, SOLVED_COUNT
from saw_ros.core.walls import LOADS, TOLERANCE_COLUMN, Walls

# The silicone sheet and the stiffest walls the ranges allow (saw_ros/bench/walls.py's SHEET,
# STIFFEST), the tissue with its mass (docs/walls.md).
SHEET = {'surface.foundation_stiffness': 1.5e5, 'surface.bending_stiffness': 6.25e-4}
STIFFEST = {'surface.foundation_stiffness': 1e10, 'surface.bending_stiffness': 1e4}
TISSUE_WITH_MASS = {'surface.foundation_stiffness': 9e3, 'surface.bending_stiffness': 1.2e-5,
                    'walls.mass': 0.13, 'walls.damping': 6.8}
TPU = {'flexure.stiffness': 2000.0, 'flexure.damping': 0.5}              # lightly damped
DAMPED = {'flexure.stiffness': 863.0, 'flexure.damping': 2.6}    # docs/compliant_robot.md's


def deviation(a, b, duration=4.0):
    """Run two simulators side by side: the largest difference of their poses (m, rad)."""
    worst = 0.0
    for _ in range(int(round(duration / 0.1))):
        a.run(0.1)
        b.run(0.1)
        worst = max(worst, float(np.abs(a.q[:3] - b.q[:3]).max()))
    return worst


def test_stiff_flexures_on_the_sheet_follow_the_bending_walls_step():
    """1e9 N/m links on the silicone sheet: today's bending-walls step within 1e-6 m over 4 s."""
    sheet = Simulator(Scenario().with_values(SHEET))
    stiff = Simulator(Scenario().with_values({**SHEET, 'flexure.stiffness': 1e9}))
    assert deviation(sheet, stiff) < 1e-6
    assert stiff.walls.unconverged == 0
    # The sheet itself moves the robot (the comparison can fail).
    rigid = Simulator(Scenario())
    rigid.run(4.0)
    assert abs(rigid.q[0, 0] - stiff.q[0, 0]) > 1e-4


def test_flexures_on_the_stiffest_walls_follow_the_rigid_walls_step():
    """
    A compliant robot on the stiffest walls follows it on rigid walls within 1e-6 m over 4 s.

    The damped flexure of docs/compliant_robot.md (1e-7 m measured). A lightly damped one (the
    TPU set, damping ratio 0.09) passes on differences: the walls' own give, 5 nm under a 5 N
    tip, moves it by 5e-6 to 3e-5 m over 4 s, as a nanometre of gap moves it on rigid walls by
    2.5e-7 m. With the walls' compliance taken out, the coupled solve is the rigid walls' link
    solve, to rounding amplified so (6e-10 m measured).
    """
    rigid = Simulator(Scenario().with_values(DAMPED))
    stiffest = Simulator(Scenario().with_values({**STIFFEST, **DAMPED}))
    assert deviation(rigid, stiffest) < 1e-6
    rigid = Simulator(Scenario().with_values(TPU))
    unyielding = Simulator(Scenario().with_values({**STIFFEST, **TPU}))
    unyielding.walls.constants[:, [GAIN, ITSELF, PATCH_RE, PATCH_IM]] = 0.0
    unyielding.walls.constants[:, TOLERANCE_COLUMN] = 1e-12
    assert deviation(rigid, unyielding) < 1e-8
    assert np.abs(unyielding.deflection).max() > 1e-4             # the links did deflect


@pytest.mark.parametrize('walls', [SHEET, TISSUE_WITH_MASS], ids=['sheet', 'tissue with mass'])
def test_the_step_ends_with_walls_flexures_and_contact_law_agreeing(walls):
    """
    After a step: the depth the law saw is the penetration less the wall less the flexure.

    Solved tight (1e-14), the walls' shape under the law's forces is the solved deflection
    (the algebra of the solve, to 1e-12 m), each link's deflection carries its tips' net load,
    and no tip left out of the solve touches its wall.
    """
    sim = Simulator(Scenario().with_values({**walls, **TPU}))
    sim.walls.constants[:, TOLERANCE_COLUMN] = 1e-14
    sim.run(0.4)
    n = sim.walls.n
    shape = sim.walls.shape_by_surface[0]
    e = sim.deflection[0]
    flex = sim._flex_state[0]
    np.testing.assert_allclose(flex[2], sim.tips[0, NORMAL, :n] - sim.tips[0, NORMAL, n:],
                               rtol=0, atol=1e-12)
    assert np.abs(e).max() > 1e-4
    touching = 0
    for wall, sign in ((0, 1.0), (1, -1.0)):
        count = int(sim.walls.constants[0, SOLVED_COUNT + wall])
        chosen = sim.walls.state[0, CHOSEN, wall, :count].astype(int)
        solved = sim.walls.state[0, SOLVED, wall, chosen]
        np.testing.assert_allclose(shape[wall, chosen], solved, rtol=0, atol=1e-12)
        p = wall * n + chosen
        np.testing.assert_allclose(sim.depth[0, p],
                                   sim.penetration[0, p] - solved - sign * e[chosen],
                                   rtol=0, atol=1e-15)
        others = np.setdiff1d(np.arange(n), chosen)
        q = wall * n + others
        assert (sim.penetration[0, q] - shape[wall, others] - sign * e[others] < 0).all()
        touching += int((sim.depth[0, p] > 0).sum())
    assert touching >= 2


def test_a_compliant_robot_crawls_between_bending_walls():
    """Flexures on the sheet and on the tissue with mass: both crawl, the walls and links give."""
    scenarios = [Scenario().with_values({**walls, **DAMPED})
                 for walls in (SHEET, TISSUE_WITH_MASS)]
    sim = Simulator(scenarios)
    run = sim.run(2.0, record_every=10)
    assert (np.abs(run.q[-1, :, 0] - run.q[0, :, 0]) > 0.05).all()
    assert (np.abs(sim.deflection).max(axis=1) > 1e-4).all()
    assert (sim.walls.largest > 1e-4).all()
    assert math.isfinite(float(run.q[-1].sum()))


@pytest.mark.parametrize('yielding', [False, True], ids=['unyielding', 'sheet'])
def test_a_link_pressed_into_both_walls_balances_its_flexure_and_both_walls(yielding):
    """
    One link, both tips in their walls (the flexure's -C between them): the kernel alone.

    Unyielding walls (their compliance taken out): the rigid walls' link solve
    (flexure.balance_link). The sheet: each tip's depth is its penetration less its wall's
    give under its own load less the link's deflection C (F_bottom - F_top), the law's forces.
    """
    scenario = Scenario().with_values(SHEET)
    walls = Walls([scenario], np.array([-1.0, 1.0]))
    constants = walls.constants[0]
    if not yielding:
        constants[[GAIN, ITSELF, PATCH_RE, PATCH_IM]] = 0.0
    constants[TOLERANCE_COLUMN] = 1e-14
    law4 = contact_law(scenario.surface, 1e-3)
    law = np.zeros(LAW_FIELDS)
    law[[KN_MEAN, KN_HALF, KN_RATE, EXPONENT]] = law4
    flex = flexure_constants([FlexureParams(stiffness=2000.0, damping=0.5, link_mass=0.004)],
                             1e-3)[0]
    tips = np.zeros((TIP_FIELDS, 2))
    tips[PENETRATION] = tips[SEEN] = [2e-3, 3e-3]
    flex_walls(law, constants, walls.state[0], np.zeros((TABLE + 4, 1)), False, flex,
               np.zeros((FLEX_ROWS, 1)), tips, np.empty((FLEX_WORK_ROWS + 4, 2)))
    assert [constants[SOLVED_COUNT], constants[SOLVED_COUNT + 1]] == [1, 1]
    force = walls.state[0, LOADS, :, 0]                            # bottom, top
    c = flex[FLEX_COMPLIANCE]
    e = c * (force[0] - force[1])
    give = constants[ITSELF] * force
    np.testing.assert_allclose(tips[SEEN], [2e-3 - give[0] - e, 3e-3 - give[1] + e],
                               rtol=0, atol=1e-15)
    kn, p = law4[0] + law4[1], law4[3]
    np.testing.assert_allclose(force, kn * tips[SEEN] ** p, rtol=1e-12)
    assert force.min() > 0.1 and abs(e) > 1e-5
    if not yielding:
        e_link, fb, ft = balance_link(2e-3, 3e-3, 0.0, 0.0, 0.0, c, law4)
        np.testing.assert_allclose([e, force[0], force[1]], [e_link, fb, ft], rtol=1e-9)


def test_flexures_on_massless_walls_in_a_batch_with_mass_are_the_quasi_static_ones():
    """
    Massless walls with flexures, on the modes' path, are the quasi-static walls' step.

    In a batch with walls with mass every wall takes the modes' path of ``flex_walls``: the
    massless tissue with flexures follows the quasi-static walls with them within 1e-6 m over
    4 s.
    """
    tissue = {key: value for key, value in TISSUE_WITH_MASS.items()
              if key.startswith('surface.')}
    quasi = Scenario().with_values({**tissue, **DAMPED})
    batch = Simulator([quasi, Scenario().with_values({**TISSUE_WITH_MASS, **DAMPED})])
    assert isinstance(batch.walls, DynamicWalls)
    alone = Simulator(quasi)
    assert type(alone.walls) is Walls
    reference = alone.run(4.0, record_every=10)
    run = batch.run(4.0, record_every=10)
    assert np.abs(run.q[:, 0, :3] - reference.q[:, 0, :3]).max() <= 1e-6
    assert np.abs(run.q[:, 1, :2] - reference.q[:, 0, :2]).max() > 1e-4     # mass matters
