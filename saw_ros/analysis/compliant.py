"""
The paper's second remedy (Section 8), open loop: what link flexures do to the vibration.

"The utilization of a monolithic compliant robot structure": each wave link on a flexure
(core.flexure). Until the compiled step couples the flexures (issue 31), this estimate runs them
open loop: the rigid robot's run gives every tip's penetration into the rigid walls at every
step (its kinematic target), the flexure links are driven through them (core.flexure.
replay_links), and what the backbone feels replaces the tips' loads in the body's normal force.
The body's motion is held to the rigid run's, except its mean height: the run is shifted
towards the bottom wall until the links carry the rigid run's mean normal load again (a soft
flexure gives way and the body settles). The vibration is shape-drive's measure, the RMS of the
body's normal acceleration, here the normal force's fluctuation over the robot's mass.

What open loop leaves out, and so what the coupled step must still answer: the body's own
response to the changed forces (its pitch, its bounce) and the speed (the flexures take depth
from the tips that push). The replay's contact law is the simulator's, hysteresis included
(rigid links replayed give the rigid run's vibration back: ``rigid_check``).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from saw_ros.core.dynamics import Simulator
from saw_ros.core.flexure import balance_links, contact_law, replay_links
from saw_ros.core.params import FlexureParams, Scenario

SETTLE_S = 3.0          # as shape-drive: the motor and the contacts settle
MEASURE_S = 4.0
STIFFNESSES = tuple(float(k) for k in np.geomspace(300.0, 1e5, 12))     # N/m
DAMPING_RATIOS = (0.05, 0.2, 0.7)    # c / (2 sqrt(k m))
# The printed sets of docs/compliant_robot.md: (name, stiffness N/m, damping ratio).
PRINTED = (('TPU', 2070.0, 0.05), ('nylon PA12', 4500.0, 0.015))
LINK_MASS = FlexureParams().link_mass     # kg
# The replay's links start undeflected: their start (decaying within 30 ms at a damping ratio
# of 0.05 on the TPU set) is left out of every figure, the rigid ones' too.
WARM_S = 0.25


@dataclass
class RigidRun:
    """The rigid robot's steady window: penetrations (T, n) and its normal force (T,), N."""

    bottom: np.ndarray
    top: np.ndarray
    normal_force: np.ndarray
    dt: float
    mass: float
    law: np.ndarray         # core.flexure.contact_law
    before: np.ndarray      # (2, n) the contacts' depths the step before the window, m

    @property
    def vibration(self) -> float:
        """Return the RMS normal acceleration, m/s^2 (the mean removed)."""
        return float(np.std(steady(self, self.normal_force)) / self.mass)


def steady(run: 'RigidRun', values: np.ndarray) -> np.ndarray:
    """Return ``values`` (T, ...) of a replay without its first WARM_S."""
    return values[int(round(WARM_S / run.dt)):]


def rigid_run(scenario: Scenario, settle: float = SETTLE_S,
              measure: float = MEASURE_S) -> RigidRun:
    """Run the rigid robot and keep its tips' penetrations and normal force over the window."""
    sim = Simulator(scenario)
    # The window starts WARM_S early: the replay's start is left out of every figure (steady),
    # so the figures cover [settle, settle + measure], shape-drive's window.
    for _ in range(int(round((settle - WARM_S) / sim.dt))):
        sim.step()
    steps = int(round((measure + WARM_S) / sim.dt))
    n = sim.penetration.shape[1] // 2
    bottom, top, speed = np.empty((steps, n)), np.empty((steps, n)), np.empty(steps + 1)
    s = scenario.surface
    speed[0] = sim.q[4, 0]
    before = np.maximum(np.stack((sim.penetration[0, :n], sim.penetration[0, n:])), 0.0)
    for i in range(steps):
        sim.step()
        bottom[i], top[i] = sim.penetration[0, :n], sim.penetration[0, n:]
        speed[i + 1] = sim.q[4, 0]
    # The body's normal force, from the change of its normal speed (what the step integrated).
    force = np.diff(speed) / sim.dt * scenario.robot.mass
    return RigidRun(bottom, top, force, sim.dt, scenario.robot.mass, contact_law(s, sim.dt),
                    before)


def replay(run: RigidRun, flexure: FlexureParams, shift: float) -> Tuple[np.ndarray, np.ndarray]:
    """Return the backbone's normal force (T,) and the deflections (T, n), body ``shift`` down."""
    bottom = np.ascontiguousarray(run.bottom + shift)
    top = np.ascontiguousarray(run.top - shift)
    reaction, deflection = np.empty_like(bottom), np.empty_like(bottom)
    replay_links(bottom, top, np.maximum(run.before[0] + shift, 0.0),
                 np.maximum(run.before[1] - shift, 0.0), flexure.stiffness, flexure.damping,
                 flexure.link_mass, run.dt, run.law, reaction, deflection)
    return reaction.sum(axis=1), deflection


def rigid_force(run: RigidRun) -> np.ndarray:
    """Return the rigid links' normal force (T,) under the replay's contact law, N."""
    n = run.bottom.shape[1]
    zero, e, fb, ft = np.zeros(n), np.empty(n), np.empty(n), np.empty(n)
    before_bottom, before_top = run.before[0].copy(), run.before[1].copy()
    out = np.empty(len(run.bottom))
    for i in range(len(out)):
        balance_links(run.bottom[i], run.top[i], before_bottom, before_top, zero, 0.0, run.law,
                      e, fb, ft)
        out[i] = fb.sum() - ft.sum()
    return out


def balanced(run: RigidRun, flexure: FlexureParams,
             tolerance: float = 1e-4) -> Tuple[np.ndarray, np.ndarray, float]:
    """Return (force, deflections, shift m): the shift that carries the rigid mean load."""
    target = float(steady(run, rigid_force(run)).mean())
    low, high = 0.0, 0.01
    while high - low > 1e-7:
        shift = 0.5 * (low + high)
        force, deflection = replay(run, flexure, shift)
        mean = float(steady(run, force).mean())
        if abs(mean - target) < tolerance * abs(target):
            break
        if mean < target:
            low = shift
        else:
            high = shift
    return force, deflection, shift


def flexure_of(stiffness: float, ratio: float, link_mass: float) -> FlexureParams:
    return FlexureParams(stiffness=stiffness,
                         damping=ratio * 2.0 * math.sqrt(stiffness * link_mass),
                         link_mass=link_mass)


def outcome(run: RigidRun, flexure: FlexureParams, rigid: float) -> Dict[str, float]:
    """Return one flexure's figures against the rigid links' force fluctuation ``rigid`` (N)."""
    force, deflection, shift = balanced(run, flexure)
    fluctuation = float(np.std(steady(run, force)))
    return {'stiffness': flexure.stiffness, 'damping': flexure.damping,
            'vibration': fluctuation / run.mass,
            'reduction_pct': 100.0 * (1.0 - fluctuation / rigid),
            'largest_deflection_mm': 1000.0 * float(np.abs(steady(run, deflection)).max()),
            'settle_mm': 1000.0 * shift}


def sweep(run: RigidRun, stiffnesses: Sequence[float] = STIFFNESSES,
          ratios: Sequence[float] = DAMPING_RATIOS, link_mass: float = LINK_MASS,
          progress: Optional[Callable[[int], None]] = None) -> List[Dict[str, float]]:
    """Return one row per (stiffness, damping ratio): reduction %, deflections, shift."""
    rigid = float(np.std(steady(run, rigid_force(run))))
    rows = []
    for ratio in ratios:
        for k in stiffnesses:
            rows.append(dict(outcome(run, flexure_of(k, ratio, link_mass), rigid),
                             damping_ratio=ratio))
            if progress is not None:
                progress(1)
    return rows


def rigid_check(run: RigidRun) -> float:
    """Return the rigid replay's vibration over the run's own, less 1 (the replay's error)."""
    return float(np.std(steady(run, rigid_force(run))) / np.std(steady(run, run.normal_force))
                 - 1.0)


def _plt():
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    return plt


def _sweep_figure(rows: List[Dict[str, Any]], columns: Tuple[str, ...], csv: Path,
                  lower: Callable[[Dict[str, Any]], float]) -> Tuple[Any, Any, Any]:
    """
    Write ``rows`` to ``csv`` and start the sweep's figure: (figure, top axes, bottom axes).

    One line a damping ratio against the stiffness: the reduction on top, ``lower`` of each row
    below; the callers label the axes.
    """
    lines = [','.join(columns)] + [','.join(f'{r[c]:.6g}' for c in columns) for r in rows]
    csv.write_text('\n'.join(lines) + '\n')
    fig, (top, bottom) = _plt().subplots(2, 1, figsize=(7.5, 7.0), sharex=True)
    for ratio in sorted({r['damping_ratio'] for r in rows}):
        mine = [r for r in rows if r['damping_ratio'] == ratio]
        k = [r['stiffness'] for r in mine]
        top.semilogx(k, [r['reduction_pct'] for r in mine], 'o-', label=f'damping ratio {ratio:g}')
        bottom.semilogx(k, [lower(r) for r in mine], 'o-')
    return fig, top, bottom


def printed_rows(run: RigidRun, link_mass: float) -> List[Dict[str, Any]]:
    """Return the sweep's row of each printed set of docs/compliant_robot.md (PRINTED)."""
    rigid = float(np.std(steady(run, rigid_force(run))))
    return [dict(outcome(run, flexure_of(k, ratio, link_mass), rigid), name=name,
                 damping_ratio=ratio) for name, k, ratio in PRINTED]


def write_report(rows: List[Dict[str, float]], printed: List[Dict[str, Any]], run: RigidRun,
                 base: Scenario, out: Path) -> Dict[str, float]:
    """Write compliant.csv, compliant.png and report.md into ``out``; return the summary."""
    out.mkdir(parents=True, exist_ok=True)
    columns = ('stiffness', 'damping_ratio', 'damping', 'vibration', 'reduction_pct',
               'largest_deflection_mm', 'settle_mm')
    fig, top, bottom = _sweep_figure(rows, columns, out / 'compliant.csv',
                                     lambda r: r['largest_deflection_mm'])
    for r in printed:
        top.plot(r['stiffness'], r['reduction_pct'], 'k*', markersize=12)
        top.annotate(r['name'], (r['stiffness'], r['reduction_pct']), textcoords='offset points',
                     xytext=(6, 6))
    top.axhline(30.0, color='grey', ls='--', lw=0.8)
    top.set_ylabel('vibration reduction, %\n(open loop, RMS normal accel.)')
    top.legend()
    top.grid(True, which='both', alpha=0.3)
    bottom.axhline(1000.0 * base.robot.amplitude, color='grey', ls='--', lw=0.8)
    bottom.set_ylabel('largest link deflection, mm\n(dashed: wave amplitude A)')
    bottom.set_xlabel('flexure stiffness per link, N/m')
    bottom.grid(True, which='both', alpha=0.3)
    fig.suptitle(f'Link flexures against the rigid robot (slope '
                 f'{math.degrees(base.conditions.slope):g} deg): rigid {run.vibration:.3f} '
                 f'm/s^2 RMS')
    fig.tight_layout()
    fig.savefig(out / 'compliant.png', dpi=110)
    _plt().close(fig)
    check = rigid_check(run)
    best = max((r for r in rows if r['largest_deflection_mm'] < 1000.0 * base.robot.amplitude),
               key=lambda r: r['reduction_pct'], default=None)
    table = ['| set | stiffness (N/m) | damping ratio | vibration (m/s^2 RMS) | reduction | '
             'largest deflection (mm) | settles (mm) |', '|---|---|---|---|---|---|---|',
             f'| rigid | - | - | {run.vibration:.3f} | - | 0 | 0 |']
    table += [f'| {r["name"]} | {r["stiffness"]:.0f} | {r["damping_ratio"]:g} | '
              f'{r["vibration"]:.3f} | {r["reduction_pct"]:.1f} % | '
              f'{r["largest_deflection_mm"]:.2f} | {r["settle_mm"]:.2f} |' for r in printed]
    thirty = [r['stiffness'] for r in rows if r['reduction_pct'] >= 30.0]
    ratios = sorted({r['damping_ratio'] for r in rows})
    spread = max(max(r['reduction_pct'] for r in rows if r['stiffness'] == k)
                 - min(r['reduction_pct'] for r in rows if r['stiffness'] == k)
                 for k in {r['stiffness'] for r in rows})
    reach = (f'A reduction of 30 % needs a flexure of at most {max(thirty):.0f} N/m.' if thirty
             else 'No flexure of the sweep reaches 30 %.')
    largest = ('' if best is None else
               f'The largest, with every link deflecting less than the amplitude A: '
               f'{best["reduction_pct"]:.1f} % at {best["stiffness"]:.0f} N/m, the body settling '
               f'{best["settle_mm"]:.2f} mm.')
    ring = math.sqrt(300.0 / LINK_MASS) / (2.0 * math.pi)
    drive = (f'{base.motor.voltage:g} V' if base.motor.voltage > 0.0 else
             f'{base.conditions.frequency:g} Hz')
    text = f"""# Link flexures and the vibration, open loop (generated by `saw-ros compliant`)

The rigid robot ({drive}, slope {math.degrees(base.conditions.slope):g} deg; {SETTLE_S:g} s to
settle, then {len(steady(run, run.bottom)) * run.dt:g} s measured) gives every tip's penetration
into the rigid walls at every step. Flexure links (core.flexure, {LINK_MASS * 1000:g} g each)
are driven through them with the simulator's contact law, hysteresis included, and what the
backbone feels replaces the tips' loads in the body's normal force; the body is shifted
towards the bottom wall until the links carry the rigid run's mean load again ("settles").
The rigid links replayed this way give the run's own vibration back (to
{100 * abs(check):.1e} %).

**Open loop**: the body's motion is the rigid run's. What the body does with the changed
forces, and the speed the flexures cost, need the flexures coupled into the compiled step
(issue 31): these are the reductions of the forcing, not yet of the robot's vibration.

{chr(10).join(table)}

{reach} {largest}

The damping matters little: across damping ratios {', '.join(f'{x:g}' for x in ratios)} the
reduction at one stiffness differs by at most {spread:.1f} points. The stiffness does it all:
a {LINK_MASS * 1000:g} g link on 300 N/m or more rings at {ring:.0f} Hz or faster, 3.6 times
the link passing (about 12 Hz) or more, so the flexure is a spring in series with the contact
that softens the tips' force swings, not an isolator (isolating 12 Hz would need a link
ringing below 8.5 Hz: under 11 N/m, sagging centimetres under a tip's load).

![sweep](compliant.png)
"""
    (out / 'report.md').write_text(text)
    return {'rigid_vibration': run.vibration, 'rigid_check': check,
            **{f'{r["name"]}_reduction_pct': r['reduction_pct'] for r in printed}}


# -- closed loop: the flexures in the compiled step ------------------------------------------
SPEED_SHARE = 0.95      # the bar: a structure counts at >= 95 % of the rigid speed


def closed_loop(base: Scenario, stiffnesses: Sequence[float] = STIFFNESSES,
                ratios: Sequence[float] = DAMPING_RATIOS, link_mass: float = LINK_MASS,
                settle: float = SETTLE_S, measure: float = MEASURE_S) -> Dict[str, Any]:
    """
    Run the compliant robot itself for every (stiffness, damping ratio), in one batch.

    At ``base``'s constant voltage: its speed, vibration (shape-drive's RMS normal
    acceleration), electrical energy per metre, and the vibration against the rigid robot's at
    the same speed (shape-drive's constant-voltage curve: the vibration rises steeply with the
    speed, so the comparison is at equal speed). Returns the rows, the rigid figures and the
    best reduction among the flexures at SPEED_SHARE of the rigid speed or more.
    """
    from saw_ros.analysis.shape_drive import ConstantCurve, evaluate, HARMONICS
    grid = [(k, ratio) for ratio in ratios for k in stiffnesses]
    scenarios = [base.with_values({f'flexure.{name}': value for name, value in
                                   vars(flexure_of(k, ratio, link_mass)).items()})
                 for k, ratio in grid]
    zeros = np.zeros((len(grid) + 1, 2 * len(HARMONICS)))
    voltage = base.motor.voltage
    outcome = evaluate([base] + scenarios, [voltage] * (len(grid) + 1), zeros, HARMONICS,
                       settle, measure)
    curve = ConstantCurve(base, HARMONICS)
    rigid = {'speed': float(outcome.speed[0]), 'vibration': float(outcome.vibration[0]),
             'energy_per_m': float(outcome.power[0] / outcome.speed[0])}
    rows = []
    for i, (k, ratio) in enumerate(grid, start=1):
        speed = float(outcome.speed[i])
        inside = curve.speed[0] <= speed <= curve.speed[-1]
        same_speed = float(curve.at(speed, curve.vibration))
        rows.append({'stiffness': k, 'damping_ratio': ratio, 'speed': speed,
                     'speed_share': speed / rigid['speed'],
                     'vibration': float(outcome.vibration[i]),
                     'rigid_vibration_same_speed': same_speed if inside else math.nan,
                     'reduction_pct': (100.0 * (1.0 - float(outcome.vibration[i]) / same_speed)
                                       if inside else math.nan),
                     'energy_per_m': float(outcome.power[i] / speed)})
    eligible = [r for r in rows if r['speed_share'] >= SPEED_SHARE
                and math.isfinite(r['reduction_pct'])]
    best = max(eligible, key=lambda r: r['reduction_pct'], default=None)
    return {'rows': rows, 'rigid': rigid, 'best': best,
            'curve_speeds': (float(curve.speed[0]), float(curve.speed[-1]))}


def write_closed_loop(result: Dict[str, Any], base: Scenario, out: Path) -> None:
    """Append the closed-loop section to ``out``/report.md; write closed_loop.csv and .png."""
    rows, rigid, best = result['rows'], result['rigid'], result['best']
    columns = ('stiffness', 'damping_ratio', 'speed', 'speed_share', 'vibration',
               'rigid_vibration_same_speed', 'reduction_pct', 'energy_per_m')
    fig, top, bottom = _sweep_figure(rows, columns, out / 'closed_loop.csv',
                                     lambda r: 100.0 * r['speed_share'])
    top.axhline(30.0, color='grey', ls='--', lw=0.8)
    top.axhline(0.0, color='k', lw=0.6)
    top.set_ylabel('vibration reduction at equal speed, %')
    top.legend()
    top.grid(True, which='both', alpha=0.3)
    bottom.axhline(100.0 * SPEED_SHARE, color='grey', ls='--', lw=0.8)
    bottom.set_ylabel("speed, % of the rigid robot's")
    bottom.set_xlabel('flexure stiffness per link, N/m')
    bottom.grid(True, which='both', alpha=0.3)
    fig.suptitle(f'The compliant robot itself ({base.motor.voltage:g} V): rigid '
                 f'{rigid["vibration"]:.3f} m/s^2 RMS at {100 * rigid["speed"]:.2f} cm/s')
    fig.tight_layout()
    fig.savefig(out / 'closed_loop.png', dpi=110)
    _plt().close(fig)
    worse = [r for r in rows if math.isfinite(r['reduction_pct']) and r['reduction_pct'] < 0.0]
    answer = ('No flexure of the sweep keeps 95 % of the rigid speed with a reduction.'
              if best is None else
              f'The best structure at >= {100 * SPEED_SHARE:g} % of the rigid speed: '
              f'{best["stiffness"]:.0f} N/m, damping ratio {best["damping_ratio"]:g}, '
              f'{best["reduction_pct"]:.1f} % less vibration than the rigid robot at the same '
              f'speed ({best["vibration"]:.3f} against {best["rigid_vibration_same_speed"]:.3f} '
              f'm/s^2 RMS), crawling at {100 * best["speed_share"]:.1f} % of the rigid speed '
              f'for {best["energy_per_m"]:.2f} J/m of electrical energy (rigid '
              f'{rigid["energy_per_m"]:.2f} J/m).')
    finite = [r for r in rows if math.isfinite(r['reduction_pct'])]
    worst = min(finite, key=lambda r: r['reduction_pct'])
    worst_text = (f'The worst: {worst["stiffness"]:.0f} N/m at a damping ratio of '
                  f'{worst["damping_ratio"]:g}, {-worst["reduction_pct"]:.1f} % more (the link '
                  f'on its flexure and its contact ring together, and the body feels it).'
                  if worst['reduction_pct'] < 0.0 else '')
    stiffest = max(finite, key=lambda r: (r['stiffness'], -r['damping_ratio']))
    text = f"""
## Closed loop: the compliant robot itself

The flexures in the compiled step (core.flexure in dynamics.advance_scenario), every
(stiffness, damping ratio) of the sweep in one batch at {base.motor.voltage:g} V, against the
rigid robot at the same speed (shape-drive's constant-voltage curve: the vibration rises
steeply with the speed). Measured like shape-drive: {SETTLE_S:g} s to settle, {MEASURE_S:g} s.

{answer}

Flexures can also shake the robot more than rigid links: {len(worse)} of the {len(rows)} do.
{worst_text} The stiffest of the sweep ({stiffest["stiffness"]:.0f} N/m) still changes it by
{-stiffest["reduction_pct"]:+.1f} %: its links ring at
{math.sqrt(stiffest["stiffness"] / LINK_MASS) / (2 * math.pi):.0f} Hz and the body feels them.
How these figures move with the step: docs/compliant_robot.md.

![closed loop](closed_loop.png)
"""
    with (out / 'report.md').open('a') as f:
        f.write(text)


# -- level to vertical: the closed loop at every slope ---------------------------------------
def closed_loop_slopes(base: Scenario, slopes_deg: Sequence[float],
                       stiffnesses: Sequence[float] = STIFFNESSES,
                       ratios: Sequence[float] = DAMPING_RATIOS, link_mass: float = LINK_MASS,
                       settle: float = SETTLE_S, measure: float = MEASURE_S,
                       progress: Optional[Callable[[int], None]] = None,
                       done: Optional[Dict[float, Dict[str, Any]]] = None
                       ) -> Dict[str, Any]:
    """
    Run ``closed_loop`` on every slope of ``slopes_deg`` (degrees, + climbs) at base's voltage.

    Each slope against the rigid robot on that slope at the same speed (its own constant-voltage
    curve). A slope where a run leaves the model (DivergenceError) is kept with the reason, not
    dropped. ``done``: closed_loop results already run, by slope in degrees. Returns 'slopes'
    (one dict a slope: 'slope_deg', and closed_loop's result or 'error') and 'robust': the one
    structure that keeps SPEED_SHARE of the rigid speed with a reduction on every slope that
    ran, the best at its least reduction (``robust``).
    """
    from saw_ros.core.dynamics import DivergenceError
    out = []
    for slope in slopes_deg:
        result: Dict[str, Any] = {'slope_deg': float(slope)}
        if done is not None and float(slope) in done:
            result.update(done[float(slope)])
        else:
            scenario = base.with_values({'conditions.slope': math.radians(slope)})
            try:
                result.update(closed_loop(scenario, stiffnesses, ratios, link_mass, settle,
                                          measure))
            except DivergenceError as exc:
                result['error'] = str(exc)
        out.append(result)
        if progress is not None:
            progress(1)
    return {'slopes': out, 'robust': robust([r for r in out if 'error' not in r])}


def robust(results: Sequence[Dict[str, Any]]) -> Optional[Dict[str, Any]]:
    """
    Return the structure best on every slope of ``results`` (closed_loop's, one a slope).

    Among the (stiffness, damping ratio) that keep SPEED_SHARE of the rigid speed with a finite
    reduction on every slope, the one whose least reduction is the largest: its stiffness,
    damping ratio, 'reductions' and 'speed_shares' (one a slope) and 'least'. None if none does.
    """
    if not results:
        return None
    best = None
    for i, row in enumerate(results[0]['rows']):
        mine = [r['rows'][i] for r in results]
        if not all(m['speed_share'] >= SPEED_SHARE and math.isfinite(m['reduction_pct'])
                   for m in mine):
            continue
        least = min(m['reduction_pct'] for m in mine)
        if best is None or least > best['least']:
            best = {'stiffness': row['stiffness'], 'damping_ratio': row['damping_ratio'],
                    'reductions': [m['reduction_pct'] for m in mine],
                    'speed_shares': [m['speed_share'] for m in mine], 'least': least}
    return best


def least_text(least: float) -> str:
    """Return a structure's least reduction over the slopes as words ('at least x % less')."""
    return (f'at least {least:.1f} % less vibration' if least >= 0.0 else
            f'on one slope {-least:.1f} % more vibration')


def write_slopes(study: Dict[str, Any], base: Scenario, out: Path,
                 shaped: Optional[List[Dict[str, Any]]] = None) -> None:
    """
    Append the slopes' section to ``out``/report.md; write slopes.csv and slopes.png.

    ``shaped``: ``shaped_slopes``' rows for the robust structure, one a slope of the study.
    """
    from saw_ros.analysis.shape_drive import ConstantCurve
    ran = [r for r in study['slopes'] if 'error' not in r]
    columns = ('slope_deg', 'stiffness', 'damping_ratio', 'speed', 'speed_share', 'vibration',
               'rigid_vibration_same_speed', 'reduction_pct', 'energy_per_m')
    lines = [','.join(columns)]
    for r in ran:
        lines += [','.join(f'{v:.6g}' for v in [r['slope_deg']] + [row[c] for c in columns[1:]])
                  for row in r['rows']]
    (out / 'slopes.csv').write_text('\n'.join(lines) + '\n')
    best = study['robust']
    fig, (top, bottom) = _plt().subplots(2, 1, figsize=(7.5, 7.5))
    slopes = [r['slope_deg'] for r in ran]
    eligible = [r['best'] for r in ran]
    top.plot([s for s, b in zip(slopes, eligible) if b is not None],
             [b['reduction_pct'] for b in eligible if b is not None], 'o-',
             label=f'best at >= {100 * SPEED_SHARE:g} % of the rigid speed, each slope its own')
    for s, b in zip(slopes, eligible):
        if b is not None:
            top.annotate(f'{b["stiffness"]:.0f} N/m, {b["damping_ratio"]:g}',
                         (s, b['reduction_pct']), textcoords='offset points', xytext=(4, 6),
                         fontsize=8)
    if best is not None:
        top.plot(slopes, best['reductions'], 's--',
                 label=f'one structure on every slope: {best["stiffness"]:.0f} N/m, damping '
                       f'ratio {best["damping_ratio"]:g}')
    if shaped and best is not None:
        together = _together(shaped, study, best)
        top.plot(list(together), list(together.values()), 'D-',
                 label=f'{best["stiffness"]:.0f} N/m with its drive shaped on each slope')
    top.axhline(30.0, color='grey', ls='--', lw=0.8)
    top.axhline(0.0, color='k', lw=0.6)
    top.set_xlabel('slope, degrees')
    top.set_ylabel('vibration reduction at equal speed, %')
    top.legend(fontsize=8)
    top.grid(True, alpha=0.3)
    ratio = best['damping_ratio'] if best is not None else max(DAMPING_RATIOS)
    for r in ran:
        mine = [row for row in r['rows'] if row['damping_ratio'] == ratio]
        k = [row['stiffness'] for row in mine]
        line, = bottom.semilogx(k, [row['reduction_pct'] for row in mine], '-',
                                label=f'{r["slope_deg"]:g} deg')
        fast = [row for row in mine if row['speed_share'] >= SPEED_SHARE]
        bottom.semilogx([row['stiffness'] for row in fast],
                        [row['reduction_pct'] for row in fast], 'o', color=line.get_color())
        slow = [row for row in mine if row['speed_share'] < SPEED_SHARE]
        bottom.semilogx([row['stiffness'] for row in slow],
                        [row['reduction_pct'] for row in slow], 'o', mfc='none',
                        color=line.get_color())
    bottom.axhline(0.0, color='k', lw=0.6)
    bottom.set_xlabel('flexure stiffness per link, N/m')
    bottom.set_ylabel(f'reduction at damping ratio {ratio:g}, %\n'
                      f'(hollow: under {100 * SPEED_SHARE:g} % of the rigid speed)')
    bottom.legend(fontsize=8)
    bottom.grid(True, which='both', alpha=0.3)
    fig.suptitle(f'The compliant robot from level to vertical ({base.motor.voltage:g} V)')
    fig.tight_layout()
    fig.savefig(out / 'slopes.png', dpi=110)
    _plt().close(fig)
    table = ['| slope | rigid speed (cm/s) | rigid vibration (m/s^2 RMS) | best structure | '
             'reduction at equal speed | speed (% of rigid) | energy (J/m, rigid) |',
             '|---|---|---|---|---|---|---|']
    for r in study['slopes']:
        if 'error' in r:
            table.append(f'| {r["slope_deg"]:g} deg | - | - | not run: {r["error"]} | - | - | - |')
            continue
        rigid, b = r['rigid'], r['best']
        head = (f'| {r["slope_deg"]:g} deg | {100 * rigid["speed"]:.2f} | '
                f'{rigid["vibration"]:.3f} |')
        table.append(head + (' none keeps the speed with a reduction | - | - | - |' if b is None
                             else f' {b["stiffness"]:.0f} N/m, damping ratio '
                             f'{b["damping_ratio"]:g} | {b["reduction_pct"]:.1f} % | '
                             f'{100 * b["speed_share"]:.1f} | {b["energy_per_m"]:.2f} '
                             f'({rigid["energy_per_m"]:.2f}) |'))
    if best is None:
        answer = (f'No single structure of the sweep keeps {100 * SPEED_SHARE:g} % of the rigid '
                  f'speed with a reduction on every slope.')
    else:
        each = '; '.join(f'{x:.1f} % at {s:g} deg, at {100 * v:.1f} % of the rigid speed'
                         for x, s, v in zip(best['reductions'], slopes, best['speed_shares']))
        answer = (f'One structure for every slope, at >= {100 * SPEED_SHARE:g} % of the rigid '
                  f'speed on each: {best["stiffness"]:.0f} N/m at a damping ratio of '
                  f'{best["damping_ratio"]:g}, {least_text(best["least"])} than the rigid robot '
                  f'at the same speed (reductions: {each}).')
    worse = ', '.join(
        f'{sum(1 for row in r["rows"] if row["reduction_pct"] < 0.0)} of {len(r["rows"])} at '
        f'{r["slope_deg"]:g} deg' for r in ran)
    outside = [(r['slope_deg'], sum(1 for row in r['rows'] if math.isnan(row['reduction_pct'])),
                r['curve_speeds']) for r in ran]
    unmatched = ' '.join(
        f'At {s:g} deg {count} of the {len(ran[0]["rows"])} flexures crawl outside the speeds '
        f'of the constant-voltage curve of the rigid robot ({100 * low:.2f} to {100 * high:.2f} '
        f'cm/s, +-{100 * ConstantCurve.SPAN:g} % of the voltage): no rigid robot at their speed '
        f'to compare with, so no reduction (missing from the plot, nan in slopes.csv).'
        for s, count, (low, high) in outside if count)
    text = f"""
## From level to vertical

The same sweep on every slope ({', '.join(f'{s:g}' for s in slopes)} degrees, + climbs, at
{base.motor.voltage:g} V), each against the rigid robot on that slope at the same speed (its own
constant-voltage curve), the best structure at >= {100 * SPEED_SHARE:g} % of the rigid speed
there:

{chr(10).join(table)}

{answer}

Flexures that shake the robot more than rigid links: {worse}. {unmatched}
{'' if not shaped or best is None else _shaped_text(shaped, study, best, base)}
![slopes](slopes.png)
"""
    with (out / 'report.md').open('a') as f:
        f.write(text)


# -- with the shaped drive on top, slope by slope --------------------------------------------
SHAPED_GENERATIONS = 60     # shape-drive's default: the level's search settles by then
SHAPED_POPULATION = 12


def shaped_slopes(base: Scenario, slopes_deg: Sequence[float], stiffness: float, ratio: float,
                  link_mass: float = LINK_MASS, generations: int = SHAPED_GENERATIONS,
                  population: int = SHAPED_POPULATION,
                  progress: Optional[Callable[[int], None]] = None) -> List[Dict[str, Any]]:
    """
    Shape the drive of one compliant robot on every slope (the paper's two remedies together).

    On each slope of ``slopes_deg`` (degrees) shape-drive's search (analysis.shape_drive.
    optimise, ``generations`` of ``population`` candidates) finds the voltage profile over the
    helix turn of the robot on flexures of ``stiffness`` and damping ``ratio``, with its
    vibration counted against the rigid robot's constant voltage at the same speed on that slope.
    A row a slope: 'reduction_pct' against that rigid robot (nan with 'why' where it has no
    constant voltage at the shaped speed), 'drive_pct' what the profile takes off the compliant
    robot's own constant voltage at the same speed, 'feasible' (shape_drive: a profile met the
    speed and power constraints and beat the constant voltage; else the constant voltage stands
    and 'drive_pct' is 0), speed, vibration and energy per metre of both; or 'error'.
    ``progress(1)`` after each generation.
    """
    from saw_ros.analysis.shape_drive import optimise
    from saw_ros.core.dynamics import DivergenceError
    flexure = flexure_of(stiffness, ratio, link_mass)
    rows: List[Dict[str, Any]] = []
    for slope in slopes_deg:
        scenario = base.with_values({'conditions.slope': math.radians(slope),
                                     'flexure.stiffness': flexure.stiffness,
                                     'flexure.damping': flexure.damping,
                                     'flexure.link_mass': flexure.link_mass})
        rigid = scenario.with_values({'flexure.stiffness': 0.0, 'flexure.damping': 0.0})
        row: Dict[str, Any] = {'slope_deg': float(slope), 'generations': generations,
                               'population': population}
        try:
            result = optimise(scenario, None, generations, population, reference=rigid,
                              progress=None if progress is None else lambda g, c: progress(1))
        except DivergenceError as exc:
            row['error'] = str(exc)
            rows.append(row)
            continue
        drive = result.shaped if result.feasible else result.constant
        reference = result.reference
        reduction = result.reference_reduction_pct
        row.update({
            'feasible': result.feasible, 'speed': drive['speed'], 'vibration': drive['vibration'],
            'energy_per_m': drive['power'] / drive['speed'],
            'drive_pct': result.vibration_reduction_pct if result.feasible else 0.0,
            'rigid_voltage': result.reference_voltage,
            'rigid_vibration': math.nan if reference is None else reference['vibration'],
            'rigid_energy_per_m': (math.nan if reference is None
                                   else reference['power'] / reference['speed'])})
        if not result.feasible:
            # The constant voltage stands: the compliant robot alone (closed_loop's figures).
            row['reduction_pct'] = math.nan
            row['why'] = 'no profile beat the constant voltage: the flexures alone'
        elif reduction is None:
            row['reduction_pct'] = math.nan
            row['why'] = ("the rigid robot's constant voltage did not reach the shaped speed "
                          f'({100 * drive["speed"]:.3f} cm/s)')
        else:
            row['reduction_pct'] = reduction
        rows.append(row)
    return rows


def _shaped_text(shaped: List[Dict[str, Any]], study: Dict[str, Any], best: Dict[str, Any],
                 base: Scenario) -> str:
    """Return the report's paragraph and table of the robust structure with its shaped drive."""
    alone = _alone(study, best)
    rigid = {r['slope_deg']: r['rigid'] for r in study['slopes'] if 'error' not in r}
    table = ['| slope | flexures alone | with the shaped drive | the drive adds | speed (% of '
             'rigid) | energy (J/m; rigid at the same speed) |', '|---|---|---|---|---|---|']
    for r in shaped:
        s = r['slope_deg']
        # A slope whose sweep left the model has no figure of the flexures alone.
        by_itself = f'{alone[s]:.1f} %' if s in alone else '- (the sweep did not run)'
        if 'error' in r:
            table.append(f'| {s:g} deg | {by_itself} | not run: {r["error"]} | - | - | - |')
            continue
        together = (f'{r["reduction_pct"]:.1f} %' if math.isfinite(r['reduction_pct'])
                    else f'{by_itself} ({r["why"]})' if not r['feasible']
                    else f'- ({r["why"]})')
        share = (f'{100 * r["speed"] / rigid[s]["speed"]:.1f}' if s in rigid else '-')
        table.append(f'| {s:g} deg | {by_itself} | {together} | '
                     f'{r["drive_pct"]:.1f} % | {share} | '
                     f'{r["energy_per_m"]:.2f} ' + (
                         f'({r["rigid_energy_per_m"]:.2f}) |' if r['feasible'] else '(-) |'))
    from saw_ros.analysis.shape_drive import SPEED_TOLERANCE
    search = f'{shaped[0]["generations"]} generations of {shaped[0]["population"]}'
    return f"""
With the shaped drive on top (the paper's two remedies together): on each slope shape-drive's
search ({search}, analysis.shape_drive) finds the voltage profile over the helix turn of the
robot on {best["stiffness"]:.0f} N/m flexures at a damping ratio of {best["damping_ratio"]:g},
its vibration counted against the rigid robot's constant voltage at the same speed on that slope
(the speed within {100 * SPEED_TOLERANCE:g} % of the compliant robot's own at
{base.motor.voltage:g} V, no more power than its constant voltage). Reductions against the
rigid robot at the same speed; "the drive adds": against the compliant robot's own constant
voltage at the same speed. The first can gain more than the drive adds where the shaped drive
crawls faster than the flexures at constant voltage (within its band): the rigid robot it is
compared with shakes more at the higher speed, the compliant one less steeply so.

{chr(10).join(table)}
"""


def _alone(study: Dict[str, Any], best: Dict[str, Any]) -> Dict[float, float]:
    """Return the robust structure's reduction at constant voltage by slope (degrees), %."""
    ran = [r for r in study['slopes'] if 'error' not in r]
    return {r['slope_deg']: x for r, x in zip(ran, best['reductions'])}


def _together(shaped: List[Dict[str, Any]], study: Dict[str, Any],
              best: Dict[str, Any]) -> Dict[float, float]:
    """
    Return the robust structure's reduction with its shaped drive by slope (degrees), %.

    Where no profile beat the constant voltage, that voltage stands: the flexures alone. Slopes
    without a comparison (a run left the model, no rigid robot at the speed) are left out.
    """
    alone = _alone(study, best)
    out = {}
    for r in shaped:
        if 'error' in r:
            continue
        if r['feasible'] and math.isfinite(r['reduction_pct']):
            out[r['slope_deg']] = r['reduction_pct']
        elif not r['feasible'] and r['slope_deg'] in alone:
            out[r['slope_deg']] = alone[r['slope_deg']]
    return out
