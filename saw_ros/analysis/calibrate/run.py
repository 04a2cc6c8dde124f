"""
The whole run: optimise, then the uncertainty, the claims and the result files.

``calibrate`` runs (or resumes) a fit in its output folder; ``finish`` writes result.json,
history.csv and the plots.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
import json
from pathlib import Path
import time
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from saw_ros.analysis.calibrate.model import Model
from saw_ros.analysis.calibrate.optimise import (load_state, optimise, parameters_from_config,
                                                 Settings, targets_from_config)
from saw_ros.analysis.calibrate.parameters import Parameter
from saw_ros.analysis.calibrate.plots import write_plots
from saw_ros.analysis.calibrate.targets import CalibrationError, Target
from saw_ros.analysis.calibrate.uncertainty import identifiability, sensitivity, SENSITIVITY_STEP
from saw_ros.core.params import Scenario
from saw_ros.core.pool import Pool


RESULT_FILE = 'result.json'
HISTORY_FILE = 'history.csv'


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
    out: Dict[str, Any] = {'trained': sorted(trained), 'grids': 'quick' if quick else 'full'}
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
