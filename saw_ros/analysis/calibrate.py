"""
Fit unknown model parameters to measured speeds and advance ratios (``saw-ros calibrate``).

Targets are conditions (slope, motor voltage or helix frequency) with a measured speed or AR: a
CSV in the format of ``msg_config/reference_paper.csv`` or of the footage campaign's
``footage.csv``, or the shipped default, the numbers the paper states (its three measured speeds
and the level and vertical AR of Figure 21 at constant 1 Hz, claims A1 and A2).

The optimiser is CMA-ES (the ``cmaes`` package) in normalised coordinates: every parameter maps
its bounds onto [0, 1] (logarithmically for those spanning a factor of 4 or more, e.g. a
stiffness), so one step size fits all. One generation is one batch of our engine: every candidate
under every target condition, stepped together by ``core.dynamics.simulate`` (candidates that
change the robot's geometry go in batches of their own, the engine steps one robot at a time).
The objective is the mean squared relative error over the targets.

After every generation the state (generation, the pickled optimiser, the best candidate so far,
the history) is written to the output folder; ``resume`` continues from it and, because the
optimiser's random generator is reseeded from (seed, generation) before every generation, ends
where an uninterrupted run with the same seed would.

The uncertainty is local and says what it is: the relative change of every target per relative
change of every parameter at the optimum (central differences, one batch), and from it a
linearised covariance of the parameters for a target error of the fit's own RMS residual (at
least 2 %): which parameters the targets pin down, which directions are flat, which pairs trade
off against each other. The spread of CMA-ES's last population is reported beside it.
No rclpy import.
"""
from __future__ import annotations

import csv
from dataclasses import asdict, dataclass, field
import json
import math
from pathlib import Path
import pickle
import time
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from saw_ros.core.dynamics import DivergenceError, simulate
from saw_ros.core.metrics import analyse
from saw_ros.core.params import ParameterError, Scenario
from saw_ros.core.pool import batches, Pool
from saw_ros.interface.config import config_path

STATE_FILE = 'state.pkl'
RESULT_FILE = 'result.json'
HISTORY_FILE = 'history.csv'
STATE_VERSION = 1
# A candidate whose simulation diverged or never moved: as bad as a 300 % error on every target.
FAILED_LOSS = 9.0
# Relative step of the finite differences around the optimum.
SENSITIVITY_STEP = 0.05
# Floor of the target error used for the parameter uncertainty: the paper states its speeds to
# two or three digits and its AR read off a figure; a perfect fit does not make them exact.
MIN_TARGET_ERROR = 0.02
# A parameter is pinned down when its 1-sigma band is within +-20 % of its value.
IDENTIFIED_REL_STD = 0.20
CORRELATED = 0.9
RECORD_EVERY = 5             # 5 ms samples for speed and AR, as the figure sweeps

# The paper's Figure 21 ARs at its default set-up (claims A1 and A2 of the fidelity report).
PAPER_AR = ((0.0, 0.72, 'A1', 'Sec. 8, Fig. 21: wave AR on the level at the defaults'),
            (90.0, 0.61, 'A2', 'Sec. 8, Fig. 21: wave AR climbing vertically at the defaults'))

# Physical bounds of the parameters a bare --params name takes (why each: docs/calibration.md).
DEFAULT_PARAMETERS = (
    # The paper gives "about 1200 N/m" for a nonlinear foam without the depth it holds at: a
    # secant stiffness of 600-2400 N/m ("about": a factor 2 either way) at the 6 mm squeeze.
    ('surface.normal_stiffness', 600.0 / 0.006 ** 0.5, 2400.0 / 0.006 ** 0.5),
    # Not given: from a dead foam (0.1, memory foam) to a perfectly elastic one.
    ('surface.restitution', 0.1, 1.0),
    # Our own regularisation of the hysteresis switch: 2-50 mm/s.
    ('surface.hysteresis_speed', 0.002, 0.05),
    # Not given: 0.24 Hz/V makes the paper's 6 V run 1.44 Hz; a 12 V class gear motor at
    # 0.15-0.35 Hz/V turns its helix at 0.6-2.5 Hz over 4-7 V.
    ('motor.hz_per_volt', 0.15, 0.35),
)
# The DC motor's load constants: winding resistance (ohm) and friction torque at the helix.
MOTOR_PARAMETERS = (
    ('motor.resistance', 1.0, 40.0),
    ('motor.friction_torque', 0.0, 0.06),
)
# What is fitted when no --params is given: the motor, which the measured speeds pin down and no
# claim of the fidelity report depends on (they all run at constant frequency). The surface's
# constants fit the paper's two ARs only at the cost of nine held-out claims, and the targets do
# not pin them down (docs/calibration.md): they are there to choose, not the default.
DEFAULT_FIT = ('motor.hz_per_volt', 'motor.resistance', 'motor.friction_torque')


def sweeps_duration() -> float:
    """Return the simulated time per point of the figure sweeps (full grids), s."""
    from saw_ros.analysis.figures.sweeps import FULL
    return FULL.duration


class CalibrationError(ValueError):
    """Targets or parameters that cannot be used; the message says which and why."""


# -- targets --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Target:
    """One measured number under one condition."""

    name: str
    slope_deg: float
    quantity: str                  # 'speed' (m/s) or 'ar'
    measured: float
    voltage: Optional[float] = None
    frequency: Optional[float] = None
    claim: str = ''                # the fidelity report's claim it trains on, if any
    source: str = ''

    def condition(self) -> Dict[str, float]:
        values = {'conditions.slope': math.radians(self.slope_deg)}
        if self.voltage is not None:
            values['motor.voltage'] = self.voltage
        else:
            values.update({'motor.voltage': 0.0, 'conditions.frequency': self.frequency})
        return values

    @property
    def label(self) -> str:
        drive = f'{self.voltage:g} V' if self.voltage is not None else f'{self.frequency:g} Hz'
        what = 'speed' if self.quantity == 'speed' else 'AR'
        return f'{what} {self.slope_deg:+g} deg {drive}'

    def display(self, value: float) -> str:
        if self.quantity == 'speed':
            return f'{100.0 * value:.2f} cm/s'
        return f'{value:.3f}'


def _number(text: Optional[str], where: str, name: str) -> Optional[float]:
    text = (text or '').strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        raise CalibrationError(f'{where}: {name} = {text!r} is not a number') from None
    if not math.isfinite(value):
        raise CalibrationError(f'{where}: {name} = {text!r} is not finite')
    return value


def load_targets(path) -> List[Target]:
    """
    Read targets from a CSV, either format.

    - ``reference_paper.csv``'s: slope_deg, voltage_V (or frequency_hz), speed_cm_s and/or
      advance_ratio, source;
    - the footage campaign's ``footage.csv``: video, slope_deg, voltage_V, frequency_hz,
      v_measured (m/s), ar_measured, ...

    A row gives one target: its speed when it has one, else its AR. (Where the helix frequency is
    given, AR and speed say the same; where the voltage drives the helix, footage.csv's AR was
    divided by the frequency the campaign assumed, a model parameter here, so the speed is the
    measurement.) Lines starting with # are comments.
    """
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f'no such targets file: {path}')
    try:
        with open(path, newline='') as f:
            lines = [line for line in f if line.strip() and not line.lstrip().startswith('#')]
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f'{path}: cannot read: {exc}') from None
    if not lines:
        raise CalibrationError(f'{path}: empty (no header, no targets)')
    reader = csv.DictReader(lines)
    columns = [c.strip() for c in reader.fieldnames or []]
    reader.fieldnames = columns
    speed_cols = {'speed_cm_s', 'v_measured'} & set(columns)
    ar_cols = {'advance_ratio', 'ar_measured'} & set(columns)
    if 'slope_deg' not in columns or not ({'voltage_V', 'frequency_hz'} & set(columns)) or not (
            speed_cols or ar_cols):
        raise CalibrationError(
            f'{path}: needs columns slope_deg, voltage_V and/or frequency_hz, and a measured '
            f'speed (speed_cm_s, or v_measured in m/s as footage.csv has it) and/or AR '
            f'(advance_ratio '
            f'or ar_measured); found {", ".join(columns) or "nothing"}')
    targets = []
    for line, row in enumerate(reader, start=2):
        where = f'{path}, row {line}'
        if None in row:
            raise CalibrationError(f'{where}: more fields than columns')
        row = {k: (v or '').strip() for k, v in row.items()}
        slope = _number(row.get('slope_deg'), where, 'slope_deg')
        if slope is None or abs(slope) > 90:
            raise CalibrationError(f'{where}: slope_deg must be given, in [-90, 90] deg')
        voltage = _number(row.get('voltage_V'), where, 'voltage_V')
        frequency = _number(row.get('frequency_hz'), where, 'frequency_hz')
        if voltage is not None and not voltage > 0:
            raise CalibrationError(f'{where}: voltage_V = {voltage:g} must be > 0')
        if voltage is None and (frequency is None or not frequency > 0):
            raise CalibrationError(f'{where}: needs voltage_V or frequency_hz (> 0)')
        if voltage is not None:
            frequency = None          # the voltage drives the helix; footage.csv notes both
        speed = _number(row.get('speed_cm_s'), where, 'speed_cm_s')
        if speed is not None:
            speed /= 100.0
        else:
            speed = _number(row.get('v_measured'), where, 'v_measured')
        ar = _number(row.get('advance_ratio') or row.get('ar_measured'), where, 'advance_ratio')
        if speed is None and ar is None:
            raise CalibrationError(f'{where}: no measured speed or AR')
        quantity, measured = ('speed', speed) if speed is not None else ('ar', ar)
        if not measured > 0:
            raise CalibrationError(f'{where}: the measured {quantity} must be > 0 (a robot that '
                                   f'did not advance cannot be fitted by relative error)')
        name = row.get('video') or row.get('source') or f'row {line}'
        targets.append(Target(name, slope, quantity, measured, voltage, frequency,
                              source=row.get('source') or row.get('notes') or str(path)))
    if not targets:
        raise CalibrationError(f'{path}: no targets (a header but no rows)')
    return targets


def paper_targets() -> List[Target]:
    """Return the shipped default: the paper's three measured speeds, its level and vertical AR."""
    targets = load_targets(config_path('reference_paper.csv'))
    for slope, ar, claim, source in PAPER_AR:
        targets.append(Target(f'AR {slope:g} deg', slope, 'ar', ar, frequency=1.0, claim=claim,
                              source=source))
    return targets


# -- parameters -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Parameter:
    """One fitted parameter: its dotted name and bounds (SI), mapped onto [0, 1]."""

    name: str
    low: float
    high: float
    log: bool
    unit: str = ''

    def value(self, u: float) -> float:
        u = min(1.0, max(0.0, float(u)))
        if self.log:
            return float(math.exp(math.log(self.low) + u * math.log(self.high / self.low)))
        return float(self.low + u * (self.high - self.low))

    def unit_of(self, value: float) -> float:
        if self.log:
            u = math.log(value / self.low) / math.log(self.high / self.low)
        else:
            u = (value - self.low) / (self.high - self.low)
        return min(1.0, max(0.0, u))


def _allowed(meta, value: float) -> bool:
    low, high = meta['low'], meta['high']
    if low is not None and (value < low or (meta['low_open'] and value == low)):
        return False
    if high is not None and (value > high or (meta['high_open'] and value == high)):
        return False
    return True


def make_parameters(specs: Sequence, base: Optional[Scenario] = None) -> List[Parameter]:
    """
    Return the parameters of ``specs``: 'name', 'name:low:high' or (name, low, high) tuples.

    A bare name takes its bounds from DEFAULT_PARAMETERS / MOTOR_PARAMETERS. Unknown names,
    conditions (they are the targets'), bounds outside the Scenario's range or in the wrong
    order raise CalibrationError.
    """
    base = base or Scenario()
    known = {name: (value, meta) for name, value, meta in base.describe()}
    defaults = {name: (low, high) for name, low, high in DEFAULT_PARAMETERS + MOTOR_PARAMETERS}
    out, seen = [], set()
    for item in specs:
        if isinstance(item, str):
            parts = item.split(':')
            if len(parts) not in (1, 3):
                raise CalibrationError(f'parameter {item!r}: write name or name:low:high')
            name = parts[0].strip()
            bounds = None
            if len(parts) == 3:
                try:
                    bounds = (float(parts[1]), float(parts[2]))
                except ValueError:
                    raise CalibrationError(f'parameter {item!r}: bounds must be numbers') from None
        else:
            name, bounds = item[0], (float(item[1]), float(item[2]))
        if name not in known:
            raise CalibrationError(f'unknown parameter {name!r}; known: '
                                   f'{", ".join(sorted(known))}')
        if name.startswith('conditions.') or name in ('motor.voltage', 'integration.dt',
                                                      'integration.duration'):
            raise CalibrationError(f'{name} is set by the condition of each target or by the '
                                   f'calibration itself, not fitted')
        value, meta = known[name]
        if isinstance(value, int) and not isinstance(value, bool):
            raise CalibrationError(f'{name} is an integer; only continuous parameters are fitted')
        if bounds is None:
            if name not in defaults:
                raise CalibrationError(f'{name}: give its bounds, {name}:LOW:HIGH (allowed '
                                       f'{_range(meta)})')
            bounds = defaults[name]
        low, high = bounds
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise CalibrationError(f'{name}: bounds {low:g}:{high:g} must be finite, low < high')
        if not (_allowed(meta, low) and _allowed(meta, high)):
            raise CalibrationError(f'{name}: bounds {low:g}:{high:g} outside its allowed range '
                                   f'{_range(meta)}')
        if name in seen:
            raise CalibrationError(f'{name} given twice')
        seen.add(name)
        log = low > 0 and high / low >= 4.0
        out.append(Parameter(name, low, high, log, meta.get('unit', '')))
    if not out:
        raise CalibrationError('no parameters to fit')
    return out


def _range(meta) -> str:
    from saw_ros.core.params import range_text
    return range_text(meta)


def default_parameters(base: Optional[Scenario] = None) -> List[Parameter]:
    """Return the DEFAULT_FIT parameters the model has, with their physical bounds."""
    base = base or Scenario()
    flat = base.flat()
    return make_parameters([n for n in DEFAULT_FIT if n in flat], base)


# -- the model under the targets ------------------------------------------------------------------
def _outcome(target: Target, scenario: Scenario, t, q, omega=None) -> float:
    """
    Return the model's speed or AR of one recorded run.

    ``omega``: the helix speed of a run the motor drove; its AR is then taken at the mean helix
    frequency the load left it, as the paper's AR divides by the wave's actual speed.
    """
    m = analyse(t, q, scenario.robot, scenario.frequency, omega=omega)
    return m.v_mean if target.quantity == 'speed' else m.advance_ratio


def _simulate_group(job) -> np.ndarray:
    """
    Simulate one batch of (candidate, target) scenarios; returns the outcomes, (n,).

    A batch that diverges is split in halves until the culprits are alone (their outcome nan),
    as the figure sweeps do.
    """
    scenarios, targets, duration = job
    try:
        tr = simulate(list(scenarios), duration, record_every=RECORD_EVERY)
    except DivergenceError:
        if len(scenarios) == 1:
            return np.array([float('nan')])
        h = len(scenarios) // 2
        return np.concatenate([_simulate_group((scenarios[:h], targets[:h], duration)),
                               _simulate_group((scenarios[h:], targets[h:], duration))])
    out = np.empty(len(scenarios))
    omega = getattr(tr, 'omega', None)
    for i, (s, target) in enumerate(zip(scenarios, targets)):
        driven = omega is not None and s.motor.voltage > 0.0
        try:
            out[i] = _outcome(target, s, tr.t, tr.q[:, i], omega[:, i] if driven else None)
        except ValueError:
            out[i] = float('nan')
    return out


class Model:
    """
    Outcomes of candidate parameter sets under every target, one batch per call.

    The scenarios of one robot geometry are cut into ``pool.workers`` batches
    (``core.pool.batches``, the cut the sweeps use) and run by ``pool``: this process without one,
    local processes or a Dask cluster with one.
    """

    def __init__(self, targets: Sequence[Target], base: Optional[Scenario] = None,
                 pool: Optional[Pool] = None, duration: Optional[float] = None):
        self.targets = list(targets)
        self.base = base or Scenario()
        self.pool = pool
        self.measured = np.array([t.measured for t in self.targets])
        # One duration for every candidate, fixed from the defaults' no-load frequencies: a
        # candidate's outcomes must not depend on which others share its batch. The figure
        # sweeps' 4 s (so the AR targets read as the claims do), longer where a slow helix needs
        # it to settle (about 1 s) and then turn two whole cycles.
        self.duration = duration or max(
            sweeps_duration(), *(1.0 + 2.0 / max(s.frequency, 0.05)
                                 for s in self.scenarios({})))

    def scenarios(self, values: Dict[str, float]) -> List[Scenario]:
        candidate = self.base.with_values(values)
        return [candidate.with_values(t.condition()) for t in self.targets]

    def outcomes(self, candidates: Sequence[Dict[str, float]]) -> np.ndarray:
        """Return (candidates, targets) outcomes; nan where a run diverged or did not move."""
        n_t = len(self.targets)
        groups: Dict[Tuple, List[Tuple[int, Scenario, Target]]] = {}
        for c, values in enumerate(candidates):
            try:
                scenarios = self.scenarios(values)
            except ParameterError:
                continue                     # an impossible set (e.g. a robot that cannot fit)
            for k, s in enumerate(scenarios):
                key = (s.robot, s.integration.dt)
                groups.setdefault(key, []).append((c * n_t + k, s, self.targets[k]))
        out = np.full(len(candidates) * n_t, float('nan'))
        jobs, slots = [], []
        workers = self.pool.workers if self.pool is not None else 1
        for group in groups.values():
            duration = self.duration
            for items in batches(group, workers):
                jobs.append((tuple(s for _, s, _ in items), tuple(t for _, _, t in items),
                             duration))
                slots.append([i for i, _, _ in items])
        mapper = self.pool.map if self.pool is not None else map
        for idx, result in zip(slots, mapper(_simulate_group, jobs)):
            out[idx] = result
        return out.reshape(len(candidates), n_t)

    def losses(self, outcomes: np.ndarray) -> np.ndarray:
        """Mean squared relative error of each candidate; FAILED_LOSS if any target failed."""
        rel = (outcomes - self.measured) / self.measured
        loss = np.mean(rel ** 2, axis=1)
        bad = ~np.isfinite(loss) | np.any(outcomes <= 0, axis=1)
        loss[bad] = FAILED_LOSS
        return loss


# -- the optimisation -----------------------------------------------------------------------------
@dataclass
class Settings:
    generations: int = 60
    popsize: int = 24
    seed: int = 1
    sigma: float = 0.25        # initial step in normalised coordinates
    duration: Optional[float] = None   # s simulated per run; None: Model's choice (4 s here)


def _config(targets, params, settings) -> dict:
    return {'targets': [asdict(t) for t in targets], 'parameters': [asdict(p) for p in params],
            'popsize': settings.popsize, 'seed': settings.seed, 'sigma': settings.sigma,
            'duration': settings.duration}


def _new_state(model: Model, params: List[Parameter], settings: Settings) -> dict:
    from cmaes import CMA
    base = model.base.flat()
    mean = np.array([p.unit_of(base[p.name]) for p in params])
    # cmaes needs two dimensions: a lone parameter gets an idle companion coordinate.
    dims = max(2, len(params))
    mean = np.concatenate([mean, np.full(dims - len(params), 0.5)])
    # Start inside the box: a default on a bound would put half of the first population on it.
    mean = np.clip(mean, 0.05, 0.95)
    optimizer = CMA(mean=mean, sigma=settings.sigma, bounds=np.tile([0.0, 1.0], (dims, 1)),
                    seed=settings.seed, population_size=settings.popsize)
    return {'version': STATE_VERSION, 'generation': 0, 'optimizer': optimizer, 'history': [],
            'best': None, 'population': None, 'elapsed_s': 0.0,
            'config': _config(model.targets, params, settings)}


def load_state(folder) -> dict:
    path = Path(folder) / STATE_FILE
    if not path.is_file():
        raise CalibrationError(f'nothing to resume in {folder}: no {STATE_FILE}')
    try:
        with open(path, 'rb') as f:
            state = pickle.load(f)
    except Exception as exc:  # noqa: BLE001  (any unpickling failure means a damaged file)
        raise CalibrationError(f'{path} is damaged: {type(exc).__name__}: {exc}') from None
    if not isinstance(state, dict) or state.get('version') != STATE_VERSION:
        raise CalibrationError(f'{path} is not a calibration state of this version')
    return state


def _save_state(folder: Path, state: dict) -> None:
    tmp = folder / (STATE_FILE + '.tmp')
    with open(tmp, 'wb') as f:
        pickle.dump(state, f)
    tmp.replace(folder / STATE_FILE)      # never a half-written state after a kill


def targets_from_config(config: dict) -> List[Target]:
    return [Target(**t) for t in config['targets']]


def parameters_from_config(config: dict) -> List[Parameter]:
    return [Parameter(**p) for p in config['parameters']]


def _values(params: Sequence[Parameter], x) -> Dict[str, float]:
    return {p.name: p.value(u) for p, u in zip(params, x)}


def optimise(model: Model, params: List[Parameter], settings: Settings, folder: Path,
             state: Optional[dict] = None, progress: bool = False,
             stop_after: Optional[int] = None) -> dict:
    """
    Run CMA-ES up to ``settings.generations`` generations, saving the state after each one.

    ``state`` continues a run (``load_state``); ``stop_after`` ends this call after that many
    generations (an interruption, for tests).
    """
    folder.mkdir(parents=True, exist_ok=True)
    state = state or _new_state(model, params, settings)
    optimizer = state['optimizer']
    bar = None
    if progress:
        import sys
        from tqdm import tqdm
        bar = tqdm(total=settings.generations, initial=state['generation'], unit='gen',
                   desc='calibrate', file=sys.stderr, leave=False)
    done = 0
    try:
        while state['generation'] < settings.generations:
            if stop_after is not None and done >= stop_after:
                break
            start = time.perf_counter()
            g = state['generation']
            # Reseeded per generation: a resumed run draws what the uninterrupted one drew
            # (the pickled optimiser does not keep its random generator).
            optimizer.reseed_rng(settings.seed * 100_003 + g)
            xs = [optimizer.ask() for _ in range(optimizer.population_size)]
            candidates = [_values(params, x) for x in xs]
            outcomes = model.outcomes(candidates)
            losses = model.losses(outcomes)
            optimizer.tell([(x, float(v)) for x, v in zip(xs, losses)])
            i = int(np.argmin(losses))
            if state['best'] is None or losses[i] < state['best']['loss']:
                state['best'] = {'loss': float(losses[i]), 'values': candidates[i],
                                 'outcomes': outcomes[i].tolist(), 'generation': g}
            state['population'] = np.array([x[:len(params)] for x in xs])
            state['generation'] = g + 1
            state['elapsed_s'] += time.perf_counter() - start
            state['history'].append({
                'generation': g, 'best_loss': float(losses[i]),
                'median_loss': float(np.median(losses)),
                'best_so_far': state['best']['loss'],
                'spread': float(np.mean(np.std(state['population'], axis=0))),
                'failed': int(np.sum(losses >= FAILED_LOSS)), 'seconds': state['elapsed_s']})
            _save_state(folder, state)
            done += 1
            if bar is not None:
                bar.set_postfix(best=f'{state["best"]["loss"]:.2e}')
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return state


# -- uncertainty ----------------------------------------------------------------------------------
def sensitivity(model: Model, params: List[Parameter], values: Dict[str, float]
                ) -> Tuple[np.ndarray, np.ndarray, Dict[str, float]]:
    """
    Return (S, centre outcomes, default outcomes of the base) from one batch.

    S[k, j] = relative change of target k per relative change of parameter j, central
    differences of SENSITIVITY_STEP (one-sided where a step would leave the parameter's range).
    """
    meta = {name: m for name, _, m in model.base.describe()}
    steps = []
    candidates = [dict(values), {}]
    for p in params:
        v = values[p.name]
        up, down = v * (1 + SENSITIVITY_STEP), v * (1 - SENSITIVITY_STEP)
        if v == 0.0:
            up, down = v + SENSITIVITY_STEP * (p.high - p.low), v
        if not _allowed(meta[p.name], up):
            up = v
        if not _allowed(meta[p.name], down):
            down = v
        steps.append((up, down))
        candidates += [{**values, p.name: up}, {**values, p.name: down}]
    out = model.outcomes(candidates)
    centre, default = out[0], out[1]
    S = np.zeros((len(model.targets), len(params)))
    for j, (p, (up, down)) in enumerate(zip(params, steps)):
        scale = values[p.name] if values[p.name] != 0.0 else (p.high - p.low)
        S[:, j] = (out[2 + 2 * j] - out[3 + 2 * j]) / centre / ((up - down) / scale)
    return S, centre, default


def identifiability(S: np.ndarray, params: List[Parameter], residual_rms: float) -> dict:
    """
    Return what the targets pin down: a linearised covariance of the relative parameters.

    cov = sigma^2 (S^T S)^-1 with sigma the target error (the fit's RMS relative residual, at
    least MIN_TARGET_ERROR); directions S does not see (singular values near zero, or fewer
    targets than parameters) are flat: no finite band.
    """
    sigma = max(float(residual_rms), MIN_TARGET_ERROR)
    names = [p.name for p in params]
    S = np.nan_to_num(S)
    _, s, vt = np.linalg.svd(S, full_matrices=True)
    s = np.concatenate([s, np.zeros(len(names) - len(s))])
    tiny = 1e-9 + 1e-6 * (s.max() if len(s) else 0.0)
    flat, std = [], np.zeros(len(names))
    for k in range(len(names)):
        extent = float('inf') if s[k] <= tiny else sigma / s[k]   # 1-sigma relative move
        if extent > IDENTIFIED_REL_STD:
            parts = [(names[j], float(vt[k, j])) for j in np.argsort(-abs(vt[k]))
                     if abs(vt[k, j]) >= 0.3]
            flat.append({'one_sigma_relative_move': extent, 'direction': {
                n: round(c, 3) for n, c in parts}})
        share = vt[k] ** 2
        if math.isfinite(extent):
            std += share * extent ** 2
        else:
            # A parameter with a part (5 % or more) in an unseen direction has no finite band.
            std[share >= 0.05 ** 2] = float('inf')
    std = np.sqrt(std)
    pairs = []
    finite = [j for j in range(len(names)) if math.isfinite(std[j])]
    if finite:
        sub = S[:, finite]
        cov = np.linalg.pinv(sub.T @ sub) * sigma ** 2
        d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
        corr = cov / np.outer(d, d)
        for a in range(len(finite)):
            for b in range(a + 1, len(finite)):
                if abs(corr[a, b]) >= CORRELATED:
                    pairs.append({'a': names[finite[a]], 'b': names[finite[b]],
                                  'correlation': round(float(corr[a, b]), 3)})
    # Pairs that only move together inside a flat direction are correlated too.
    for f in flat:
        members = list(f['direction'])
        for a in range(len(members)):
            for b in range(a + 1, len(members)):
                pair = {'a': members[a], 'b': members[b], 'correlation': None,
                        'flat_direction': True}
                if not any({p['a'], p['b']} == {members[a], members[b]} for p in pairs):
                    pairs.append(pair)
    return {'target_error': sigma,
            'relative_std': {n: (float(v) if math.isfinite(v) else None)
                             for n, v in zip(names, std)},
            'identified': [n for n, v in zip(names, std) if v <= IDENTIFIED_REL_STD],
            'not_identified': [n for n, v in zip(names, std) if not v <= IDENTIFIED_REL_STD],
            'flat_directions': flat, 'correlated': pairs,
            'singular_values': [float(v) for v in s]}


# -- the whole run --------------------------------------------------------------------------------
@dataclass
class Result:
    folder: Path
    data: dict
    files: List[Path] = field(default_factory=list)

    @property
    def values(self) -> Dict[str, float]:
        return {p['name']: p['value'] for p in self.data['parameters']}


def calibrate(targets: Sequence[Target], params: Sequence[Parameter], folder,
              settings: Settings = Settings(), base: Optional[Scenario] = None,
              resume: bool = False, progress: bool = False, pool: Optional[Pool] = None,
              command: str = 'saw-ros calibrate', stop_after: Optional[int] = None,
              plots: bool = True, claims: Optional[str] = None) -> Optional[Result]:
    """
    Fit ``params`` to ``targets``; write state, history, result.json and the plots in ``folder``.

    With ``resume`` the targets, parameters, population size and seed are those of the saved
    state (``settings.generations`` may extend it). Returns None when ``stop_after`` ended the
    run before its last generation. ``claims`` ('full' or 'quick' grids) also evaluates the
    fidelity report's claims with the calibrated set and the defaults (held-out honesty).
    """
    folder = Path(folder)
    base = base or Scenario()
    state = None
    if resume:
        state = load_state(folder)
        config = state['config']
        targets = targets_from_config(config)
        params = parameters_from_config(config)
        settings = Settings(settings.generations, config['popsize'], config['seed'],
                            config['sigma'], config['duration'])
    targets, params = list(targets), list(params)
    if not targets:
        raise CalibrationError('no targets')
    model = Model(targets, base, pool, settings.duration)
    state = optimise(model, params, settings, folder, state, progress, stop_after)
    if state['generation'] < settings.generations:
        return None
    return finish(model, params, state, settings, folder, command, plots, claims)


def claims_summary(values: Dict[str, float], trained: Sequence[str], base: Scenario,
                   quick: bool = False, pool: Optional[Pool] = None) -> dict:
    """Every claim of the fidelity report with the defaults and with ``values``: held counts."""
    from saw_ros.analysis.figures import claims as claims_mod
    from saw_ros.analysis.figures import sweeps
    out = {'trained': sorted(trained), 'grids': 'quick' if quick else 'full'}
    for key, scenario in (('defaults', base), ('calibrated', base.with_values(values))):
        found = claims_mod.evaluate(sweeps.compute(sweeps.FIGURES, quick=quick, pool=pool,
                                                   base=scenario))
        untrained = [c for c in found if c.id not in trained]
        out[key] = {'held': sum(1 for c in found if c.held), 'total': len(found),
                    'held_untrained': sum(1 for c in untrained if c.held),
                    'untrained': len(untrained),
                    'not_held': [c.id for c in found if not c.held]}
    return out


def finish(model: Model, params: List[Parameter], state: dict, settings: Settings,
           folder: Path, command: str, plots: bool = True,
           claims: Optional[str] = None) -> Result:
    start = time.perf_counter()
    best = state['best']
    S, centre, default = sensitivity(model, params, best['values'])
    rel = (centre - model.measured) / model.measured
    rel_default = (default - model.measured) / model.measured
    # A target no fitted parameter moves trains nothing: its claim stays a prediction, and its
    # residual (which no fit could reduce) does not count as the target error.
    informative = np.any(abs(np.nan_to_num(S)) > 1e-6, axis=1)
    used = rel[informative] if informative.any() else rel
    ident = identifiability(S, params, float(np.sqrt(np.mean(used ** 2))))
    base = model.base.flat()
    population = state['population']
    spread = {}
    for j, p in enumerate(params):
        vals = [p.value(u) for u in population[:, j]]
        spread[p.name] = float(np.std(vals))
    data = {
        'command': command,
        'generations': state['generation'], 'popsize': settings.popsize, 'seed': settings.seed,
        'evaluations': state['generation'] * settings.popsize,
        'optimise_s': round(state['elapsed_s'], 2),
        'loss_default': float(np.mean(rel_default ** 2)), 'loss': float(np.mean(rel ** 2)),
        'parameters': [{
            'name': p.name, 'value': best['values'][p.name], 'default': base[p.name],
            'low': p.low, 'high': p.high, 'unit': p.unit, 'log_scale': p.log,
            'at_bound': min(abs(p.unit_of(best['values'][p.name]) - b) for b in (0, 1)) < 0.01,
            'relative_std': ident['relative_std'][p.name],
            'identified': p.name in ident['identified'],
            'final_population_std': spread[p.name]} for p in params],
        'targets': [{
            'name': t.name, 'label': t.label, 'quantity': t.quantity, 'slope_deg': t.slope_deg,
            'voltage_V': t.voltage, 'frequency_hz': t.frequency, 'claim': t.claim,
            'measured': t.measured, 'default': float(default[k]), 'calibrated': float(centre[k]),
            'error_default_pct': 100.0 * float(abs(rel_default[k])),
            'error_calibrated_pct': 100.0 * float(abs(rel[k])),
            'informative': bool(informative[k]),
            'source': t.source} for k, t in enumerate(model.targets)],
        'trained_claims': sorted({t.claim for k, t in enumerate(model.targets)
                                  if t.claim and informative[k]}),
        'sensitivity': {'step': SENSITIVITY_STEP, 'parameters': [p.name for p in params],
                        'targets': [t.label for t in model.targets],
                        'matrix': S.tolist()},
        'identifiability': ident,
        'history': state['history'],
    }
    data['sensitivity_s'] = round(time.perf_counter() - start, 2)
    if claims:
        start = time.perf_counter()
        data['claims'] = claims_summary(best['values'], data['trained_claims'], model.base,
                                        quick=claims == 'quick', pool=model.pool)
        data['claims_s'] = round(time.perf_counter() - start, 2)
    folder.mkdir(parents=True, exist_ok=True)
    files = [folder / RESULT_FILE, folder / HISTORY_FILE]
    (folder / RESULT_FILE).write_text(json.dumps(data, indent=1, default=_json_default) + '\n')
    with open(folder / HISTORY_FILE, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(state['history'][0]))
        w.writeheader()
        w.writerows(state['history'])
    if plots:
        files += write_plots(data, folder)
    return Result(folder, data, files)


def _json_default(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f'not JSON: {type(value).__name__}')


def speed_error_pct(result_data: dict, key: str = 'calibrated') -> float:
    """Return the mean relative error of the speed targets, %."""
    errors = [abs(t[key] - t['measured']) / t['measured'] for t in result_data['targets']
              if t['quantity'] == 'speed']
    return 100.0 * float(np.mean(errors)) if errors else float('nan')


# -- plots ----------------------------------------------------------------------------------------
def _plt():
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    return plt


def write_plots(data: dict, folder: Path) -> List[Path]:
    """fit.png, sensitivity.png and convergence.png."""
    plt = _plt()
    files = []
    targets = data['targets']
    labels = [t['label'] for t in targets]
    x = np.arange(len(targets))
    fig, ax = plt.subplots(figsize=(max(6.0, 1.3 * len(targets) + 2), 4.2))
    ax.axhspan(0.95, 1.05, color='0.9', label='within 5 %')
    ax.axhline(1.0, color='k', lw=0.8)
    ax.bar(x - 0.18, [t['default'] / t['measured'] for t in targets], 0.36, label='defaults',
           color='tab:gray')
    ax.bar(x + 0.18, [t['calibrated'] / t['measured'] for t in targets], 0.36,
           label='calibrated', color='tab:blue')
    ax.set_xticks(x, labels, rotation=20, ha='right', fontsize=8)
    ax.set_ylabel('model / measured')
    ax.set_title(f'fit: mean squared relative error {data["loss_default"]:.2e} -> '
                 f'{data["loss"]:.2e}')
    ax.legend(fontsize=8)
    files.append(_save(plt, fig, folder / 'fit.png'))

    S = np.array(data['sensitivity']['matrix'])
    names = [n.split('.', 1)[1] for n in data['sensitivity']['parameters']]
    fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * len(names) + 2.5), 0.55 * len(labels) + 2))
    lim = max(1e-3, float(np.nanmax(abs(S))))
    im = ax.imshow(S, cmap='RdBu_r', vmin=-lim, vmax=lim, aspect='auto')
    ax.set_xticks(range(len(names)), names, rotation=25, ha='right', fontsize=8)
    ax.set_yticks(range(len(labels)), labels, fontsize=8)
    for (k, j), v in np.ndenumerate(S):
        ax.text(j, k, f'{v:.2f}', ha='center', va='center', fontsize=7)
    fig.colorbar(im, ax=ax, label='d ln(target) / d ln(parameter)')
    ax.set_title('sensitivity at the calibrated set')
    files.append(_save(plt, fig, folder / 'sensitivity.png'))

    h = data['history']
    fig, ax = plt.subplots(figsize=(6, 3.6))
    gens = [r['generation'] for r in h]
    ax.semilogy(gens, [r['best_so_far'] for r in h], label='best so far')
    ax.semilogy(gens, [r['best_loss'] for r in h], '.', label='best of the generation')
    ax.semilogy(gens, [r['median_loss'] for r in h], '.', alpha=0.5, label='median')
    ax.set_xlabel('generation')
    ax.set_ylabel('mean squared relative error')
    ax.legend(fontsize=8)
    files.append(_save(plt, fig, folder / 'convergence.png'))
    return files


def _save(plt, fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


# -- the calibrated parameter file ----------------------------------------------------------------
TRAINED_TAG = '# trained_claims:'


def calibrated_yaml(template: str, values: Dict[str, float], header: Iterable[str],
                    trained_claims: Iterable[str]) -> str:
    """
    Return ``template`` (the simulator's parameter file) with ``values`` put in.

    Every line but the calibrated values stays as the simulator's ``--write-yaml`` wrote it, so
    the two files differ in those values and the header only. Nested (section: key:) layout.
    """
    lines = template.splitlines()
    body = [i for i, line in enumerate(lines) if not line.startswith('#')]
    out = [f'# {h}' if h else '#' for h in header]
    out.append(f'{TRAINED_TAG} {" ".join(sorted(trained_claims)) or "none"}')
    missing = dict(values)
    section = None
    for i in body:
        line = lines[i]
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if stripped.endswith(':') and not stripped.startswith('#') and indent == 4:
            section = stripped[:-1]
        elif indent == 6 and ':' in stripped and not stripped.startswith('#') and section:
            key = stripped.split(':', 1)[0]
            name = f'{section}.{key}'
            if name in missing:
                line = f'{" " * indent}{key}: {float(missing.pop(name))!r}'
        out.append(line)
    if missing:
        raise CalibrationError(f'the simulator parameter file has no {", ".join(missing)}')
    return '\n'.join(out) + '\n'


def trained_claims_of(path) -> List[str]:
    """Return the claims a calibrated parameter file was trained on (its TRAINED_TAG line)."""
    for line in Path(path).read_text().splitlines():
        if line.startswith(TRAINED_TAG):
            rest = line[len(TRAINED_TAG):].split()
            return [] if rest == ['none'] else rest
    return []


def write_calibrated_yaml(result: Result, path, command: str) -> Path:
    """Write the calibrated simulator parameter file at ``path`` from msg_config/simulator.yaml."""
    template = config_path('simulator.yaml').read_text()
    d = result.data
    header = [
        'Calibrated parameters of the saw_ros simulator node:',
        f'  python -m saw_ros.ros.nodes.simulator --ros-args --params-file {path}',
        'The defaults of msg_config/simulator.yaml with the fitted values put in:',
    ]
    for p in d['parameters']:
        header.append(f'  {p["name"]} = {p["value"]:.6g} (default {p["default"]:.6g}; '
                      f'{"pinned down by the targets" if p["identified"] else "NOT pinned down"})')
    header += [f'Targets: {", ".join(t["label"] for t in d["targets"])}; mean squared relative '
               f'error {d["loss_default"]:.2e} -> {d["loss"]:.2e}.',
               'See docs/calibration.md. Do not edit by hand; made by:',
               f'  {command}']
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(calibrated_yaml(template, result.values, header, d['trained_claims']))
    return path
