"""
The design study (issue 31): which robot crawls best, and where the paper's robot sits.

The robot's geometry (wave links n, amplitude A, wavelength L, tip distance r: the radius at
which the link tips ride about the helix's backbone) and its link flexures (stiffness k, at
DAMPING_RATIO) are swept, as a Latin hypercube or a grid, against three walls (rigid, the
silicone sheet and the soft tissue of docs/walls.md), at a constant motor voltage. Every run
gives

- the speed (mean forward speed over the window, m/s) and the AR (speed over
  4 pi^2 A r f / L at the helix frequency f it turned at);
- the cost of transport, the electrical energy per unit weight and distance: mean V i over
  (m g speed);
- the vibration: shape-drive's measure (the RMS of the body's normal acceleration over the
  window), as ``saw-ros compliant`` takes it, measured by the same function
  (``analysis.shape_drive.evaluate`` with a constant voltage).

A design the model cannot run is reported as such, with the reason, never as numbers: links
that collide over a wave cycle (core.kinematics), a geometry the Scenario refuses (links that do
not fit the body, a robot too tall for the gap), a motor that stalls, a robot that does not
advance, and a run that left the model (DivergenceError). Flexures run on every wall (on bending
walls core.flexure.flex_walls solves the walls and the links together).

One job per geometry (its walls and flexures, each run alone so that one run leaving the model
does not take the others with it) on the pool: local processes or a Dask cluster.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
import itertools
import math
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from saw_ros.core.params import GRAVITY, ParameterError, Scenario
from saw_ros.core.pool import LocalPool, Pool

# Measured as shape-drive and saw-ros compliant measure: the motor and the contacts settle, then
# a window of five to six helix turns at 6 V.
SETTLE_S = 3.0
MEASURE_S = 4.0
VOLTAGE = 6.0           # V: the middle of the paper's 4-7 V, as saw-ros compliant
# The flexures' damping ratio c / (2 sqrt(k m)): the best of saw-ros compliant's sweep
# (docs/compliant_robot.md); lightly damped flexures shake the robot more.
DAMPING_RATIO = 0.7
# Slower than this share of its no-load speed the helix has stalled against the walls.
STALL_SHARE = 0.1
# Below this AR the robot does not advance (walls_study's stall bar).
NO_ADVANCE_AR = 0.05
DEFAULT_SIZE = 400      # geometries of the default Latin hypercube (docs/design_study.md)
DEFAULT_SEED = 1
LARGEST_STUDY = 20000   # runs: a grid beyond this is refused, not started

# The walls of docs/walls.md: (surface.foundation_stiffness N/m^2, surface.bending_stiffness
# N m^2); 0 keeps the paper's rigid walls behind their contact springs.
WALLS: Dict[str, Tuple[float, float]] = {
    'rigid': (0.0, Scenario().surface.bending_stiffness),
    'sheet': (1.5e5, 6.25e-4),
    'tissue': (9e3, 1.2e-5),
}


@dataclass(frozen=True)
class Dimension:
    """One swept parameter: its Scenario name, the default range and how it is sampled."""

    name: str
    low: float
    high: float
    log: bool = False
    integer: bool = False

    def values(self, unit: np.ndarray) -> np.ndarray:
        """Map points of [0, 1] onto the range (log-uniform where ``log``, rounded integers)."""
        if self.log:
            out = self.low * (self.high / self.low) ** unit
        else:
            out = self.low + (self.high - self.low) * unit
        return np.round(out) if self.integer else out

    def levels(self, count: int) -> List[float]:
        """Return ``count`` evenly spread levels over the range (fewer where integers repeat)."""
        return sorted({float(v) for v in self.values(np.linspace(0.0, 1.0, count))})


# The default ranges (ours): around the paper's robot (19 links, A 18.5 mm, L 102 mm, r 9.8 mm,
# rigid links), wide enough that the model refuses designs at their ends: short waves with long
# tips collide, many long links do not fit the body, a short robot does not reach both walls.
# The amplitude stops below the base link (20 mm: robot.amplitude must be shorter); the
# flexures span saw-ros compliant's sweep.
DIMENSIONS: Tuple[Dimension, ...] = (
    Dimension('robot.wave_links', 10, 26, integer=True),
    Dimension('robot.amplitude', 0.010, 0.0195),
    Dimension('robot.wavelength', 0.070, 0.130),
    Dimension('robot.tip_distance', 0.007, 0.014),
    Dimension('flexure.stiffness', 300.0, 1e5, log=True),
)
GEOMETRY = tuple(d.name for d in DIMENSIONS if d.name.startswith('robot.'))
COLUMNS = ('design', 'paper', 'wall', 'wave_links', 'amplitude_m', 'wavelength_m',
           'tip_distance_m', 'flexure_stiffness_N_per_m', 'flexure_damping_N_s_per_m',
           'status', 'speed_m_per_s', 'advance_ratio', 'helix_Hz', 'power_W',
           'cost_of_transport', 'vibration_m_per_s2', 'reason')


@dataclass
class DesignRun:
    """One design on one wall: its figures (SI) when ``status`` is 'ok', else the reason."""

    design: int
    wall: str
    geometry: Dict[str, float]
    flexure: float                  # N/m, 0: rigid links
    damping: float                  # N s/m
    status: str
    reason: str = ''
    speed: float = math.nan         # m/s
    advance_ratio: float = math.nan
    helix_hz: float = math.nan
    power: float = math.nan         # W, mean electrical power V i
    cost_of_transport: float = math.nan
    vibration: float = math.nan     # m/s^2 RMS
    paper: bool = False

    @property
    def ok(self) -> bool:
        return self.status == 'ok'


@dataclass
class Study:
    """Every run of a design study, and how it was drawn."""

    runs: List[DesignRun]
    method: str
    size: int
    seed: int
    walls: Tuple[str, ...]
    settle: float
    measure: float
    voltage: float
    dimensions: Tuple[Dimension, ...] = field(default_factory=lambda: DIMENSIONS)

    def on(self, wall: str) -> List[DesignRun]:
        return [r for r in self.runs if r.wall == wall]

    def paper(self, wall: str) -> Optional[DesignRun]:
        return next((r for r in self.on(wall) if r.paper), None)


# -- drawing the designs -----------------------------------------------------------------------
def latin_hypercube(count: int, dims: int, seed: int) -> np.ndarray:
    """Return ``count`` points of [0, 1]^dims, one in each of ``count`` strata per dimension."""
    rng = np.random.default_rng(seed)
    unit = np.empty((count, dims))
    for j in range(dims):
        unit[:, j] = (rng.permutation(count) + rng.random(count)) / count
    return unit


def draw(method: str, size: int, seed: int = DEFAULT_SEED,
         dimensions: Sequence[Dimension] = DIMENSIONS
         ) -> List[Tuple[Dict[str, float], Tuple[float, ...]]]:
    """
    Return the study's geometries, each with the flexure stiffnesses it is run with.

    'lhs': ``size`` points of a Latin hypercube over every dimension, each geometry run with its
    own flexure; 'grid': ``size`` levels per dimension, every geometry with every flexure level.
    Every geometry also runs with rigid links (the paper's kind), so the flexures are compared
    on the same geometry.
    """
    geometric = [d for d in dimensions if d.name in GEOMETRY]
    flexure = next(d for d in dimensions if d.name == 'flexure.stiffness')
    if method == 'lhs':
        unit = latin_hypercube(size, len(dimensions), seed)
        names = [d.name for d in dimensions]
        out: List[Tuple[Dict[str, float], Tuple[float, ...]]] = []
        for row in unit:
            values = {d.name: float(d.values(np.array(u))) for d, u in zip(dimensions, row)}
            out.append(({n: values[n] for n in names if n in GEOMETRY},
                        (values['flexure.stiffness'],)))
        return out
    if method == 'grid':
        flexures = tuple(flexure.levels(size))
        return [(dict(zip(GEOMETRY, combo)), flexures)
                for combo in itertools.product(*(d.levels(size) for d in geometric))]
    raise ValueError(f'unknown method {method!r}: lhs or grid')


def runs_in(designs: Sequence[Tuple[Dict[str, float], Tuple[float, ...]]],
            walls: Sequence[str]) -> int:
    """Return how many runs a study of ``designs`` on ``walls`` makes (with the paper's)."""
    return sum(len(walls) * (1 + len(f)) for _, f in designs) + len(walls)


def paper_geometry() -> Dict[str, float]:
    """Return the paper's robot (the Scenario's defaults) as a geometry of the study."""
    flat = Scenario().flat()
    return {name: float(flat[name]) for name in GEOMETRY}


# -- running them ------------------------------------------------------------------------------
def wall_scenario(base: Scenario, wall: str, geometry: Dict[str, float],
                  flexure: float, link_mass: float) -> Scenario:
    """Return ``base`` with the geometry, the wall and the flexure (at DAMPING_RATIO)."""
    foundation, bending = WALLS[wall]
    values: Dict[str, Any] = {name: (int(v) if name == 'robot.wave_links' else v)
                              for name, v in geometry.items()}
    values.update({'surface.foundation_stiffness': foundation,
                   'surface.bending_stiffness': bending,
                   'flexure.stiffness': flexure,
                   'flexure.damping': damping_of(flexure, link_mass)})
    return base.with_values(values)


def damping_of(stiffness: float, link_mass: float) -> float:
    """Return the flexure damping (N s/m) of DAMPING_RATIO on a link of ``link_mass`` kg."""
    return DAMPING_RATIO * 2.0 * math.sqrt(stiffness * link_mass) if stiffness > 0.0 else 0.0


def measure_run(scenario: Scenario, settle: float, measure: float) -> Dict[str, Any]:
    """
    Run one scenario at its constant voltage; return its status and figures.

    Status 'ok' with speed, AR, helix frequency, power, cost of transport and vibration;
    otherwise 'links collide', 'infeasible', 'diverged', 'stalled' or 'no advance' with the
    reason (one line) and no figures.
    """
    # Here, not at the top: the command line's parser imports this module, and the compiled
    # core takes a second to load.
    from saw_ros.analysis.shape_drive import evaluate, HARMONICS
    from saw_ros.core.dynamics import DivergenceError
    from saw_ros.core.kinematics import v_theory
    try:
        outcome = evaluate(scenario, [scenario.motor.voltage],
                           np.zeros((1, 2 * len(HARMONICS))), HARMONICS, settle, measure)
    except DivergenceError as exc:
        return {'status': 'diverged', 'reason': str(exc)}
    except ParameterError as exc:
        status = 'links collide' if 'links interfere' in str(exc) else 'infeasible'
        return {'status': status, 'reason': str(exc)}
    speed, helix = float(outcome.speed[0]), float(outcome.helix_hz[0])
    no_load = scenario.frequency
    if no_load <= 0.0:
        return {'status': 'stalled',
                'reason': f'the motor stalled: {scenario.motor.voltage:g} V is below the '
                          f'{scenario.motor.dead_voltage:.3g} V its friction needs'}
    if not helix >= STALL_SHARE * no_load:
        return {'status': 'stalled',
                'reason': f'the motor stalled: the helix turned at {helix:.3g} Hz, under '
                          f'{STALL_SHARE:.0%} of its no-load {no_load:.3g} Hz'}
    ar = speed / v_theory(scenario.robot, helix)
    if not ar >= NO_ADVANCE_AR:
        return {'status': 'no advance',
                'reason': f'AR {ar:.3g} under {NO_ADVANCE_AR:g}: the tips slip or do not '
                          f'reach the walls (the robot is {1000 * scenario.robot.height:.1f} '
                          f'mm tall in a {1000 * scenario.conditions.gap:.1f} mm gap)'}
    power = float(outcome.power[0])
    return {'status': 'ok', 'speed': speed, 'advance_ratio': ar, 'helix_hz': helix,
            'power': power,
            'cost_of_transport': power / (scenario.robot.mass * GRAVITY * speed),
            'vibration': float(outcome.vibration[0])}


Job = Tuple[int, Dict[str, float], Tuple[float, ...], Scenario, Tuple[str, ...], float, float,
            bool]


def run_geometry(job: Job) -> List[DesignRun]:
    """Run one geometry on every wall, with rigid links and each flexure (a pool's job)."""
    design, geometry, flexures, base, walls, settle, measure, paper = job
    link_mass = base.flexure.link_mass
    runs = []
    for wall in walls:
        for flexure in (0.0,) + tuple(flexures):
            damping = damping_of(flexure, link_mass)
            run = DesignRun(design, wall, geometry, flexure, damping, 'ok', paper=paper)
            runs.append(run)
            try:
                scenario = wall_scenario(base, wall, geometry, flexure, link_mass)
            except ParameterError as exc:
                run.status, run.reason = 'infeasible', str(exc)
                continue
            for key, value in measure_run(scenario, settle, measure).items():
                setattr(run, key, value)
    return runs


def run_study(base: Scenario, method: str = 'lhs', size: int = DEFAULT_SIZE,
              seed: int = DEFAULT_SEED, walls: Sequence[str] = tuple(WALLS),
              settle: float = SETTLE_S, measure: float = MEASURE_S,
              dimensions: Sequence[Dimension] = DIMENSIONS, pool: Optional[Pool] = None,
              progress: Optional[Callable[[int], None]] = None) -> Study:
    """
    Run the paper's robot (design 0) and every drawn design on ``walls``, one job a geometry.

    ``base``: everything the sweep does not set (slope, gap, motor and its voltage, contact).
    ``progress(runs)`` after every geometry.
    """
    if base.motor.voltage <= 0.0:
        raise ParameterError('the design study needs the motor (motor.voltage > 0): the cost '
                             'of transport is its electrical energy')
    pool = pool if pool is not None else LocalPool(1)
    walls = tuple(walls)
    designs = draw(method, size, seed, dimensions)
    jobs: List[Job] = [(0, paper_geometry(), (), base, walls, settle, measure, True)]
    jobs += [(i, geometry, flexures, base, walls, settle, measure, False)
             for i, (geometry, flexures) in enumerate(designs, start=1)]
    runs: List[DesignRun] = []
    for done in pool.map(run_geometry, jobs):
        runs.extend(done)
        if progress is not None:
            progress(len(done))
    return Study(runs, method, size, seed, walls, settle, measure, base.motor.voltage,
                 tuple(dimensions))


# -- the fronts --------------------------------------------------------------------------------
def pareto_front(speed: Sequence[float], cost: Sequence[float]) -> np.ndarray:
    """
    Return a mask of the points no other point dominates (faster or as fast, and cheaper).

    A point dominates another when its speed is at least as high and its cost at most as high,
    one of them strictly. Equal points do not dominate each other: both stay on the front.
    """
    fast = np.asarray(speed, float)
    dear = np.asarray(cost, float)
    front = np.zeros(len(fast), bool)
    best = math.inf         # the lowest cost among the strictly faster points
    order = np.argsort(-fast, kind='stable')
    i = 0
    while i < len(order):
        j = i
        while j < len(order) and fast[order[j]] == fast[order[i]]:
            j += 1
        group = order[i:j]
        cheapest = float(dear[group].min())
        for k in group:
            front[k] = dear[k] == cheapest and dear[k] < best
        best = min(best, cheapest)
        i = j
    return front


def dominates(a: Tuple[float, float], b: Tuple[float, float]) -> bool:
    """Return whether (speed, cost) ``a`` dominates ``b``."""
    return a[0] >= b[0] and a[1] <= b[1] and (a[0] > b[0] or a[1] < b[1])


MEASURES = (('cost_of_transport', 'cost of transport', ''),
            ('vibration', 'vibration', ' m/s^2 RMS'))


def standing(study: Study, wall: str, measure: str) -> Dict[str, Any]:
    """
    Return where the paper's robot sits on ``wall``'s front of speed against ``measure``.

    Keys: 'front' (the runs on it), 'paper' (its run or None), 'dominated_by' (the runs that
    dominate it), 'as_fast' (the lowest ``measure`` among the designs at least as fast) and
    'as_cheap' (the fastest among those with no more ``measure``), each None when there is none.
    """
    runs = [r for r in study.on(wall) if r.ok]
    mask = pareto_front([r.speed for r in runs], [getattr(r, measure) for r in runs])
    front = sorted((r for r, m in zip(runs, mask) if m), key=lambda r: r.speed)
    paper = study.paper(wall)
    result: Dict[str, Any] = {'front': front, 'paper': paper, 'dominated_by': [],
                              'as_fast': None, 'as_cheap': None}
    if paper is None or not paper.ok:
        return result
    mine = (paper.speed, getattr(paper, measure))
    others = [r for r in runs if r is not paper]
    result['dominated_by'] = [r for r in others if dominates((r.speed, getattr(r, measure)),
                                                             mine)]
    if result['dominated_by']:
        result['as_fast'] = min((r for r in result['dominated_by'] if r.speed >= paper.speed),
                                key=lambda r: getattr(r, measure), default=None)
        result['as_cheap'] = max((r for r in result['dominated_by']
                                  if getattr(r, measure) <= mine[1]),
                                 key=lambda r: r.speed, default=None)
    return result


# -- outputs -----------------------------------------------------------------------------------
def _number(value: float, spec: str) -> str:
    return format(value, spec) if math.isfinite(value) else ''


def write_csv(study: Study, path: Path) -> Path:
    """Write every run, one row each; no figures where the status says why there are none."""
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in study.runs:
            g = r.geometry
            w.writerow([r.design, int(r.paper), r.wall, int(g['robot.wave_links']),
                        f'{g["robot.amplitude"]:.6g}', f'{g["robot.wavelength"]:.6g}',
                        f'{g["robot.tip_distance"]:.6g}', f'{r.flexure:.6g}', f'{r.damping:.6g}',
                        r.status, _number(r.speed, '.6g'), _number(r.advance_ratio, '.5g'),
                        _number(r.helix_hz, '.5g'), _number(r.power, '.5g'),
                        _number(r.cost_of_transport, '.5g'), _number(r.vibration, '.5g'),
                        r.reason])
    return path


def _plt():
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    return plt


def write_figure(study: Study, wall: str, path: Path) -> Path:
    """Write ``wall``'s two fronts (speed against cost of transport, and vibration) as a PNG."""
    plt = _plt()
    from matplotlib.ticker import FormatStrFormatter
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    runs = [r for r in study.on(wall) if r.ok]
    for ax, (measure, label, unit) in zip(axes, MEASURES):
        rigid = [r for r in runs if r.flexure == 0.0 and not r.paper]
        flexed = [r for r in runs if r.flexure > 0.0]
        ax.plot([100 * r.speed for r in rigid], [getattr(r, measure) for r in rigid], 'o',
                color='0.65', ms=3.5, label='rigid links')
        if flexed:
            ax.plot([100 * r.speed for r in flexed], [getattr(r, measure) for r in flexed], '^',
                    color='C0', alpha=0.5, ms=3.5, label=f'flexures (damping ratio '
                    f'{DAMPING_RATIO:g})')
        place = standing(study, wall, measure)
        front = place['front']
        ax.plot([100 * r.speed for r in front], [getattr(r, measure) for r in front], 'o-',
                color='C3', ms=5, mfc='none', label=f'Pareto front ({len(front)})')
        paper = place['paper']
        if paper is not None and paper.ok:
            ax.plot(100 * paper.speed, getattr(paper, measure), '*', color='k', ms=16,
                    label="the paper's robot")
        ax.set_xlabel('speed (cm/s)')
        # Log: a few slow designs cost ten times the rest and would squash the front.
        ax.set_yscale('log')
        ax.yaxis.set_major_formatter(FormatStrFormatter('%g'))
        ax.yaxis.set_minor_formatter(FormatStrFormatter('%g'))
        ax.set_ylabel(f'{label}{" (" + unit.strip() + ")" if unit else ""}, log scale')
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    refused = len(study.on(wall)) - len(runs)
    fig.suptitle(f'Design study on the {wall} walls ({study.voltage:g} V, level)\n{len(runs)} '
                 f'designs ran, {refused} could not (summary.md says why)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def describe(run: DesignRun) -> str:
    """Return a design's geometry and flexure in a few words."""
    g = run.geometry
    flexure = ('rigid links' if run.flexure == 0.0 else
               f'flexures {run.flexure:.0f} N/m')
    return (f'design {run.design}: {int(g["robot.wave_links"])} links, A '
            f'{1000 * g["robot.amplitude"]:.1f} mm, L {1000 * g["robot.wavelength"]:.1f} mm, r '
            f'{1000 * g["robot.tip_distance"]:.1f} mm, {flexure}')


def _change(new: float, old: float) -> str:
    return f'{100.0 * (new / old - 1.0):+.1f} %'


def standing_text(study: Study, wall: str, measure: str, label: str, unit: str) -> str:
    """Return one paragraph: where the paper's robot sits on one front, with numbers."""
    place = standing(study, wall, measure)
    paper = place['paper']
    if paper is None or not paper.ok:
        why = 'it was not run' if paper is None else f'{paper.status}: {paper.reason}'
        return f"- speed against {label}: the paper's robot has no figures here ({why})."
    mine = getattr(paper, measure)
    head = (f"- speed against {label}: the paper's robot makes {100 * paper.speed:.2f} cm/s at "
            f'{mine:.3g}{unit}; ')
    dominated = place['dominated_by']
    if not dominated:
        return head + f'it is on the front ({len(place["front"])} designs): no design is ' \
                      f'both as fast and as good.'
    text = head + f'dominated by {len(dominated)} of the designs. '
    fast, cheap = place['as_fast'], place['as_cheap']
    if fast is not None:
        text += (f'At least as fast, the best is {describe(fast)}: {100 * fast.speed:.2f} cm/s '
                 f'({_change(fast.speed, paper.speed)}) at {getattr(fast, measure):.3g}{unit} '
                 f'({_change(getattr(fast, measure), mine)}). ')
    if cheap is not None and cheap is not fast:
        text += (f'At no more {label}, the fastest is {describe(cheap)}: '
                 f'{100 * cheap.speed:.2f} cm/s ({_change(cheap.speed, paper.speed)}) at '
                 f'{getattr(cheap, measure):.3g}{unit} '
                 f'({_change(getattr(cheap, measure), mine)}).')
    return text.rstrip()


def front_table(study: Study, wall: str, measure: str, label: str) -> str:
    """Return the designs of one front as a markdown table, slowest first."""
    front = standing(study, wall, measure)['front']
    rows = [f'The front of speed against {label} ({len(front)} designs):', '',
            '| design | links | A (mm) | L (mm) | r (mm) | flexure (N/m) | speed (cm/s) | AR | '
            'cost of transport | vibration (m/s^2 RMS) |', '|---' * 10 + '|']
    for r in front:
        g = r.geometry
        rows.append(f'| {r.design}{" (paper)" if r.paper else ""} | '
                    f'{int(g["robot.wave_links"])} | {1000 * g["robot.amplitude"]:.1f} | '
                    f'{1000 * g["robot.wavelength"]:.1f} | {1000 * g["robot.tip_distance"]:.1f} '
                    f'| {"rigid" if r.flexure == 0.0 else f"{r.flexure:.0f}"} | '
                    f'{100 * r.speed:.2f} | {r.advance_ratio:.3f} | {r.cost_of_transport:.3f} | '
                    f'{r.vibration:.2f} |')
    return '\n'.join(rows)


FLEXURE_BANDS = ((300.0, 1e3), (1e3, 3e3), (3e3, 1e4), (1e4, 1e5))      # N/m


def flexure_table(study: Study, wall: str = 'rigid') -> str:
    """Return each flexure against rigid links on the same geometry, by stiffness band."""
    rigid = {r.design: r for r in study.on(wall) if r.ok and r.flexure == 0.0}
    pairs = [(rigid[r.design], r) for r in study.on(wall)
             if r.ok and r.flexure > 0.0 and r.design in rigid]
    rows = [f'Flexures against rigid links on the same geometry, {wall} walls (medians over '
            f'the pairs of each band):', '',
            '| flexure (N/m) | pairs | with less vibration | vibration | speed | cost of '
            'transport |', '|---' * 6 + '|']
    for low, high in FLEXURE_BANDS:
        band = [(a, b) for a, b in pairs if low <= b.flexure < high]
        if not band:
            continue

        def median(get: Callable[[DesignRun], float]) -> str:
            return _change(float(np.median([get(b) / get(a) for a, b in band])), 1.0)
        rows.append(f'| {low:g} - {high:g} | {len(band)} | '
                    f'{sum(b.vibration < a.vibration for a, b in band)} | '
                    f'{median(lambda r: r.vibration)} | {median(lambda r: r.speed)} | '
                    f'{median(lambda r: r.cost_of_transport)} |')
    return '\n'.join(rows) if pairs else ''


def rank_correlations(study: Study, wall: str) -> str:
    """Return how each geometric parameter ranks with the cost of transport (rigid links)."""
    runs = [r for r in study.on(wall) if r.ok and r.flexure == 0.0]
    if len(runs) < 3:
        return ''

    def ranks(values: Sequence[float]) -> np.ndarray:
        return np.argsort(np.argsort(np.asarray(values, float))).astype(float)
    cost = ranks([r.cost_of_transport for r in runs])
    parts = []
    for name in GEOMETRY:
        mine = ranks([r.geometry[name] for r in runs])
        if mine.std() > 0.0:
            rho = float(np.corrcoef(mine, cost)[0, 1])
            parts.append(f'{name.split(".")[1]} {rho:+.2f}')
    return (f'Rank correlation (Spearman) of each parameter with the cost of transport, the '
            f'{len(runs)} rigid-link designs that ran: ' + ', '.join(parts) + '.')


def summary_text(study: Study, figures: Dict[str, str], seconds: Optional[float] = None) -> str:
    """Return summary.md: the study, the statuses, and where the paper's robot sits."""
    statuses = sorted({r.status for r in study.runs})
    size = (f'a Latin hypercube of {study.size} geometries (seed {study.seed}), each with rigid '
            f'links and with its own flexure' if study.method == 'lhs' else
            f'a grid of {study.size} levels per parameter, every geometry with rigid links and '
            f'each flexure level')
    ranges = '\n'.join(f'| `{d.name}` | {d.low:g} | {d.high:g} | '
                       f'{"log" if d.log else "integer" if d.integer else "linear"} |'
                       for d in study.dimensions)
    table = ['| wall | ' + ' | '.join(statuses) + ' |', '|---|' + '---|' * len(statuses)]
    for wall in study.walls:
        runs = study.on(wall)
        table.append(f'| {wall} | ' + ' | '.join(str(sum(r.status == s for r in runs))
                                                 for s in statuses) + ' |')
    reasons = []
    for status in statuses:
        if status == 'ok':
            continue
        example = next(r for r in study.runs if r.status == status)
        reasons.append(f'- **{status}**, e.g. {describe(example)} on the {example.wall} walls: '
                       f'{example.reason}')
    sections = []
    for wall in study.walls:
        lines = [f'### {wall.capitalize()} walls', '', f'![{wall}]({figures[wall]})', '']
        lines += [standing_text(study, wall, measure, label, unit)
                  for measure, label, unit in MEASURES]
        for measure, label, _ in MEASURES:
            lines += ['', front_table(study, wall, measure, label)]
        lines += ['', rank_correlations(study, wall)]
        if any(r.ok and r.flexure > 0.0 for r in study.on(wall)):
            lines += ['', flexure_table(study, wall)]
        sections.append('\n'.join(lines))
    took = '' if seconds is None else f' It took {seconds:.0f} s.'
    return f"""# Design study (generated by `saw-ros design`)

The designs: {size}; and the paper's robot (design 0).

On the {', '.join(study.walls)} walls at {study.voltage:g} V, level. Each run settles
{study.settle:g} s and is measured over {study.measure:g} s; {len(study.runs)} runs in
all.{took} Flexure damping ratio {DAMPING_RATIO:g}. Speed: the mean forward speed; cost of
transport: the mean electrical power V i over (m g speed); vibration: the RMS normal
acceleration of the body (shape-drive's measure, as `saw-ros compliant` takes it).
docs/design_study.md explains the study.

| parameter | low | high | sampled |
|---|---|---|---|
{ranges}

Runs by status (only 'ok' runs have figures; design.csv gives every run's reason):

{chr(10).join(table)}

{chr(10).join(reasons)}

## Where the paper's robot sits

{(chr(10) + chr(10)).join(sections)}
"""


def write_outputs(study: Study, out: Path, seconds: Optional[float] = None) -> Dict[str, Path]:
    """Write design.csv, design_<wall>.png and summary.md into ``out``; return their paths."""
    out.mkdir(parents=True, exist_ok=True)
    paths = {'csv': write_csv(study, out / 'design.csv')}
    figures = {}
    for wall in study.walls:
        paths[wall] = write_figure(study, wall, out / f'design_{wall}.png')
        figures[wall] = paths[wall].name
    paths['summary'] = out / 'summary.md'
    paths['summary'].write_text(summary_text(study, figures, seconds))
    return paths


def check_dimensions(changes: Iterable[Tuple[str, float, float]],
                     dimensions: Sequence[Dimension] = DIMENSIONS) -> Tuple[Dimension, ...]:
    """Return ``dimensions`` with the (name, low, high) ranges changed; ValueError if wrong."""
    by_name = {d.name: d for d in dimensions}
    for name, low, high in changes:
        if name not in by_name:
            raise ValueError(f'{name} is not swept; the swept parameters: '
                             f'{", ".join(by_name)}')
        if not low < high:
            raise ValueError(f'{name}: the low end {low:g} must be below the high end {high:g}')
        d = by_name[name]
        if d.log and low <= 0.0:
            raise ValueError(f'{name} is sampled on a log scale: its low end must be above 0')
        by_name[name] = Dimension(name, low, high, d.log, d.integer)
    return tuple(by_name[d.name] for d in dimensions)
