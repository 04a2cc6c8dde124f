"""
The paper's physics as a pure numpy library: no rclpy import anywhere below this package.

Modules are named after the concepts of the paper: ``params`` (typed parameters), ``kinematics``
(Section 4.1, Appendix A.1), ``contact`` (Section 4.2), ``dynamics`` (Section 4.3), ``statics``
(Section 3), ``metrics`` (Section 5: v_theory, AR, CCI).

The names below are imported when first asked for (PEP 562), not with the package: a process
that needs only ``saw_ros.core.params`` (the recorder, the player, the CLI's argument checks)
would otherwise import numba and load the compiled kernels, about 0.15 s of every start.
"""
from importlib import import_module
from typing import Any, List

_HOME = {
    'DivergenceError': 'dynamics', 'Simulator': 'dynamics', 'Trajectory': 'dynamics',
    'simulate': 'dynamics', 'link_geometry': 'kinematics', 'v_theory': 'kinematics',
    'ConditionParams': 'params', 'IntegrationParams': 'params', 'MotorParams': 'params',
    'ParameterError': 'params', 'RobotParams': 'params', 'Scenario': 'params',
    'SurfaceParams': 'params',
}

__all__ = sorted(_HOME)


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(import_module(f'{__name__}.{_HOME[name]}'), name)
    globals()[name] = value
    return value


def __dir__() -> List[str]:
    return sorted(set(globals()) | set(_HOME))
