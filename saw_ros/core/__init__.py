"""
The paper's physics as a pure numpy library: no rclpy import anywhere below this package.

Modules are named after the concepts of the paper: ``params`` (typed parameters), ``kinematics``
(Section 4.1, Appendix A.1), ``contact`` (Section 4.2), ``dynamics`` (Section 4.3), ``statics``
(Section 3), ``metrics`` (Section 5: v_theory, AR, CCI).
"""
from saw_ros.core.dynamics import DivergenceError, simulate, Simulator, Trajectory
from saw_ros.core.kinematics import link_geometry, v_theory
from saw_ros.core.params import (ConditionParams, IntegrationParams, MotorParams, ParameterError,
                                 RobotParams, Scenario, SurfaceParams)

__all__ = ['ConditionParams', 'DivergenceError', 'IntegrationParams', 'MotorParams',
           'ParameterError', 'RobotParams', 'Scenario', 'Simulator', 'SurfaceParams',
           'Trajectory', 'link_geometry', 'simulate', 'v_theory']
