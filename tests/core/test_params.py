import math

import pytest

from saw_ros.core import ParameterError, RobotParams, Scenario, SurfaceParams
from saw_ros.core.params import ConditionParams, IntegrationParams


def test_defaults_are_model_md_section_8():
    s = Scenario()
    assert s.robot.mass == 0.313 and s.robot.length == 0.35 and s.robot.wavelength == 0.102
    assert s.robot.amplitude == 0.0185 and s.robot.tip_distance == 0.0098
    assert s.robot.link == pytest.approx(0.102 / 9) and s.robot.wave_links == 19
    assert s.robot.inertia == pytest.approx(0.313 * 0.35 ** 2 / 12)
    assert s.surface.normal_stiffness == 15500 and s.surface.tangential_stiffness == 1082
    assert s.surface.friction_coefficient == 1.0 and s.surface.restitution == 0.9
    assert s.conditions.gap == 0.045 and s.integration.dt == 0.001 and s.frequency == 1.0


@pytest.mark.parametrize('make, name, value', [
    (lambda: SurfaceParams(normal_stiffness=-5.0), 'surface.normal_stiffness', '-5'),
    (lambda: SurfaceParams(tangential_stiffness=0.0), 'surface.tangential_stiffness', '0'),
    (lambda: RobotParams(mass=0.0), 'robot.mass', '0'),
    (lambda: RobotParams(wavelength=-0.1), 'robot.wavelength', '-0.1'),
    (lambda: IntegrationParams(dt=0.0), 'integration.dt', '0'),
    (lambda: SurfaceParams(friction_coefficient=-0.1), 'surface.friction_coefficient', '-0.1'),
    (lambda: SurfaceParams(restitution=1.5), 'surface.restitution', '1.5'),
    (lambda: ConditionParams(slope=2.0), 'conditions.slope', '2'),
    (lambda: Scenario(conditions=ConditionParams(gap=0.02)), 'conditions.gap', '0.02'),
])
def test_invalid_values_name_parameter_value_and_range(make, name, value):
    with pytest.raises(ParameterError) as err:
        make()
    text = str(err.value)
    assert name in text and value in text and ('allowed' in text or 'must be' in text)


def test_non_numbers_and_nan_are_refused():
    with pytest.raises(ParameterError, match='surface.friction_coefficient'):
        SurfaceParams(friction_coefficient=float('nan'))
    with pytest.raises(ParameterError, match='robot.wave_links'):
        RobotParams(wave_links=2.5)


def test_with_values_validates_and_refuses_unknown_names():
    s = Scenario().with_values({'conditions.slope': math.radians(30), 'motor.voltage': 6.0})
    assert s.conditions.slope == pytest.approx(math.radians(30))
    assert s.frequency == pytest.approx((6.0 - s.motor.dead_voltage) * s.motor.hz_per_volt)
    with pytest.raises(ParameterError, match='unknown parameter'):
        Scenario().with_values({'surface.stiffness': 1.0})
    assert set(Scenario().flat()) >= {'robot.mass', 'surface.normal_stiffness', 'conditions.gap'}
