"""The design study (analysis.design, saw-ros design): fronts, the paper's row, refused designs."""
import csv
import itertools
import math

import numpy as np
import pytest

from saw_ros.analysis import design
from saw_ros.cli.main import main
from saw_ros.core.dynamics import Simulator
from saw_ros.core.kinematics import v_theory
from saw_ros.core.params import GRAVITY, Scenario
from saw_ros.core.pool import LocalPool

BASE = Scenario().with_values({'motor.voltage': 6.0})
SETTLE, MEASURE = 0.5, 0.5


def brute_force_front(points):
    return [not any(design.dominates(q, p) for q in points) for p in points]


def test_pareto_front_of_a_known_set():
    # (speed, cost): (3, 3) is dominated by (3, 2); (1, 1) and (4, 4) are ends of the front;
    # the two equal points (2, 1.5) stay on it together; (2, 5) is dominated by (4, 4).
    points = [(1, 1), (2, 1.5), (2, 1.5), (3, 2), (3, 3), (4, 4), (2, 5)]
    mask = design.pareto_front(*zip(*points))
    assert mask.tolist() == [True, True, True, True, False, True, False]


def test_pareto_front_against_brute_force():
    rng = np.random.default_rng(7)
    for _ in range(20):
        # Integers: ties in speed, in cost and whole equal points are common.
        points = [tuple(p) for p in rng.integers(0, 8, size=(40, 2)).astype(float)]
        mask = design.pareto_front(*zip(*points))
        assert mask.tolist() == brute_force_front(points)


def test_latin_hypercube_has_one_point_per_stratum():
    unit = design.latin_hypercube(11, 5, seed=3)
    for column in unit.T:
        assert sorted(np.floor(column * 11).astype(int)) == list(range(11))
    assert ((unit >= 0) & (unit < 1)).all()


def test_grid_crosses_every_level():
    designs = design.draw('grid', 2)
    assert len(designs) == 2 ** 4
    assert all(f == (300.0, 1e5) for _, f in designs)
    assert {g['robot.wave_links'] for g, _ in designs} == {10.0, 26.0}


def direct(scenario, settle, measure):
    """Speed, power, vibration of one scenario from Simulator.run's record, by hand."""
    sim = Simulator(scenario)
    trajectory = sim.run(settle + measure)
    first = int(round(settle / sim.dt))
    vx = trajectory.q[first + 1:, 0, 3]
    vy = trajectory.q[first:, 0, 4]
    accel = np.diff(vy) / sim.dt
    power = scenario.motor.voltage * trajectory.current[first + 1:, 0]
    omega = trajectory.omega[first + 1:, 0]
    return (vx.mean(), power.mean(), np.sqrt(((accel - accel.mean()) ** 2).mean()),
            omega.mean() / (2 * math.pi))


def test_the_paper_row_equals_a_direct_simulation():
    study = design.run_study(BASE, 'lhs', 1, walls=('rigid', 'tissue'), settle=SETTLE,
                             measure=MEASURE)
    for wall in ('rigid', 'tissue'):
        row = study.paper(wall)
        assert row.ok and row.geometry == design.paper_geometry() and row.flexure == 0.0
        scenario = design.wall_scenario(BASE, wall, row.geometry, 0.0, 0.004)
        speed, power, vibration, helix = direct(scenario, SETTLE, MEASURE)
        assert row.speed == pytest.approx(speed, rel=1e-9)
        assert row.power == pytest.approx(power, rel=1e-9)
        assert row.vibration == pytest.approx(vibration, rel=1e-9)
        assert row.advance_ratio == pytest.approx(speed / v_theory(scenario.robot, helix),
                                                  rel=1e-9)
        assert row.cost_of_transport == pytest.approx(power / (0.313 * GRAVITY * speed),
                                                      rel=1e-9)
    # The walls are the study's: the tissue gives way and the robot's speed changes.
    assert study.paper('tissue').speed != pytest.approx(study.paper('rigid').speed, rel=1e-3)
    # Design 1 with its flexure on the rigid walls and on the tissue (flexures on bending
    # walls run: core.flexure.flex_walls).
    flexed = [r for r in study.runs if r.design == 1 and r.flexure > 0.0]
    assert [r.wall for r in flexed] == ['rigid', 'tissue']
    assert all(r.status != 'not modelled' for r in study.runs)
    # The paper's robot on flexures on the tissue: its row is the direct simulation's.
    paper = design.paper_geometry()
    rigid_links, flexed = design.run_geometry((0, paper, (2000.0,), BASE, ('tissue',), SETTLE,
                                               MEASURE, True))
    assert flexed.ok and flexed.flexure == 2000.0
    scenario = design.wall_scenario(BASE, 'tissue', paper, 2000.0, 0.004)
    assert flexed.speed == pytest.approx(direct(scenario, SETTLE, MEASURE)[0], rel=1e-9)
    assert flexed.speed != pytest.approx(rigid_links.speed, rel=1e-3)


def statuses(runs):
    return {(r.wall, r.flexure > 0.0): r for r in runs}


def test_designs_the_model_cannot_run_are_reported_without_numbers(tmp_path):
    paper = design.paper_geometry()
    collide = dict(paper, **{'robot.amplitude': 0.0195, 'robot.wavelength': 0.085,
                             'robot.tip_distance': 0.012})
    too_many = dict(paper, **{'robot.wave_links': 30.0})
    cases = [(collide, BASE, 'links collide', 'links interfere'),
             (too_many, BASE, 'infeasible', 'do not fit'),
             # A friction torque above the motor's stall torque at 6 V (0.50 N m).
             (paper, BASE.with_values({'motor.friction_torque': 0.8}), 'stalled',
              'the motor stalled')]
    runs = []
    for i, (geometry, base, status, why) in enumerate(cases, start=1):
        done = design.run_geometry((i, geometry, (2000.0,), base, ('rigid', 'sheet'), SETTLE,
                                    MEASURE, False))
        runs += done
        by = statuses(done)
        for key in (('rigid', False), ('rigid', True), ('sheet', False), ('sheet', True)):
            run = by[key]
            assert run.status == status and why in run.reason, (key, run.reason)
            assert all(math.isnan(getattr(run, f)) for f in (
                'speed', 'advance_ratio', 'power', 'cost_of_transport', 'vibration'))
    study = design.Study(runs, 'lhs', 3, 1, ('rigid', 'sheet'), SETTLE, MEASURE, 6.0)
    paths = design.write_outputs(study, tmp_path)
    rows = list(csv.DictReader(paths['csv'].open()))
    assert len(rows) == len(runs)
    for row in rows:
        assert row['status'] != 'ok' and row['reason']
        assert row['speed_m_per_s'] == row['cost_of_transport'] == row['vibration_m_per_s2'] == ''
    text = paths['summary'].read_text()
    assert 'nan' not in text.lower() and '**stalled**' in text and '**links collide**' in text
    assert "the paper's robot has no figures here (it was not run)" in text


def test_the_command_writes_every_output(tmp_path, capsys):
    out = tmp_path / 'study'
    code = main(['design', '--size', '2', '--walls', 'rigid,sheet', '--settle-s', '0.5',
                 '--measure-s', '1', '--workers', '1', '--quiet', '--out', str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    assert "rigid: speed against cost of transport: the paper's robot makes" in printed
    rows = list(csv.DictReader((out / 'design.csv').open()))
    assert len(rows) == design.runs_in(design.draw('lhs', 2), ('rigid', 'sheet')) == 10
    assert {r['wall'] for r in rows} == {'rigid', 'sheet'}
    assert [r for r in rows if r['paper'] == '1' and r['status'] == 'ok']
    for name in ('design_rigid.png', 'design_sheet.png', 'summary.md'):
        assert (out / name).stat().st_size > 0
    assert 'design_rigid.png' in (out / 'summary.md').read_text()


def test_ranges_are_checked():
    with pytest.raises(ValueError, match='is not swept'):
        design.check_dimensions([('robot.mass', 0.1, 0.2)])
    with pytest.raises(ValueError, match='must be below'):
        design.check_dimensions([('robot.amplitude', 0.02, 0.01)])
    with pytest.raises(ValueError, match='log scale'):
        design.check_dimensions([('flexure.stiffness', 0.0, 10.0)])
    changed = design.check_dimensions([('robot.wave_links', 15, 20)])
    assert [d.name for d in changed] == [d.name for d in design.DIMENSIONS]
    assert changed[0].levels(6) == [15.0, 16.0, 17.0, 18.0, 19.0, 20.0]


def test_same_numbers_on_two_processes():
    one = design.run_study(BASE, 'lhs', 2, walls=('rigid',), settle=SETTLE, measure=MEASURE)
    two = design.run_study(BASE, 'lhs', 2, walls=('rigid',), settle=SETTLE, measure=MEASURE,
                           pool=LocalPool(2))
    pairs = list(itertools.zip_longest(one.runs, two.runs))
    assert all(a.status == b.status and (a.speed == b.speed or not a.ok) for a, b in pairs)


def test_the_design_study_page_quotes_the_committed_run():
    """docs/design_study.md's numbers are docs/design_study/summary.md's (generated)."""
    import re
    from pathlib import Path
    docs = Path(__file__).resolve().parents[2] / 'docs'
    page = (docs / 'design_study.md').read_text()
    quoted = page[page.index('## What the fronts show'):page.index('**What the model leaves')]
    summary = ' '.join((docs / 'design_study' / 'summary.md').read_text().split())
    numbers = re.findall(r'[+-]?\d+\.\d+ (?:%|cm/s)|[+-]\d\.\d\d', quoted)
    assert len(numbers) > 20
    missing = [n for n in numbers if n not in summary]
    missing += [n for n in re.findall(r'(\d+) designs', quoted)
                if f'dominated by {n} of the designs' not in summary]
    assert not missing, missing


def test_the_study_on_a_dask_cluster_equals_the_local_pool():
    """--scheduler: the geometries go to Dask workers and come back in order, the same runs."""
    distributed = pytest.importorskip('distributed')
    from saw_ros.analysis.cluster import DaskPool
    local = design.run_study(BASE, 'lhs', 2, walls=('rigid',), settle=SETTLE, measure=MEASURE)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=':0') as cluster:
        with DaskPool(cluster.scheduler_address) as pool:
            remote = design.run_study(BASE, 'lhs', 2, walls=('rigid',), settle=SETTLE,
                                      measure=MEASURE, pool=pool)
    assert [(r.design, r.flexure, r.status) for r in remote.runs] == \
        [(r.design, r.flexure, r.status) for r in local.runs]
    assert [r.speed for r in remote.runs if r.ok] == [r.speed for r in local.runs if r.ok]
