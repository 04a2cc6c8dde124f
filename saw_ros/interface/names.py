"""
ROS 2 topic names checked without ROS: the rules rcl applies, for layers that must not load rclpy.

``saw-ros bag record`` refuses a topic the recorder could never subscribe to before it starts
the node; the CLI layer imports no rclpy (tests/packaging/test_layers.py), so the rules rcl
checks a topic name against (``rcl_validate_topic_name``: the name as written, before it is
expanded with the node's namespace) are written out here, and tests/interface/test_names.py holds
them to rclpy's own ``validate_topic_name``, name by name.
"""
from __future__ import annotations

from typing import Optional


def _word_char(c: str) -> bool:
    return c == '_' or (c.isascii() and c.isalnum())


def topic_name_problem(name: str) -> Optional[str]:
    """
    Return what makes ``name`` an invalid ROS topic name, or None when it is valid.

    Relative (``scan``), absolute (``/saw/pose``), private (``~/out``) names and substitutions
    (``{node}/out``) are valid; the reason names the first rule the name breaks.
    """
    if not name:
        return 'it is empty'
    if name[0].isdigit():
        return 'it starts with a number'
    if name.endswith('/'):
        return "it ends with '/'"
    opened: Optional[int] = None
    for i, c in enumerate(name):
        if _word_char(c) or c in '/~':
            continue
        if c == '{':
            if opened is not None:
                return f"'{{' at {i} inside another substitution"
            opened = i
        elif c == '}':
            if opened is None:
                return f"'}}' at {i} closes no substitution"
            opened = None
        else:
            return f'{c!r} at {i}: only letters, digits, _, /, ~, {{ and }} are allowed'
    if opened is not None:
        return f"'{{' at {opened} is never closed"
    for i, c in enumerate(name):
        if c == '~' and i != 0:
            return f"'~' at {i}: only the first character may be '~'"
        # rcl looks at the character after a '~' only when another follows it: '~a' passes,
        # '~ab' does not (Jazzy's rclpy, tests/interface/test_names.py).
        if c == '~' and len(name) > 2 and name[1] != '/':
            return "'~' is not followed by '/'"
        if c == '/' and i + 1 < len(name) and name[i + 1].isdigit():
            return f'the part after the / at {i} starts with a number'
        if c == '{':
            inside = name[i + 1:name.index('}', i)]
            if inside[:1].isdigit():
                return f'the substitution at {i} starts with a number'
            if not all(_word_char(ch) for ch in inside):
                return f'the substitution at {i} holds other than letters, digits and _'
    return None
