"""
Numbers for people: a value that could not be computed is said in words, never printed as nan.

``shown(value, '.3f', ' cm/s', why)`` is the value formatted, or ``why`` (the reason and what to
do) when it is None or not finite. Every report the command line prints goes through it.
"""
from __future__ import annotations

import math
from typing import Optional


def finite(value) -> bool:
    """Return True for a finite number (not None, nan or inf)."""
    try:
        return value is not None and math.isfinite(value)
    except TypeError:
        return False


def shown(value, spec: str, unit: str = '', why: Optional[str] = None, scale: float = 1.0) -> str:
    """Return ``value * scale`` formatted with ``spec`` and ``unit``, or ``why`` in words."""
    if finite(value):
        return f'{value * scale:{spec}}{unit}'
    return why or 'not computed'
