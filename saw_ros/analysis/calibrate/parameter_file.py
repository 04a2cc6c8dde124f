"""The calibrated parameter file: a copy of the simulator's with the fitted values put in."""
from __future__ import annotations

from pathlib import Path
from typing import Dict, Iterable, List

from saw_ros.analysis.calibrate.run import Result
from saw_ros.analysis.calibrate.targets import CalibrationError
from saw_ros.interface.config import config_path


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
