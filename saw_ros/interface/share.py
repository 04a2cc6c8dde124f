"""
Where an installed ROS package keeps its ``share/<pkg>`` files, without a sourced environment.

Every install of a ROS package is an install prefix laid out alike: the pip venv of
``scripts/bootstrap.sh`` (``.venv/lib/python3.11/site-packages/<pkg>``, ``.venv/share/<pkg>``),
``/opt/ros/jazzy`` (``.../local/lib/python3.12/dist-packages/<pkg>``,
``/opt/ros/jazzy/share/<pkg>``) and a colcon workspace
(``install/<pkg>/lib/python3.X/site-packages/<pkg>``, ``install/<pkg>/share/<pkg>``, or the
merged ``install/lib/...``). So the share directory of a package with Python code (every message
package, and saw_ros) is found by walking up from where Python imports it to the first folder
holding the package's ament index marker (``share/ament_index/resource_index/packages/<pkg>``)
or ``share/<pkg>/package.xml``: that needs no ``AMENT_PREFIX_PATH``, and gives the files of the
very package whose Python classes are in use. The ament index (the prefixes of
``AMENT_PREFIX_PATH``, as ``ament_index_python`` reads them) comes second, for packages without
Python code or installed elsewhere.

No rclpy, no ament_index_python import.
"""
from __future__ import annotations

import importlib.util
import os
from typing import List, Optional

SOURCE_HINT = ('source the setup of the ROS install that has it (scripts/bootstrap.sh for the '
               'venv, /opt/ros/jazzy/setup.bash, or <workspace>/install/setup.bash)')


class PackageNotFound(LookupError):
    """No install prefix holds this package's share directory."""


def _is_prefix_of(prefix: str, package: str) -> bool:
    return (os.path.isfile(os.path.join(prefix, 'share', 'ament_index', 'resource_index',
                                        'packages', package))
            or os.path.isfile(os.path.join(prefix, 'share', package, 'package.xml')))


def python_locations(package: str) -> List[str]:
    """Folders (or the module file) Python imports ``package`` from; [] if it has none."""
    try:
        spec = importlib.util.find_spec(package)
    except (ImportError, ValueError):
        return []
    if spec is None:
        return []
    if spec.submodule_search_locations:
        return [str(p) for p in spec.submodule_search_locations]
    return [spec.origin] if spec.origin and os.path.isabs(spec.origin) else []


def prefix_above(path: str, package: str) -> Optional[str]:
    """
    Return the nearest folder above ``path`` that is an install prefix of ``package``.

    Symbolic links are not resolved: a colcon --symlink-install prefix links its files into the
    build folder, and the prefix is where the link is, not where it points.
    """
    folder = os.path.dirname(os.path.abspath(path))
    while True:
        if _is_prefix_of(folder, package):
            return folder
        parent = os.path.dirname(folder)
        if parent == folder:
            return None
        folder = parent


def ament_prefixes(package: str) -> List[str]:
    """Return the prefixes of ``AMENT_PREFIX_PATH`` that list ``package`` in their ament index."""
    value = os.environ.get('AMENT_PREFIX_PATH', '')
    return [p for p in value.split(os.pathsep) if p and os.path.isfile(
        os.path.join(p, 'share', 'ament_index', 'resource_index', 'packages', package))]


def share_directories(package: str) -> List[str]:
    """
    Candidate ``share/<package>`` folders, best first.

    Beside the imported Python package, then from the ament index. Not cached: the environment may
    change between calls.
    """
    found: List[str] = []
    for location in python_locations(package):
        prefix = prefix_above(location, package)
        if prefix is not None:
            found.append(os.path.join(prefix, 'share', package))
    found += [os.path.join(p, 'share', package) for p in ament_prefixes(package)]
    unique = []
    for folder in found:
        if folder not in unique and os.path.isdir(folder):
            unique.append(folder)
    return unique


def not_found_message(package: str, what: str = '') -> str:
    """One line: what is missing and what to source."""
    where = os.environ.get('AMENT_PREFIX_PATH') or 'not set'
    return (f"package '{package}' not found{' (' + what + ')' if what else ''}: no install "
            f'prefix beside its Python package, AMENT_PREFIX_PATH {where}; {SOURCE_HINT}')


def share_file(package: str, *parts: str) -> str:
    """``<share of package>/<parts...>``, from the first candidate share folder that has it."""
    folders = share_directories(package)
    for folder in folders:
        path = os.path.join(folder, *parts)
        if os.path.isfile(path):
            return path
    if folders:
        raise PackageNotFound(f"package '{package}' has no {'/'.join(parts)} "
                              f"(looked in {', '.join(folders)})")
    raise PackageNotFound(not_found_message(package, '/'.join(parts)))
