"""
YAML parameter files (``msg_config/``) <-> the core's Scenario: one source of truth.

A file is a ROS 2 parameters file (``<node>: {ros__parameters: {...}}``); inside, parameters are
written either flat with dots (``surface.normal_stiffness: 15500.0``) or nested
(``surface: {normal_stiffness: 15500.0}``), exactly the names of ``Scenario.flat()``. Values are
SI. No rclpy import: the offline commands read the same files as the nodes.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, Optional

from saw_ros.core.params import ParameterError, Scenario
import yaml

CONFIG_DIR = Path(__file__).resolve().parents[2] / 'msg_config'


def config_path(name: str) -> Path:
    """
    Return a file of msg_config/.

    From the source tree (a checkout, an editable install), else from the installed
    ``share/saw_ros/msg_config`` (pip or colcon install, found from this package's own location,
    then the ament index; no sourced environment needed).
    """
    local = CONFIG_DIR / name
    if local.exists():
        return local
    from saw_ros.interface.share import PackageNotFound, share_file
    try:
        return Path(share_file('saw_ros', 'msg_config', name))
    except PackageNotFound:  # report the source-tree path in the caller's error
        return local


def flatten(tree: Dict[str, Any], prefix: str = '') -> Dict[str, Any]:
    flat = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            flat.update(flatten(value, name + '.'))
        else:
            flat[name] = value
    return flat


def load_parameters(path: Path, node: Optional[str] = None) -> Dict[str, Any]:
    """Return the flat parameter dict of one node's section (or the only / wildcard section)."""
    path = Path(path)
    if not path.exists():
        raise ParameterError(f'parameter file {path} does not exist')
    data = yaml.safe_load(path.read_text()) or {}
    sections = {k: v for k, v in data.items() if isinstance(v, dict) and 'ros__parameters' in v}
    if not sections:
        return flatten(data)
    for key in ([node] if node else []) + ['/**', '**']:
        if key in sections:
            return flatten(sections[key]['ros__parameters'])
    if len(sections) == 1:
        return flatten(next(iter(sections.values()))['ros__parameters'])
    raise ParameterError(f'{path} has sections {sorted(sections)}; none is for node {node!r}')


def scenario_from_parameters(values: Dict[str, Any], base: Optional[Scenario] = None) -> Scenario:
    """
    Scenario from a flat dict.

    Names that are not model parameters are ignored here (node options such as real_time_factor
    live beside them in the same file).
    """
    base = base or Scenario()
    known = set(base.flat())
    return base.with_values({k: v for k, v in values.items() if k in known})


def load_scenario(path: Path, node: str = 'simulator',
                  base: Optional[Scenario] = None) -> Scenario:
    """Return the Scenario of ``node``'s parameters in the parameter file ``path``."""
    return scenario_from_parameters(load_parameters(path, node), base)
