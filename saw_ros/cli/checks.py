"""
What every subcommand checks before its long work: paths, file kinds and numbers.

Each check raises ``UserError`` with one line naming the input (its flag), the value and what is
wrong with it (unit and allowed range where one applies; the ranges are the spec() tables'), so
that a mistake is found in the first second, not after a campaign has run.
"""
from __future__ import annotations

from pathlib import Path
import tempfile
from typing import Any, Dict, List, Optional, Sequence

from saw_ros.cli.errors import UserError
from saw_ros.core.params import check_value, ParameterError, Scenario

VIDEO_SUFFIXES = ('.mp4', '.avi')       # what VideoWriter's mp4v codec writes
YAML_SUFFIXES = ('.yaml', '.yml')


def _writable_from(path: Path, flag: str, shown: Path) -> None:
    """Raise unless files can be created at ``path`` (made if needed) or its nearest parent."""
    existing = path
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f'{flag} {shown}: cannot be written: {existing} is a file, not a folder')
    try:
        # Root passes every permission test: only a real file says whether the folder takes one.
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        raise UserError(f'{flag} {shown}: cannot be written in {existing}: '
                        f'{exc.strerror or exc}') from None


def output_file(path, flag: str, suffixes: Sequence[str] = ()) -> Path:
    """Check an output file: its extension (one of ``suffixes``), not a folder, writable."""
    path = Path(path)
    if suffixes and path.suffix.lower() not in suffixes:
        raise UserError(f'{flag} {path}: must end in {" or ".join(suffixes)}')
    if path.is_dir():
        raise UserError(f'{flag} {path}: is a folder; give a file name')
    _writable_from(path.parent, flag, path)
    return path


def output_dir(path, flag: str) -> Path:
    """Check an output folder: not a file, and files can be created in it (or where it goes)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UserError(f'{flag} {path}: is a file, not a folder')
    _writable_from(path, flag, path)
    return path


def input_file(path, flag: str, what: str = 'file') -> Path:
    """Check that an input file exists, is a file and can be read."""
    path = Path(path)
    if not path.exists():
        raise UserError(f'{flag} {path}: no such {what}')
    if path.is_dir():
        raise UserError(f'{flag} {path}: is a folder, not a {what}')
    try:
        with open(path, 'rb') as f:
            f.read(1)
    except OSError as exc:
        raise UserError(f'{flag} {path}: cannot be read: {exc.strerror or exc}') from None
    return path


def text_file(path, flag: str, what: str) -> Path:
    """Check an input that must be text (CSV, YAML): readable and not binary (a video, a bag)."""
    path = input_file(path, flag, what)
    with open(path, 'rb') as f:
        head = f.read(4096)
    binary = b'\0' in head
    try:
        head.decode('utf-8')
    except UnicodeDecodeError as exc:
        # A multi-byte character cut at the end of the sample is still text.
        binary = binary or exc.start < len(head) - 3
    if binary:
        raise UserError(f'{flag} {path}: is not a text {what} (binary content)')
    return path


def params_file(path, flag: str = '--params-file') -> Path:
    """Check a ROS parameters YAML file: text, parses, a mapping."""
    import yaml
    path = text_file(path, flag, 'parameter file (YAML)')
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' (line {mark.line + 1})' if mark is not None else ''
        raise UserError(f'{flag} {path}: is not valid YAML{where}: '
                        f'{getattr(exc, "problem", None) or exc}') from None
    if data is not None and not isinstance(data, dict):
        raise UserError(f'{flag} {path}: is not a parameter file (a YAML mapping such as '
                        f'"simulator: {{ros__parameters: {{...}}}}"; found a '
                        f'{type(data).__name__})')
    return path


def video_input(path, flag: str, fps: float = 0.0):
    """Check a video file OpenCV can read (before any frame is tracked); return its source."""
    from saw_ros.vision.offline import VideoFile
    from saw_ros.vision.video import video_info, VideoError
    input_file(path, flag, 'video file')
    try:
        _, _, width, height = video_info(path)
    except VideoError:
        raise UserError(f'{flag} {path}: not a video OpenCV can decode (a video file: .mp4, '
                        f'.avi, ...)') from None
    if width <= 0 or height <= 0:
        raise UserError(f'{flag} {path}: OpenCV opens it but finds no picture in it')
    return VideoFile(path, fps)


def number(value: float, flag: str, unit: str = '', low: Optional[float] = None,
           high: Optional[float] = None, low_open: bool = False, high_open: bool = False,
           description: str = '') -> float:
    """Check that ``value`` is finite and in the range; the message gives range and unit."""
    meta = {'low': low, 'high': high, 'low_open': low_open, 'high_open': high_open,
            'unit': unit, 'description': description}
    return spec_number(value, flag, meta)


def spec_number(value: float, flag: str, meta: Dict[str, Any], scale: float = 1.0,
                unit: Optional[str] = None, name: str = '') -> float:
    """
    Check a flag's value against a spec() field's range (``meta``): ``check_value``'s check.

    ``scale``: SI per flag unit (pi/180 for a flag in degrees, 1e-3 in mm), ``unit`` the flag's
    unit then; ``name``: the parameter the flag sets, named in the message.
    """
    shown = dict(meta, unit=meta.get('unit', '') if unit is None else unit,
                 low=None if meta.get('low') is None else _round(meta['low'] / scale),
                 high=None if meta.get('high') is None else _round(meta['high'] / scale),
                 description=', '.join(t for t in (name, meta.get('description', '')) if t))
    try:
        return check_value(flag, value, shown, default=value if isinstance(value, int) and
                           not isinstance(value, bool) else 0.0)
    except ParameterError as exc:
        raise UserError(str(exc).replace(' ()', '')) from None


def spec_numbers(text: str, name: str, parameter: str, scale: float = 1.0,
                 unit: Optional[str] = None) -> List[float]:
    """
    Return the comma-separated values of --``name``, each checked against ``parameter``'s range.

    ``scale`` and ``unit`` as ``spec_number``'s (a list in degrees: pi/180, 'deg').
    """
    try:
        values = [float(v) for v in text.split(',') if v.strip()]
    except ValueError:
        raise UserError(f'--{name} {text!r}: expects comma-separated numbers') from None
    if not values:
        raise UserError(f'--{name} is empty')
    meta = {n: m for n, _, m in Scenario().describe()}[parameter]
    for v in values:
        spec_number(v, f'--{name}', meta, scale, unit, parameter)
    return values


def _round(value: float) -> float:
    """Return a range end in the flag's unit without the conversion's float noise (90.0000001)."""
    return float(f'{value:.6g}')
