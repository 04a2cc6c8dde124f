"""
What the fit moves: dotted-name parameters within physical bounds, mapped onto [0, 1].

Bounds must lie within the range the Scenario's spec tables allow (``core.params.check_value``,
the one range check); a bare name takes the physical bounds below (why each: docs/calibration.md).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import List, Optional, Sequence

from saw_ros.analysis.calibrate.targets import CalibrationError
from saw_ros.core.params import check_value, ParameterError, range_text, Scenario


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
        # A start outside the bounds sits on the nearer one: a default of 0 (rigid flexures,
        # rigid walls) under log bounds raised a math domain error before the first generation.
        if self.log and value <= self.low:
            return 0.0
        if self.log:
            u = math.log(value / self.low) / math.log(self.high / self.low)
        else:
            u = (value - self.low) / (self.high - self.low)
        return min(1.0, max(0.0, u))


def allowed(name: str, meta: dict, value: float) -> bool:
    """Return whether ``value`` is within the range the spec tables allow for ``name``."""
    try:
        check_value(name, value, meta)          # the spec tables' own range check
    except ParameterError:
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
                                       f'{range_text(meta)})')
            bounds = defaults[name]
        low, high = bounds
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise CalibrationError(f'{name}: bounds {low:g}:{high:g} must be finite, low < high')
        if not (allowed(name, meta, low) and allowed(name, meta, high)):
            raise CalibrationError(f'{name}: bounds {low:g}:{high:g} outside its allowed range '
                                   f'{range_text(meta)}')
        if name in seen:
            raise CalibrationError(f'{name} given twice')
        seen.add(name)
        log = low > 0 and high / low >= 4.0
        out.append(Parameter(name, low, high, log, meta.get('unit', '')))
    if not out:
        raise CalibrationError('no parameters to fit')
    return out


def default_parameters(base: Optional[Scenario] = None) -> List[Parameter]:
    """Return the DEFAULT_FIT parameters the model has, with their physical bounds."""
    base = base or Scenario()
    flat = base.flat()
    return make_parameters([n for n in DEFAULT_FIT if n in flat], base)
