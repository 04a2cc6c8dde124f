"""
The paper's next step (Section 8): a drive that calms the robot's vertical vibration.

The paper saw the robot vibrate "vertically in the direction of motion" and proposed "controlled
motor activation with varying speeds" to reduce it. Here the motor's voltage follows a profile
over one helix turn (core.drive.PhaseProfile: a mean voltage and a few Fourier harmonics in the
helix phase, fed forward), and CMA-ES looks for the profile that minimises the vibration

    a_rms = RMS of the body's normal acceleration dv_y/dt over the steady part of a run,

(the COM's acceleration normal to the surfaces: what a passenger of the robot, or the tissue it
crawls through, feels) while keeping the mean speed within SPEED_TOLERANCE of the constant-voltage
drive and the mean electrical power V i no higher. Every generation is one batch of the core
(one scenario per candidate) on the pool, as the calibration's are.

``reference``: another robot whose constant drives the vibration is counted against, at the
same speed; the compliant robot's shaped drive against the rigid robot's constant voltage
(issue 31, docs/compliant_robot.md). The speed and power constraints stay the shaped robot's own.

``motor_bandwidth`` measures what the motor can do at all: the helix speed's modulation per volt
of a single harmonic, against the quasi-static response, at any number of harmonics per turn. The
vibration's energy sits near the link-passing rate (docs/drive.md); where the motor cannot follow
there, no voltage profile can reach it, and the report says so with that measurement.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
import json
import math
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Union

import numpy as np

from saw_ros.core.drive import PhaseProfile, VOLTAGE_LIMIT
from saw_ros.core.dynamics import Simulator
from saw_ros.core.params import ParameterError, Scenario
from saw_ros.core.pool import batches, LocalPool, Pool

SPEED_TOLERANCE = 0.02     # relative: the mean speed stays within 2 % of the constant drive's
HARMONICS = (1, 2, 3, 9, 18)
SETTLE_S = 3.0             # the motor and the contacts settle (CCI < 2 % well before: fidelity)
MEASURE_S = 4.0            # five to six helix turns at 6 V
COEFFICIENT_BOUND = 0.6    # |a_k|, |b_k| <= 0.6 of the mean voltage
PENALTY = 5000.0
# The reference robot's constant drive must reach the shaped drive's speed this closely for the
# two to be compared: near 6 V a 1 % faster robot shakes about 7 % more (docs/drive.md).
SAME_SPEED = 0.005


@dataclass
class DriveOutcome:
    """Steady-state figures of S runs (arrays (S,)): m/s, m/s^2 RMS, W, Hz."""

    speed: np.ndarray
    vibration: np.ndarray
    power: np.ndarray
    helix_hz: np.ndarray
    normal_acceleration: Optional[np.ndarray] = None    # (n, S) over the window, when recorded
    omega: Optional[np.ndarray] = None                  # (n, S) helix speed, rad/s


def evaluate(base: Union[Scenario, Sequence[Scenario]], means, coefficients,
             harmonics: Sequence[int] = HARMONICS, settle: float = SETTLE_S,
             measure: float = MEASURE_S, record: bool = False) -> DriveOutcome:
    """
    Run one scenario per candidate (mean voltage, coefficients) and measure the window.

    ``base``: the scenario of every candidate, or one scenario per candidate (other slopes).
    """
    means = np.atleast_1d(np.asarray(means, float))
    count = len(means)
    scenarios = [base] * count if isinstance(base, Scenario) else list(base)
    if any(s.motor.voltage <= 0.0 for s in scenarios):
        raise ParameterError('shaping the drive needs the motor: set motor.voltage > 0')
    sim = Simulator(scenarios)
    sim.set_profile(PhaseProfile(means, harmonics, coefficients))
    dt = sim.dt
    first, steps = int(round(settle / dt)), int(round((settle + measure) / dt))
    for _ in range(first):
        sim.step()
    n = steps - first
    vx = np.empty((n, count))
    vy = np.empty((n + 1, count))
    power = np.empty((n, count))
    omega = np.empty((n, count))
    vy[0] = sim.q[4]
    for k in range(n):
        sim.step()
        vx[k], vy[k + 1], omega[k] = sim.q[3], sim.q[4], sim.omega
        power[k] = sim.motor.voltage * sim.current
    accel = np.diff(vy, axis=0) / dt
    centred = accel - accel.mean(axis=0)
    return DriveOutcome(vx.mean(axis=0), np.sqrt((centred ** 2).mean(axis=0)),
                        power.mean(axis=0), omega.mean(axis=0) / (2.0 * math.pi),
                        accel if record else None, omega if record else None)


def _evaluate_job(job) -> DriveOutcome:
    base, means, coefficients, harmonics, settle, measure = job
    return evaluate(base, means, coefficients, harmonics, settle, measure)


def evaluate_on(pool: Pool, base: Scenario, means, coefficients,
                harmonics: Sequence[int] = HARMONICS, settle: float = SETTLE_S,
                measure: float = MEASURE_S) -> DriveOutcome:
    """``evaluate`` with the candidates cut into the pool's parts (one batch each)."""
    means = np.atleast_1d(np.asarray(means, float))
    coefficients = np.asarray(coefficients, float).reshape(len(means), 2 * len(harmonics))
    parts = batches(list(range(len(means))), pool.workers)
    jobs = [(base, means[p], coefficients[p], tuple(harmonics), settle, measure) for p in parts]
    done = list(pool.map(_evaluate_job, jobs))
    return DriveOutcome(*(np.concatenate([getattr(d, name) for d in done])
                          for name in ('speed', 'vibration', 'power', 'helix_hz')))


@dataclass
class ShapeResult:
    """
    What the search found, against two constant drives.

    ``constant``: the constant ``base_voltage`` the search started from (the speed to keep);
    ``matched``: the constant voltage ``matched_voltage`` that gives the shaped drive's own mean
    speed, measured: the fair reference, since the vibration rises steeply with the speed
    (docs/drive.md). The reduction is counted against ``matched``.
    """

    base_voltage: float
    harmonics: List[int]
    mean_voltage: float
    coefficients: List[float]
    constant: Dict[str, float]
    shaped: Dict[str, float]
    matched_voltage: float
    matched: Dict[str, float]
    feasible: bool      # the shaped drive met the constraints and beat the constant one
    generations: int
    history: List[Dict[str, float]] = field(default_factory=list)
    # The reference robot's constant drive at the shaped drive's speed (optimise(reference=)).
    reference_voltage: Optional[float] = None
    reference: Optional[Dict[str, float]] = None

    @property
    def vibration_reduction_pct(self) -> float:
        return 100.0 * (1.0 - self.shaped['vibration'] / self.matched['vibration'])

    @property
    def reference_reaches_speed(self) -> bool:
        """Whether the reference robot's constant drive ran at the shaped drive's speed."""
        return self.reference is not None and abs(
            self.reference['speed'] / self.shaped['speed'] - 1.0) <= SAME_SPEED

    @property
    def reference_reduction_pct(self) -> Optional[float]:
        """Return the reduction against the reference robot at the same speed, % (None: none)."""
        if self.reference is None or not self.reference_reaches_speed:
            return None
        return 100.0 * (1.0 - self.shaped['vibration'] / self.reference['vibration'])

    def profile(self) -> PhaseProfile:
        return PhaseProfile([self.mean_voltage], self.harmonics, [self.coefficients])


def _figures(outcome: DriveOutcome, i: int) -> Dict[str, float]:
    return {'speed': float(outcome.speed[i]), 'vibration': float(outcome.vibration[i]),
            'power': float(outcome.power[i]), 'helix_hz': float(outcome.helix_hz[i])}


class ConstantCurve:
    """Constant-voltage drives around the base voltage: speed, vibration and power per voltage."""

    SPAN = 0.08     # +-8 % of the voltage: wider than the speed band the search may use

    def __init__(self, base: Scenario, harmonics: Sequence[int], points: int = 9):
        self.voltage = base.motor.voltage * np.linspace(1 - self.SPAN, 1 + self.SPAN, points)
        outcome = evaluate(base, self.voltage, np.zeros((points, 2 * len(harmonics))),
                           harmonics)
        order = np.argsort(outcome.speed)
        self.speed = outcome.speed[order]
        self.vibration = outcome.vibration[order]
        self.power = outcome.power[order]
        self.voltage = self.voltage[order]

    def at(self, speed, values: np.ndarray) -> np.ndarray:
        return np.interp(speed, self.speed, values)


def cost(outcome: DriveOutcome, curve: ConstantCurve, speed: float,
         reference: Optional[ConstantCurve] = None) -> np.ndarray:
    """
    Vibration over a constant drive's at the same speed, plus penalties past the constraints.

    ``reference``: the constant drives of another robot to count the vibration against (the
    power stays against ``curve``, the shaped robot's own).

    Quadratic penalties outside the speed band (kept at 3/4 of SPEED_TOLERANCE) and above 99.5 %
    of the constant drive's power at the same speed: margins, so that the best candidate still
    meets both against the constant drive measured at its speed afterwards (the curve is an
    interpolation).
    """
    speed_off = np.abs(outcome.speed / speed - 1.0) - 0.75 * SPEED_TOLERANCE
    power_over = outcome.power / curve.at(outcome.speed, curve.power) - 0.995
    # Stalled or reversed runs (a profile that drops to 0 V) sit far outside the band.
    against = curve if reference is None else reference
    return (outcome.vibration / against.at(outcome.speed, against.vibration)
            + PENALTY * np.maximum(speed_off, 0.0) ** 2
            + PENALTY * np.maximum(power_over, 0.0) ** 2)


def matched_constant(base: Scenario, speed: float, curve: ConstantCurve,
                     harmonics: Sequence[int], tolerance: float = 1e-3):
    """Return (voltage, figures) of the constant drive at ``speed``, found by secant steps."""
    voltage = float(np.interp(speed, curve.speed, curve.voltage))
    dims = 2 * len(harmonics)
    for _ in range(4):
        figures = _figures(evaluate(base, [voltage], np.zeros((1, dims)), harmonics), 0)
        if abs(figures['speed'] / speed - 1.0) <= tolerance:
            break
        # Speed per volt from the curve's neighbours of this voltage.
        slope = float(np.interp(voltage, np.sort(curve.voltage), np.gradient(
            curve.speed[np.argsort(curve.voltage)], np.sort(curve.voltage))))
        voltage += (speed - figures['speed']) / slope
    return voltage, figures


def feasible(shaped: Dict[str, float], constant: Dict[str, float],
             matched: Dict[str, float]) -> bool:
    return (abs(shaped['speed'] / constant['speed'] - 1.0) <= SPEED_TOLERANCE
            and shaped['power'] <= matched['power'] and shaped['vibration'] <
            matched['vibration'])


def optimise(base: Scenario, pool: Optional[Pool] = None, generations: int = 60,
             population: int = 12, sigma: float = 0.08, seed: int = 1,
             harmonics: Sequence[int] = HARMONICS,
             progress: Optional[Callable[[int, float], None]] = None,
             reference: Optional[Scenario] = None) -> ShapeResult:
    """
    Search the profile (CMA-ES) that keeps the speed of the constant base.motor.voltage.

    ``reference``: a robot (the rigid one, for a compliant ``base``) whose constant drives the
    vibration is minimised against, at the same speed; measured at the end beside ``matched``.
    """
    from cmaes import CMA  # noqa: I100: only the search needs it (a dependency of calibrate)

    pool = pool if pool is not None else LocalPool(1)
    harmonics = [int(h) for h in harmonics]
    voltage = base.motor.voltage
    dims = 2 * len(harmonics)
    start_outcome = evaluate(base, [voltage], np.zeros((1, dims)), harmonics)
    const = _figures(start_outcome, 0)
    curve = ConstantCurve(base, harmonics)
    reference_curve = None if reference is None else ConstantCurve(reference, harmonics)
    # The mean voltage within +-15 %: the speed may move 2 %, and the profile's shape changes
    # the speed a mean voltage gives by a few per cent.
    low = np.r_[0.85 * voltage, np.full(dims, -COEFFICIENT_BOUND)]
    high = np.r_[min(1.15 * voltage, VOLTAGE_LIMIT), np.full(dims, COEFFICIENT_BOUND)]
    # CMA-ES in [0, 1] coordinates: one step size fits the voltage and the coefficients.
    span = high - low
    start = (np.r_[voltage, np.zeros(dims)] - low) / span
    search = CMA(mean=start, sigma=sigma, bounds=np.c_[np.zeros(dims + 1), np.ones(dims + 1)],
                 population_size=population, seed=seed)
    # The constant drive's own cost (1 against its own curve, to interpolation) is the bar.
    best_x, best_fig = np.r_[voltage, np.zeros(dims)], const
    best_cost = float(cost(start_outcome, curve, const['speed'], reference_curve)[0])
    history = []
    for generation in range(generations):
        unit = [search.ask() for _ in range(search.population_size)]
        x = low + np.array(unit) * span
        outcome = evaluate_on(pool, base, x[:, 0], x[:, 1:], harmonics)
        costs = cost(outcome, curve, const['speed'], reference_curve)
        search.tell(list(zip(unit, costs)))
        i = int(np.argmin(costs))
        if costs[i] < best_cost:
            best_x, best_cost, best_fig = x[i], float(costs[i]), _figures(outcome, i)
        history.append({'generation': generation, 'best_cost': best_cost,
                        'generation_cost': float(costs[i])})
        if progress is not None:
            progress(generation, best_cost)
    matched_voltage, matched = matched_constant(base, best_fig['speed'], curve, harmonics)
    reference_voltage, reference_figures = None, None
    if reference is not None and reference_curve is not None:
        reference_voltage, reference_figures = matched_constant(
            reference, best_fig['speed'], reference_curve, harmonics)
    return ShapeResult(voltage, harmonics, float(best_x[0]), [float(c) for c in best_x[1:]],
                       const, best_fig, matched_voltage, matched,
                       feasible(best_fig, const, matched), generations, history,
                       reference_voltage, reference_figures)


def spectrum(signal: np.ndarray, dt: float):
    """Return (frequencies Hz, one-sided power) of a signal with its mean removed (Hann)."""
    signal = np.asarray(signal, float)
    window = np.hanning(len(signal))
    power = np.abs(np.fft.rfft((signal - signal.mean()) * window)) ** 2
    return np.fft.rfftfreq(len(signal), dt), power


def band_shares(frequencies, power, helix_hz: float, links_per_wave: float) -> Dict[str, float]:
    """
    Split the vibration's power into the bands of its sources, each a share of the total.

    helix: below 1.5 helix rates (the turn itself); link passing: within 40 % of the rate at
    which links cross the crests (links per wavelength times the helix rate) and its second
    multiple; above: the rest (the contacts' own modes, impacts).
    """
    total = float(power.sum()) or 1.0
    passing = links_per_wave * helix_hz
    helix = frequencies < 1.5 * helix_hz
    near = (np.abs(frequencies - passing) <= 0.4 * passing) | (
        np.abs(frequencies - 2.0 * passing) <= 0.4 * passing)
    return {'helix_rate': float(power[helix].sum()) / total,
            'link_passing': float(power[near & ~helix].sum()) / total,
            'other': float(power[~helix & ~near].sum()) / total,
            'link_passing_hz': passing}


HARMONIC_BARS = 40


def harmonic_power(frequencies, power, helix_hz: float, count: int) -> np.ndarray:
    """Return the share of ``power`` within half a helix rate of each multiple 1..count of it."""
    total = float(power.sum()) or 1.0
    return np.array([power[np.abs(frequencies - k * helix_hz) < 0.5 * helix_hz].sum() / total
                     for k in range(1, count + 1)])


def motor_bandwidth(base: Scenario, harmonics: Sequence[int], depth: float = 0.2,
                    settle: float = SETTLE_S, measure: float = MEASURE_S) -> Dict[int, float]:
    """
    Measure the helix speed's response to a voltage ripple of ``depth`` at each harmonic.

    Returns, per harmonic k, the ripple of omega at k per turn over the ripple an instant
    (quasi-static) motor would show, |d omega| / (depth * mean omega): 1 means the motor follows
    the profile fully at that rate, 0.1 that a profile reaches the helix at a tenth of its depth.
    """
    harmonics = [int(h) for h in harmonics]
    coefficients = np.zeros((len(harmonics), 2 * len(harmonics)))
    for i in range(len(harmonics)):
        coefficients[i, i] = depth
    single = [evaluate(base, [base.motor.voltage], coefficients[i:i + 1], harmonics, settle,
                       measure, record=True) for i in range(len(harmonics))]
    out = {}
    for k, outcome in zip(harmonics, single):
        if outcome.omega is None:
            raise RuntimeError('evaluate(record=True) kept no helix speed')
        omega = outcome.omega[:, 0]
        frequencies, power = spectrum(omega, base.integration.dt)
        target = k * outcome.helix_hz[0]
        near = np.abs(frequencies - target) <= 0.15 * outcome.helix_hz[0]
        # Amplitude of a sinusoid from the Hann-windowed spectrum: 2 |X| / sum(window) ... with
        # the window's coherent gain 1/2: 4 |X| / n.
        amplitude = 4.0 * math.sqrt(float(power[near].max())) / len(omega)
        out[k] = amplitude / (depth * float(np.mean(omega)))
    return out


SLOPES_DEG = (-20.0, 0.0, 20.0, 45.0, 90.0)
BANDWIDTH_HARMONICS = (1, 2, 3, 9, 18)


def _plt():
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    return plt


def across_slopes(result: ShapeResult, base: Scenario,
                  slopes_deg: Sequence[float] = SLOPES_DEG) -> List[Dict[str, float]]:
    """Run the level's profile and the constant drive at each slope, one batch; a row each."""
    scenarios = [base.with_values({'conditions.slope': math.radians(d)}) for d in slopes_deg]
    dims = 2 * len(result.harmonics)
    count = len(scenarios)
    means = np.r_[np.full(count, result.base_voltage), np.full(count, result.mean_voltage)]
    coefficients = np.r_[np.zeros((count, dims)), np.tile(result.coefficients, (count, 1))]
    outcome = evaluate(scenarios * 2, means, coefficients, result.harmonics)
    rows = []
    for i, slope in enumerate(slopes_deg):
        constant, shaped = _figures(outcome, i), _figures(outcome, count + i)
        rows.append({'slope_deg': float(slope),
                     'constant_speed_cm_s': 100.0 * constant['speed'],
                     'shaped_speed_cm_s': 100.0 * shaped['speed'],
                     'constant_power_W': constant['power'], 'shaped_power_W': shaped['power'],
                     'constant_vibration_m_s2': constant['vibration'],
                     'shaped_vibration_m_s2': shaped['vibration'],
                     'vibration_reduction_pct':
                         100.0 * (1.0 - shaped['vibration'] / constant['vibration'])})
    return rows


def write_report(result: ShapeResult, base: Scenario, out_dir: Path,
                 slopes_deg: Sequence[float] = SLOPES_DEG) -> Dict[str, Any]:
    """Spectra, profile, slopes and the motor's bandwidth: PNGs, result.json and report.md."""
    out_dir.mkdir(parents=True, exist_ok=True)
    plt = _plt()
    dims = 2 * len(result.harmonics)
    runs = evaluate(base, [result.matched_voltage, result.mean_voltage],
                    np.r_[np.zeros((1, dims)), [result.coefficients]], result.harmonics,
                    record=True)
    dt = base.integration.dt
    links_per_wave = base.robot.wavelength / base.robot.link
    shares = []
    per_harmonic = []
    acceleration = runs.normal_acceleration
    if acceleration is None:
        raise RuntimeError('evaluate(record=True) kept no normal acceleration')
    for i in range(2):
        frequencies, power = spectrum(acceleration[:, i], dt)
        shares.append(band_shares(frequencies, power, runs.helix_hz[i], links_per_wave))
        per_harmonic.append(harmonic_power(frequencies, power, runs.helix_hz[i], HARMONIC_BARS)
                            * runs.vibration[i] ** 2)
    # The vibration repeats with the helix turn: its spectrum is lines at multiples of the helix
    # rate, so one bar per multiple reads better than the raw spectrum.
    fig, ax = plt.subplots(figsize=(9, 4.5))
    k = np.arange(1, HARMONIC_BARS + 1)
    for i, (label, shift) in enumerate(((f'constant {result.matched_voltage:.3f} V', -0.2),
                                        ('shaped drive', 0.2))):
        ax.bar(k + shift, per_harmonic[i], 0.4, label=f'{label}: RMS '
               f'{runs.vibration[i]:.2f} m/s$^2$')
    ax.set_yscale('log')
    for multiple, name in ((links_per_wave, 'link passing'), (2 * links_per_wave, 'x 2')):
        ax.axvline(multiple, color='grey', ls=':', lw=1)
        ax.text(multiple, 1.0, f' {name}', transform=ax.get_xaxis_transform(), va='top',
                fontsize=8, color='grey')
    ax.set_xlabel(f'multiple of the helix rate ({runs.helix_hz[0]:.2f} Hz)')
    ax.set_ylabel('mean square normal acceleration (m$^2$/s$^4$)')
    ax.set_title('Where the vertical vibration sits (level, both drives at the same speed)')
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / 'spectrum.png', dpi=100)
    plt.close(fig)

    turn = result.profile().over_turn(360)[0]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(np.arange(360), turn, label='shaped drive')
    ax.axhline(result.base_voltage, color='grey', ls='--', label='constant voltage')
    ax.set_xlabel('helix phase (deg)')
    ax.set_ylabel('motor voltage (V)')
    ax.set_title(f'Voltage over one helix turn (harmonics {result.harmonics})')
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / 'profile.png', dpi=100)
    plt.close(fig)

    rows = across_slopes(result, base, slopes_deg)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    x = np.arange(len(rows))
    for ax, key, label in zip(axes, ('speed_cm_s', 'power_W', 'vibration_m_s2'),
                              ('mean speed (cm/s)', 'mean electrical power (W)',
                               'RMS normal acceleration (m/s$^2$)')):
        ax.bar(x - 0.2, [r[f'constant_{key}'] for r in rows], 0.4, label='constant')
        ax.bar(x + 0.2, [r[f'shaped_{key}'] for r in rows], 0.4, label='shaped')
        ax.set_xticks(x, [f'{r["slope_deg"]:g} deg' for r in rows])
        ax.set_ylabel(label)
    axes[0].legend()
    fig.suptitle("The level's profile across slopes")
    fig.tight_layout()
    fig.savefig(out_dir / 'slopes.png', dpi=100)
    plt.close(fig)

    if result.history:
        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.plot([h['generation'] for h in result.history],
                [h['best_cost'] for h in result.history])
        ax.set_xlabel('generation')
        ax.set_ylabel('best feasible relative vibration')
        fig.tight_layout()
        fig.savefig(out_dir / 'convergence.png', dpi=100)
        plt.close(fig)

    bandwidth = motor_bandwidth(base, BANDWIDTH_HARMONICS)
    summary = {'result': asdict(result), 'flexure': asdict(base.flexure),
               'vibration_reduction_pct': result.vibration_reduction_pct,
               'vibration_reduction_vs_base_pct':
                   100.0 * (1.0 - result.shaped['vibration'] / result.constant['vibration']),
               'speed_change_pct': 100.0 * (result.shaped['speed'] / result.constant['speed']
                                            - 1.0),
               'power_change_pct': 100.0 * (result.shaped['power'] / result.matched['power']
                                            - 1.0),
               'reference_reduction_pct': result.reference_reduction_pct,
               'band_shares': {'constant': shares[0], 'shaped': shares[1]},
               'motor_bandwidth': {str(k): v for k, v in bandwidth.items()},
               'slopes': rows}
    (out_dir / 'result.json').write_text(json.dumps(summary, indent=1) + '\n')
    (out_dir / 'report.md').write_text(report_text(summary))
    return summary


def link_passing_sentence(bandwidth: Dict[str, float], share: float,
                          reduction_pct: float) -> str:
    """Say what the measured motor response at the link-passing harmonic means for a profile."""
    passing = min(bandwidth, key=lambda k: abs(int(k) - 9))
    response = bandwidth[passing]
    if response < 0.5:
        return (f'{100 * share:.0f} % of the vibration sits at the link-passing rate, where this '
                f'motor passes {100 * response:.0f} % of a voltage ripple to the helix (harmonic '
                f'{passing}): the rotor inertia behind the winding resistance filters it out. A '
                f'profile then works through the low harmonics (reshaping the turn), and the '
                f'reduction stops at {reduction_pct:.0f} %; a drive that follows the link-passing '
                'rate (a tenth of the reflected inertia: docs/drive.md) reaches further.')
    return (f'{100 * share:.0f} % of the vibration sits at the link-passing rate, and this motor '
            f'passes {100 * response:.0f} % of a voltage ripple there (harmonic {passing}): the '
            f'profile acts on it directly ({reduction_pct:.0f} % less vibration).')


def reference_text(r: Dict[str, Any], reduction_pct: Optional[float]) -> List[str]:
    """Return the report's lines on the reference (rigid) robot at the shaped drive's speed."""
    rigid, shaped, matched = r['reference'], r['shaped'], r['matched']
    if reduction_pct is None:
        return ['', '## Against the rigid robot', '',
                f'NO comparison: the rigid robot (this scenario with `flexure.stiffness` = 0) '
                f'did not reach the shaped drive\'s {100 * shaped["speed"]:.3f} cm/s at a '
                f'constant voltage (nearest: {100 * rigid["speed"]:.3f} cm/s at '
                f'{r["reference_voltage"]:.3f} V), so the vibrations cannot be compared at the '
                f'same speed.']
    return [
        '', '## Against the rigid robot', '',
        f'The rigid robot (this scenario with `flexure.stiffness` = 0) at the constant '
        f'{r["reference_voltage"]:.3f} V that gives the shaped drive\'s speed, measured: '
        f'{rigid["vibration"]:.3f} m/s^2 RMS. Flexures and shaped drive together'
        + ('' if r['feasible'] else ' (no profile beat the constant drive: its figures)')
        + f': '
        f'{shaped["vibration"]:.3f} m/s^2 RMS, {reduction_pct:.1f} % less at the same speed; '
        f'the flexures alone (constant {r["matched_voltage"]:.3f} V) '
        f'{100.0 * (1.0 - matched["vibration"] / rigid["vibration"]):.1f} % less. Electrical '
        f'energy per metre: rigid {rigid["power"] / rigid["speed"]:.2f} J/m, flexures '
        f'{matched["power"] / matched["speed"]:.2f} J/m, flexures and shaped drive '
        f'{shaped["power"] / shaped["speed"]:.2f} J/m.']


def report_text(summary: Dict[str, Any]) -> str:
    """Return the markdown report, every number from ``summary`` (written by write_report)."""
    r = summary['result']
    before, after = summary['band_shares']['constant'], summary['band_shares']['shaped']
    bandwidth = summary['motor_bandwidth']
    lines = [
        '# A drive that calms the vibration (generated by `saw-ros shape-drive`)', '',
        f'The best profile found in {r["generations"]} generations (harmonics '
        f'{r["harmonics"]} of the helix turn, mean {r["mean_voltage"]:.3f} V) against the '
        f'constant {r["base_voltage"]:g} V it started from and against the constant voltage '
        f'that gives the shaped drive\'s own speed ({r["matched_voltage"]:.3f} V, measured), on '
        'the level. The vibration rises steeply with the speed, so the reduction is counted '
        'at the same speed:', '',
        f'| | constant {r["base_voltage"]:g} V | constant {r["matched_voltage"]:.3f} V | '
        'shaped |', '|---|---|---|---|',
        *(f'| {label} | {scale * r["constant"][key]:{fmt}} | {scale * r["matched"][key]:{fmt}} '
          f'| {scale * r["shaped"][key]:{fmt}} |'
          for label, key, scale, fmt in (('mean speed (cm/s)', 'speed', 100.0, '.3f'),
                                         ('mean electrical power (W)', 'power', 1.0, '.4f'),
                                         ('RMS normal acceleration (m/s^2)', 'vibration', 1.0,
                                          '.3f'))),
        '', f'Shaped against the constant drive at the same speed: vibration '
        f'{-summary["vibration_reduction_pct"]:+.1f} %, power {summary["power_change_pct"]:+.2f}'
        f' %; its speed is {summary["speed_change_pct"]:+.2f} % off the {r["base_voltage"]:g} V '
        f"drive's (against which the vibration is "
        f'{-summary["vibration_reduction_vs_base_pct"]:+.1f} %).',
        '', f'Constraints: speed within {100 * SPEED_TOLERANCE:g} %, power no higher. '
        + ('The shaped drive meets them.' if r['feasible'] else
           'NO candidate beat the constant drive within them: the constant drive stands (run '
           'more generations).'),
        *([] if r.get('reference') is None else
          reference_text(r, summary['reference_reduction_pct'])),
        '', '![spectrum](spectrum.png)', '',
        "## Where the vibration's energy sits", '',
        f"Share of the normal acceleration's power (link passing: "
        f'{before["link_passing_hz"]:.1f} Hz, links per wavelength times the helix rate):', '',
        '| band | constant | shaped |', '|---|---|---|',
        *(f'| {name.replace("_", " ")} | {100 * before[name]:.1f} % | {100 * after[name]:.1f} % |'
          for name in ('helix_rate', 'link_passing', 'other')),
        '', '## What the motor can reach', '',
        "The helix speed's ripple per harmonic of a 20 % voltage ripple, against what an "
        'instant (quasi-static) motor would give (1 = follows fully):', '',
        '| harmonic (per turn) | response |', '|---|---|',
        *(f'| {k} | {v:.3f} |' for k, v in bandwidth.items()),
        '', link_passing_sentence(bandwidth, before['link_passing'],
                                  summary['vibration_reduction_pct']), '',
        '![profile](profile.png)', '', "## Across slopes (the level's profile)", '',
        '| slope | speed constant / shaped (cm/s) | power constant / shaped (W) | vibration '
        'reduction |', '|---|---|---|---|',
        *(f'| {s["slope_deg"]:g} deg | {s["constant_speed_cm_s"]:.2f} / '
          f'{s["shaped_speed_cm_s"]:.2f} | {s["constant_power_W"]:.3f} / '
          f'{s["shaped_power_W"]:.3f} | {s["vibration_reduction_pct"]:.1f} % |'
          for s in summary['slopes']),
        '', '![slopes](slopes.png)', '']
    return '\n'.join(lines)
