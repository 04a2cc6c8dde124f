"""
Message definitions and type hashes as rosbag2 stores them in an MCAP schema.

rosbag2 (``rosbag2_cpp/.../local_message_definition_source.cpp``) builds a ``ros2msg`` schema from
the installed ``share/<pkg>/msg/<Type>.msg`` files: the root text, then every dependency once,
depth first, in sorted order of the names found in each text, each one introduced by a line of 80
``=`` and ``MSG: <pkg>/<Type>``. The type hash is ``type_hashes[0]`` of the ``.json`` beside it.
The files are looked up without ``AMENT_PREFIX_PATH`` when possible (``saw_ros.interface.share``).
"""
from __future__ import annotations

import functools
import json
import re
from typing import Set, Tuple

from saw_ros.interface.share import PackageNotFound, share_file

# The same pattern rosbag2 uses: the first word of a line followed by blanks is a field type.
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
               'int32', 'uint32', 'int64', 'uint64', 'string'}
_DELIMITER = '=' * 80 + '\n'


class UnknownMessageType(LookupError):
    """No installed definition for this message type."""


def split_type(type_name: str) -> Tuple[str, str, str]:
    """``pkg/msg/Type`` or ``pkg/Type`` -> (pkg, 'msg', Type)."""
    parts = type_name.split('/')
    if len(parts) == 2:
        return parts[0], 'msg', parts[1]
    if len(parts) == 3:
        return parts[0], parts[1], parts[2]
    raise UnknownMessageType(f'not a ROS message type name: {type_name!r}')


def _share_file(type_name: str, extension: str) -> str:
    """
    ``share/<pkg>/<namespace>/<Type><extension>`` of the installed interface package.

    Found beside its Python package (no sourced environment needed), else through the ament index.
    """
    pkg, namespace, name = split_type(type_name)
    try:
        return share_file(pkg, namespace, name + extension)
    except PackageNotFound as exc:
        raise UnknownMessageType(f'{type_name}: {exc}') from None


def check_definitions() -> None:
    """
    Raise UnknownMessageType if message definitions cannot be found at all.

    Its message is one line saying what to source; a recorder calls this before creating its bag.
    """
    message_definition('builtin_interfaces/msg/Time')


@functools.lru_cache(maxsize=None)
def _msg_text(type_name: str) -> str:
    with open(_share_file(type_name, '.msg'), encoding='utf-8', newline='') as f:
        return f.read()


def _dependencies(text: str, package: str) -> list:
    found: Set[str] = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        found.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(found)


@functools.lru_cache(maxsize=None)
def message_definition(type_name: str) -> str:
    """Return the ``ros2msg`` schema text of ``type_name`` (``geometry_msgs/msg/PoseStamped``)."""
    seen: Set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise UnknownMessageType(f'definition of {type_name} nests too deep')
        text = _msg_text(name)
        for dep in _dependencies(text, split_type(name)[0]):
            if dep not in seen:
                seen.add(dep)
                text += '\n' + _DELIMITER + f'MSG: {dep}\n' + append(dep, depth - 1)
        return text

    return append(type_name, 50)


@functools.lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """``RIHS01_<sha256>`` from ``share/<pkg>/msg/<Type>.json`` ('' when the file has none)."""
    try:
        path = _share_file(type_name, '.json')
    except UnknownMessageType:
        return ''
    with open(path, encoding='utf-8') as f:
        hashes = json.load(f).get('type_hashes', [])
    return hashes[0]['hash_string'] if hashes else ''
