"""
Typed, validated parameters of the model: the one source of truth.

Every field carries its unit, its allowed range and a description in its dataclass metadata, so
that the ROS nodes (parameter descriptors), the YAML files in ``msg_config/`` and the command
line all map onto the same definitions. Units are SI (m, s, kg, N, rad); degrees and cm appear
only in human-facing output.

Defaults are those of ``docs/model.md`` section 8 (the paper's robot and surfaces, with the
choices we made where the paper is silent, each with its reason).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
import math
import numbers
from typing import Any, Dict, Iterable, Iterator, Mapping, Optional, Tuple


GRAVITY = 9.81           # m/s^2 (dynamics.GRAVITY)
PLACEMENT_SHARE = 0.8    # of max_penetration the crests may press in the robot's start position


class ParameterError(ValueError):
    """An invalid parameter value: the message names the parameter, the value and the range."""


def spec(default: Any, unit: str, description: str, low: Optional[float] = None,
         high: Optional[float] = None, low_open: bool = False, high_open: bool = False,
         **extra: Any) -> Any:
    """
    Return a dataclass field with its unit, range and description kept beside the default.

    ``extra`` goes into the metadata as well (e.g. ``flag``: a command-line flag other than
    ``--<name>``). Used by the Scenario's groups here and by the vision layer's dataclasses
    (``TrackerConfig``, ``CameraModel``, ``RenderOptions``), so that node parameters, the
    ``msg_config/`` files and the command line all read one definition.
    """
    return field(default=default, metadata=spec_meta(unit, description, low, high, low_open,
                                                     high_open, **extra))


def spec_meta(unit: str, description: str, low: Optional[float] = None,
              high: Optional[float] = None, low_open: bool = False, high_open: bool = False,
              **extra: Any) -> Dict[str, Any]:
    """
    Return the metadata of a spec() field, for a parameter that is no dataclass field.

    Such as a node's own: its topics, its frame rate...
    """
    return {'unit': unit, 'description': description, 'low': low, 'high': high,
            'low_open': low_open, 'high_open': high_open, **extra}


def spec_entries(cls: type, names: Optional[Iterable[str]] = None
                 ) -> Iterator[Tuple[str, Any, Dict[str, Any]]]:
    """
    Yield (name, default, metadata) of the spec() fields of dataclass ``cls``.

    All of them, or ``names`` in that order.
    """
    fields = {f.name: f for f in dataclasses.fields(cls) if 'unit' in f.metadata}
    for name in (fields if names is None else names):
        f = fields[name]
        yield name, f.default, dict(f.metadata)


def range_text(meta: Mapping[str, Any]) -> str:
    """'[0, 179]', '(0, inf) m', ...: the allowed range of a spec() field, with its unit."""
    low, high = meta['low'], meta['high']
    left = '(' if meta['low_open'] or meta['low'] is None else '['
    right = ')' if meta['high_open'] or meta['high'] is None else ']'
    lo = '-inf' if low is None else f'{low:g}'
    hi = 'inf' if high is None else f'{high:g}'
    unit = f' {meta["unit"]}' if meta['unit'] else ''
    return f'{left}{lo}, {hi}{right}{unit}'


def check_value(name: str, value: Any, meta: Mapping[str, Any], default: Any = 0.0) -> Any:
    """
    Return ``value`` checked against the spec() metadata ``meta`` of parameter ``name``.

    The one range check of every parameter: the Scenario's groups and the vision dataclasses run
    it on each field (``check_fields``), the ROS nodes on their own parameters
    (``saw_ros.ros.params``). ``default`` gives the kind: an
    integer where the default is one, else a finite number, returned as a float; a value among
    ``meta['choices']`` where the metadata lists them. None, booleans and other kinds (strings,
    lists) without choices are returned unchecked. Raises ParameterError naming the parameter,
    the value and the allowed range with its unit.
    """
    choices = meta.get('choices')
    if choices is not None and value not in choices:
        raise ParameterError(f'{name} = {value!r} is invalid: must be one of '
                             f'{", ".join(map(str, choices))}')
    if choices is not None or value is None or isinstance(value, bool) or \
            isinstance(default, (bool, str, list, tuple)):
        return value
    # (numbers.Integral and Real: numpy's integers and floats count too)
    if isinstance(default, int):
        if not isinstance(value, numbers.Integral):
            raise ParameterError(f'{name} = {value!r} is invalid: must be an integer in '
                                 f'{range_text(meta)}')
        value = int(value)
    elif not isinstance(value, numbers.Real):
        raise ParameterError(f'{name} = {value!r} is invalid: must be a number in '
                             f'{range_text(meta)}')
    else:
        value = float(value)
    if not math.isfinite(value):
        raise ParameterError(f'{name} = {value!r} is invalid: must be finite, in '
                             f'{range_text(meta)}')
    low, high = meta.get('low'), meta.get('high')
    too_low = low is not None and (value <= low if meta.get('low_open') else value < low)
    too_high = high is not None and (value >= high if meta.get('high_open') else value > high)
    if too_low or too_high:
        raise ParameterError(f'{name} = {value:g} is out of range: allowed '
                             f'{range_text(meta)} ({meta["description"]})')
    return value


def check_fields(obj: Any, prefix: str = '') -> None:
    """
    Run ``check_value`` on every spec() field of the dataclass instance ``obj``.

    Each field keeps its checked value (an integer given for a float becomes a float, frozen
    dataclasses included); a refusal names the field ``prefix + name``.
    """
    for f in dataclasses.fields(obj):
        if 'unit' not in f.metadata:
            continue
        value = getattr(obj, f.name)
        checked = check_value(prefix + f.name, value, f.metadata, f.default)
        if checked is not value:
            object.__setattr__(obj, f.name, checked)


class _Validated:
    """Mixin: checks every numeric field against its metadata range after construction."""

    section: str = ''

    def __post_init__(self) -> None:
        check_fields(self, f'{self.section}.')
        self._check()

    def _check(self) -> None:
        """Check that involve several fields."""

    def replace(self: Any, **changes: Any) -> Any:
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class RobotParams(_Validated):
    """The SAW robot: a rigid body carrying a helix-driven wave of links (paper Section 2)."""

    section = 'robot'
    mass: float = spec(0.313, 'kg', 'robot mass with batteries', 0.0, None, low_open=True)
    length: float = spec(0.35, 'm', 'overall robot length', 0.0, None, low_open=True)
    pitch_inertia: float = spec(0.0, 'kg m^2',
                                'pitch moment of inertia about the COM; 0 means a uniform bar, '
                                'mass * length^2 / 12', 0.0, None)
    wavelength: float = spec(0.102, 'm', 'wavelength L of the helix', 0.0, None, low_open=True)
    amplitude: float = spec(0.0185, 'm', 'half-amplitude A of the backbone wave', 0.0, None,
                            low_open=True)
    tip_distance: float = spec(0.0098, 'm', 'distance r from a link centre to its tips', 0.0,
                               None, low_open=True)
    link_width: float = spec(0.0, 'm', 'width b of a wave link; 0 means wavelength / 9', 0.0, None)
    base_link_width: float = spec(0.020, 'm', 'width of the base link joining wave and head', 0.0,
                                  None, low_open=True)
    wave_links: int = spec(19, '', 'number of wave links (the base link comes in addition)', 1,
                           200)

    @property
    def inertia(self) -> float:
        if self.pitch_inertia > 0.0:
            return self.pitch_inertia
        return self.mass * self.length ** 2 / 12.0

    @property
    def link(self) -> float:
        return self.link_width if self.link_width > 0.0 else self.wavelength / 9.0

    @property
    def height(self) -> float:
        """Tallest extent of the robot: crest tip above the axis, trough tip below it."""
        return 2.0 * (self.amplitude + self.tip_distance)

    @property
    def wave_length_along_body(self) -> float:
        return self.base_link_width + self.wave_links * self.link

    def _check(self) -> None:
        if self.amplitude >= self.base_link_width:
            raise ParameterError(
                f'robot.amplitude = {self.amplitude:g} m is invalid: the base link '
                f'(robot.base_link_width = {self.base_link_width:g} m) must be longer than the '
                f'amplitude to reach the wave')
        if self.wave_length_along_body >= self.length:
            raise ParameterError(
                f'robot.wave_links = {self.wave_links} links of {self.link:g} m do not fit in '
                f'robot.length = {self.length:g} m: allowed up to '
                f'{int((self.length - self.base_link_width) / self.link)} links')


@dataclass(frozen=True)
class SurfaceParams(_Validated):
    """The two compliant surfaces (paper Section 4.2, Eqs. 6-8)."""

    section = 'surface'
    normal_stiffness: float = spec(15500.0, 'N/m^exponent',
                                   'Hertz normal stiffness kn: Fn = kn * delta^exponent', 0.0,
                                   None, low_open=True)
    hertz_exponent: float = spec(1.5, '', 'exponent of the normal law (1.5 Hertz, 1.0 linear)',
                                 1.0, 3.0)
    tangential_stiffness: float = spec(1082.0, 'N/m', 'tangential stiffness kt of the surface',
                                       0.0, None, low_open=True)
    friction_coefficient: float = spec(1.0, '', 'Coulomb coefficient of friction mu', 0.0, 5.0)
    restitution: float = spec(0.9, '', 'coefficient of restitution e: share of the stored energy '
                              'a tip gets back when it unloads', 0.0,
                              1.0, low_open=True)
    # Below 1 um/s the switch is the paper's sign rule at every rate that matters; its folded
    # gain kn (1 - e) / (2 v0 dt) would reach inf (then NaN) as v0 -> 0.
    hysteresis_speed: float = spec(0.01, 'm/s', 'deformation rate over which the force '
                                   'factor passes from e (unloading) to 1 (loading)', 1e-6, None)
    # Up to 50 mm, deeper than the robot's whole amplitude: the surfaces are layers of foam, and
    # the weight check (Scenario) raises it to the power hertz_exponent.
    max_penetration: float = spec(0.015, 'm',
                                  'deepest a tip can physically press into a surface; deeper '
                                  'means the simulation diverged', 0.0, 0.05, low_open=True)
    # Walls that bend (core.walls, docs/walls.md): each surface a beam on an elastic foundation.
    # 0 keeps them rigid behind their contact springs, the paper's model and the default.
    foundation_stiffness: float = spec(0.0, 'N/m^2', 'stiffness k of what holds each surface, per '
                                       'metre of its length (Winkler foundation); 0 = rigid '
                                       'walls', 0.0, 1e10)
    bending_stiffness: float = spec(6.25e-4, 'N m^2', 'bending stiffness EI of each surface '
                                    '(the strip the robot touches); used with '
                                    'foundation_stiffness > 0', 0.0, 1e4, low_open=True)
    contact_width: float = spec(0.005, 'm', 'length of surface one tip presses on: its force is '
                                'spread over it (bending walls only)', 0.0, 0.05, low_open=True)


@dataclass(frozen=True)
class ConditionParams(_Validated):
    """The operating conditions of one run: slope, gap, load and wave frequency."""

    section = 'conditions'
    slope: float = spec(0.0, 'rad', 'slope alpha of the surfaces (+ climbs, - descends)',
                        -math.pi / 2, math.pi / 2)
    # Up to 0.1 m: in a wider gap the robot drops onto the bottom surface from higher than
    # its own height (a 1 m gap drove its tips 15 mm into the silicone on landing).
    gap: float = spec(0.045, 'm', 'distance h between the bottom and top surfaces', 0.0, 0.1,
                      low_open=True)
    # 100 N is 33 times the robot's weight: more than any tether of a 313 g crawler, and a
    # bound keeps the robot from being thrown beyond dynamics.MAX_SPEED in one step.
    external_force: float = spec(0.0, 'N', 'resisting force F_ext along -x at the COM (tether)',
                                 -100.0, 100.0)
    # Up to 5 Hz, three times the paper's fastest run (1.7 Hz): from 9 Hz on the paper's robot
    # bounces off the surfaces deeper than max_penetration within 1-2 s, at any dt (physics, not
    # the integrator), and at 5 Hz already in a 80 mm gap.
    frequency: float = spec(1.0, 'Hz', 'helix turns per second f (0 stops the wave); ignored '
                            'while motor.voltage > 0, which then drives the helix', 0.0, 5.0)


@dataclass(frozen=True)
class IntegrationParams(_Validated):
    """Time stepping (paper Section 4.3: semi-implicit Euler at 1 kHz)."""

    section = 'integration'
    # Up to 4 ms: the paper's robot squeezed in its 45 mm gap rings at omega = 336 rad/s, and
    # the step is kept within omega dt <= 1.5 (core.stability; 4.46 ms). Other surfaces and gaps
    # move the limit: the Scenario checks it with the reason.
    dt: float = spec(0.001, 's', 'integration time step', 0.0, 0.004, low_open=True)
    duration: float = spec(5.0, 's', 'simulated time of a run', 0.0, None)


@dataclass(frozen=True)
class MotorParams(_Validated):
    """
    The DC motor between the voltage and the helix (docs/motor.md).

    Constants are referred to the helix shaft, after the paper's 156:1 gearbox. The motor constant
    (back-EMF per rad/s = torque per ampere) is k = 1 / (2 pi hz_per_volt): an ideal motor turns
    the helix at hz_per_volt * V at no load. With the winding resistance R and the Coulomb
    friction tau_f the helix speed omega follows

        J d omega / dt = k i - tau_f sign(omega) - tau_load,    i = (V - k omega) / R,

    tau_load the work the link tips do against the contact forces per radian of helix. The
    paper gives the gearbox (156:1) and the voltages (4-7 V) only; the constants are ours, for a
    20 mm 6 V brushed motor (docs/motor.md says where each comes from), to be refined by
    ``saw-ros calibrate``. ``voltage`` 0 leaves the motor out: conditions.frequency then turns
    the helix at constant speed, as in the paper's simulation.
    """

    section = 'motor'
    # Bounded 40 times beyond the paper's motor either way, where the step's arithmetic still
    # holds: at hz_per_volt 1e300 the no-load speed V / k swamped the helix speed in the implicit
    # step (garbage speeds of 1e285 rad/s), at 5e-324 k was inf, and resistance and inertia
    # both at 1e300 made the torque inf * 0 = NaN.
    hz_per_volt: float = spec(0.24, 'Hz/V', 'helix turns per second per volt of back-EMF (the '
                              'no-load speed of a motor without friction); sets the motor '
                              'constant k = 1 / (2 pi hz_per_volt) in V s/rad = N m/A', 0.006,
                              10.0)
    resistance: float = spec(8.0, 'ohm', 'winding resistance; 0 = an ideal stiff source whose '
                             'speed does not depend on the load', 0.0, 320.0)
    friction_torque: float = spec(0.02, 'N m', 'Coulomb friction torque at the helix (gearbox, '
                                  'and the helix against the links)', 0.0, 0.8)
    inertia: float = spec(0.006, 'kg m^2', 'rotor inertia reflected through the gearbox, plus '
                          'the helix, at the helix shaft; 0 = quasi-static', 0.0, 0.24)
    # Up to 20 V: 4.7 Hz at the default 0.24 Hz/V, within conditions.frequency's 5 Hz (the
    # Scenario holds any other hz_per_volt to that too).
    voltage: float = spec(0.0, 'V', 'motor voltage; above 0 the motor drives the helix and '
                          'conditions.frequency is ignored', 0.0, 20.0)

    @property
    def torque_constant(self) -> float:
        """Return k = 1 / (2 pi hz_per_volt): back-EMF in V s/rad, torque in N m/A."""
        return 1.0 / (2.0 * math.pi * self.hz_per_volt)

    @property
    def dead_voltage(self) -> float:
        """Return the voltage below which the motor cannot beat its own friction, R tau_f / k."""
        return self.resistance * self.friction_torque / self.torque_constant

    def frequency(self, voltage: float) -> float:
        """
        Return the helix frequency at no load, Hz: hz_per_volt (V - R tau_f / k), at least 0.

        Under load the helix turns slower: the simulation finds out how much.
        """
        if not math.isfinite(voltage) or voltage < 0.0:
            raise ParameterError(f'motor voltage = {voltage!r} is invalid: must be >= 0 V')
        return max(0.0, self.hz_per_volt * (voltage - self.dead_voltage))


@dataclass(frozen=True)
class WallDynamicsParams(_Validated):
    """
    Walls with mass and damping (issue 31, core.dynamic_walls, docs/walls.md).

    The Scenario's ``walls`` section: with bending walls (surface.foundation_stiffness > 0)
    and a mass or a damping above 0 each wall is a core.dynamic_walls wall in the compiled step.
    The sets of docs/walls.md: the silicone sheet 0.33 kg/m, the soft tissue 0.13 kg/m.
    """

    section = 'walls'
    # Up to 100 kg/m: a steel plate 10 mm thick and 1 m wide is 79 kg/m; the tissue set is
    # 0.13. Up to 1e6 N s/m^2: with no mass the wall then relaxes over c / k, 111 s on the
    # tissue's foundation, longer than any run.
    mass: float = spec(0.0, 'kg/m', 'mass of each surface per metre of its length (the strip '
                       'and what moves with it); 0 = quasi-static walls; used with '
                       'surface.foundation_stiffness > 0', 0.0, 100.0)
    damping: float = spec(0.0, 'N s/m^2', 'viscous damping of the foundation per metre of wall; '
                          'used with surface.foundation_stiffness > 0', 0.0, 1e6)

    # Lighter than this (but not 0, the quasi-static wall) the modes' propagator overflows
    # (-c / 2m, as the flexures' did at 1e-300 kg).
    LIGHTEST = 1e-6

    def _check(self) -> None:
        if 0.0 < self.mass < self.LIGHTEST:
            raise ParameterError(
                f'walls.mass = {self.mass:g} kg/m is invalid: 0 (quasi-static walls) or at '
                f'least {self.LIGHTEST:g} kg/m')


@dataclass(frozen=True)
class FlexureParams(_Validated):
    """
    A compliant robot (issue 31, core.flexure, docs/model.md): each wave link on a flexure.

    The link follows its kinematic target through a spring-damper normal to the backbone, in
    the compiled step (the Scenario's ``flexure`` section). docs/compliant_robot.md gives the
    printed TPU and nylon sets and their sources.
    """

    section = 'flexure'
    stiffness: float = spec(0.0, 'N/m', "stiffness of a link's flexure normal to the backbone; "
                            "0 = rigid links (the paper's robot)", 0.0, 1e9)
    damping: float = spec(0.0, 'N s/m', "viscous damping of a link's flexure", 0.0, 1e3)
    # From 0.1 g: at 1e-300 kg the link's propagator overflowed (-c / 2m) to a non-finite state.
    link_mass: float = spec(0.004, 'kg', 'mass of one wave link (part of robot.mass)', 1e-4,
                            0.1)

    # Softer than 1 N/m a link sags more than its own weight can bear in the model (4 g: 4 cm);
    # at 1e-300 the step's compliance 1 / k overflowed (ZeroDivisionError in the kernel).
    SOFTEST = 1.0

    def _check(self) -> None:
        if 0.0 < self.stiffness < self.SOFTEST:
            raise ParameterError(
                f'flexure.stiffness = {self.stiffness:g} N/m is invalid: 0 (rigid links) or at '
                f'least {self.SOFTEST:g} N/m')


@dataclass(frozen=True)
class Scenario:
    """Everything one simulation run needs."""

    robot: RobotParams = field(default_factory=RobotParams)
    surface: SurfaceParams = field(default_factory=SurfaceParams)
    conditions: ConditionParams = field(default_factory=ConditionParams)
    integration: IntegrationParams = field(default_factory=IntegrationParams)
    motor: MotorParams = field(default_factory=MotorParams)
    flexure: FlexureParams = field(default_factory=FlexureParams)
    walls: WallDynamicsParams = field(default_factory=WallDynamicsParams)

    def __post_init__(self) -> None:
        # The robot starts centred in the gap; its crests must leave a fifth of max_penetration
        # for the motion (at the full depth a 27.5 mm gap diverged within 5 ms, at 80 % none did).
        lowest = self.robot.height - 2.0 * PLACEMENT_SHARE * self.surface.max_penetration
        if self.conditions.gap <= lowest:
            raise ParameterError(
                f'conditions.gap = {self.conditions.gap:g} m is invalid: the robot '
                f'({self.robot.height * 1000:.1f} mm tall) cannot be placed in it without '
                f'pressing deeper than {PLACEMENT_SHARE:.0%} of surface.max_penetration = '
                f'{self.surface.max_penetration:g} m into each surface; allowed above '
                f'{lowest:g} m')
        # Surfaces too soft to carry the robot: even its n bottom tips all pressed
        # max_penetration deep hold less than its weight, so it sinks through.
        s = self.surface
        per_stiffness = self.robot.wave_links * s.max_penetration ** s.hertz_exponent
        held = per_stiffness * s.normal_stiffness
        if held < self.robot.mass * GRAVITY:
            raise ParameterError(
                f'surface.normal_stiffness = {s.normal_stiffness:g} N/m^{s.hertz_exponent:g} '
                f'is too soft: all {self.robot.wave_links} bottom tips pressed '
                f'surface.max_penetration = {s.max_penetration:g} m deep hold {held:.3g} N, less '
                f"than the robot's weight ({self.robot.mass * GRAVITY:.3g} N); allowed above "
                f'{self.robot.mass * GRAVITY / per_stiffness:.4g} N/m^'
                f'{s.hertz_exponent:g}')
        top = ConditionParams.__dataclass_fields__['frequency'].metadata['high']
        if self.motor.voltage > 0.0 and self.frequency > top:
            raise ParameterError(
                f'motor.voltage = {self.motor.voltage:g} V is invalid: at motor.hz_per_volt = '
                f'{self.motor.hz_per_volt:g} Hz/V it turns the helix at {self.frequency:.3g} Hz '
                f'at no load, above the {top:g} Hz conditions.frequency allows; allowed up to '
                f'{top / self.motor.hz_per_volt + self.motor.dead_voltage:.4g} V')

    @property
    def frequency(self) -> float:
        """
        Return the helix frequency of this run, Hz.

        That is conditions.frequency, or with motor.voltage set the motor's no-load frequency at
        that voltage (a load slows the helix below it: the simulation records the actual speed,
        ``Trajectory.omega``).
        """
        if self.motor.voltage > 0.0:
            return self.motor.frequency(self.motor.voltage)
        return self.conditions.frequency

    @property
    def frequency_source(self) -> str:
        """
        Return the parameter that drives the helix.

        motor.voltage when above 0, else conditions.frequency.
        """
        if self.motor.voltage > 0.0:
            return (f'motor.voltage = {self.motor.voltage:g} V at no load, slower under load; '
                    f'conditions.frequency ignored')
        return 'conditions.frequency'

    # -- flat name access, shared by the YAML files, the node parameters and the CLI ----------
    SECTIONS = ('robot', 'surface', 'conditions', 'integration', 'motor', 'flexure', 'walls')

    def flat(self) -> Dict[str, Any]:
        """{'surface.normal_stiffness': 15500.0, ...}."""
        return {name: value for name, value, _ in self.describe()}

    def describe(self) -> Iterator[Tuple[str, Any, Dict[str, Any]]]:
        """(dotted name, value, metadata) for every parameter."""
        for section in self.SECTIONS:
            group = getattr(self, section)
            for f in dataclasses.fields(group):
                yield f'{section}.{f.name}', getattr(group, f.name), dict(f.metadata)

    def with_values(self, values: Dict[str, Any]) -> 'Scenario':
        """
        Return a new, validated Scenario with dotted-name values changed.

        Unknown names raise.
        """
        groups: Dict[str, Dict[str, Any]] = {s: {} for s in self.SECTIONS}
        for name, value in values.items():
            section, _, key = name.partition('.')
            if section not in groups or key not in {f.name for f in
                                                    dataclasses.fields(getattr(self, section))}:
                raise ParameterError(f'unknown parameter {name!r}; known: '
                                     f'{", ".join(sorted(self.flat()))}')
            groups[section][key] = value
        parts = {s: getattr(self, s).replace(**c) if c else getattr(self, s)
                 for s, c in groups.items()}
        return Scenario(**parts)
