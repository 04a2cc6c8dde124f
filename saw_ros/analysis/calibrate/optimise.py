"""
The optimisation: CMA-ES generations, with the state saved after each one.

The state (generation, the pickled optimiser, the best candidate so far, the history) is
written to the output folder after every generation; ``resume`` continues from it and, because
the optimiser's random generator is reseeded from (seed, generation) before every generation,
ends where an uninterrupted run with the same seed would.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
import pickle
import time
from typing import Dict, List, Optional, Sequence

import numpy as np

from saw_ros.analysis.calibrate.model import FAILED_LOSS, Model
from saw_ros.analysis.calibrate.parameters import Parameter
from saw_ros.analysis.calibrate.targets import CalibrationError, Target


STATE_FILE = 'state.pkl'
STATE_VERSION = 1


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
