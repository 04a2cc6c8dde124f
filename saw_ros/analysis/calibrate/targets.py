"""
What the fit aims at: measured speeds and ARs under their conditions.

A CSV in the format of ``msg_config/reference_paper.csv`` or of the footage campaign's
``footage.csv``, or the numbers the paper states (its three measured speeds and the level
and vertical AR of Figure 21 at constant 1 Hz, claims A1 and A2).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
import math
from pathlib import Path
from typing import Any, Dict, List, Optional

from saw_ros.interface.config import config_path


class CalibrationError(ValueError):
    """Targets or parameters that cannot be used; the message says which and why."""


# The paper's Figure 21 ARs at its default set-up (claims A1 and A2 of the fidelity report).
PAPER_AR = ((0.0, 0.72, 'A1', 'Sec. 8, Fig. 21: wave AR on the level at the defaults'),
            (90.0, 0.61, 'A2', 'Sec. 8, Fig. 21: wave AR climbing vertically at the defaults'))


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
        values: Dict[str, Any] = {'conditions.slope': math.radians(self.slope_deg)}
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
        if speed is not None:
            quantity, measured = 'speed', speed
        elif ar is not None:
            quantity, measured = 'ar', ar
        else:
            raise CalibrationError(f'{where}: no measured speed or AR')
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
