"""
Recorded footage as the campaign's experiment: ``saw-ros campaign --videos MANIFEST.csv``.

The paper's Section 6 compares its model with videos of the real robot. Here each row of a
manifest (CSV) is one recorded run: the video, the slope, the motor voltage (or the helix
frequency), the scale (px per metre, or the markers' spacing on the robot) and notes. Each video
is tracked by the offline tracker (``saw_ros.vision.offline``, what ``saw-ros track`` runs); the
measured speed is the least-squares slope of the tracked COM position over the whole wave cycles
at the end of the clip (the ripple within a cycle cancels; a clip shorter than a cycle is used
whole). The same conditions are simulated as one batch (``saw_ros.core.simulate``, as
``analysis.campaign.run_campaign``) and the simulated speed is the campaign's: the mean over whole
cycles after steady state (``analysis.compare.RunComparator``). AR = speed / v_theory; the
relative error is |AR_measured - AR_sim| / AR_sim.

Outputs (``write_footage_outputs``): the campaign's table and Figures 17 and 18
(``analysis.campaign.write_outputs``: ``campaign.csv``, ``campaign.md``, ``figure17_speed.png``,
``figure18_ar.png``, "tracked" meaning measured on the footage), ``footage.csv`` (one row per
video: condition columns, then measured speed and AR, the targets a calibration fits the model
to, then the simulation and the tracking counts), ``footage.md`` and ``frames/<video>.csv``
(every frame's tracking status, as ``saw-ros track --csv``).

``make_clip`` and ``make_samples`` make footage with a known answer from our own simulation
(clean, or cluttered as ``vision.scene`` does): the sample manifest in samples/footage/.
No rclpy import.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
import math
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from saw_ros.analysis.campaign import (ConditionResult, duration_for, missing_note,
                                       notes_markdown, summarise, write_outputs)
from saw_ros.analysis.compare import RunComparator
from saw_ros.analysis.shown import shown
from saw_ros.core import Scenario, simulate
from saw_ros.core.kinematics import v_theory
from saw_ros.core.metrics import run_frequency, run_turns
from saw_ros.vision.camera import FPS

MANIFEST_COLUMNS = ('video', 'slope_deg', 'voltage_V', 'frequency_hz', 'px_per_m',
                    'marker_spacing_m', 'fps', 'notes', 'camera_calibration', 'plane')
TARGET_COLUMNS = ('video', 'slope_deg', 'voltage_V', 'frequency_hz', 'v_measured',
                  'ar_measured', 'window_s', 'v_theory', 'v_sim', 'ar_sim', 'relative_error',
                  'frames', 'frames_ok', 'px_per_m', 'scale_from', 'notes')
FRAME_COLUMNS = ('frame', 't', 'status', 'front_x', 'front_y', 'back_x', 'back_y', 'x', 'y',
                 'pitch_deg')


class ManifestError(ValueError):
    """The manifest cannot be used (the message says which row and why)."""


@dataclass
class FootageRun:
    """One manifest row."""

    video: Path
    slope_deg: float
    voltage: Optional[float] = None
    frequency: Optional[float] = None
    px_per_m: Optional[float] = None
    marker_spacing: Optional[float] = None
    notes: str = ''
    fps: float = 0.0           # frames per second: a folder of frames needs it; 0 = the file's
    camera_calibration: Optional[Path] = None   # the lens (ROS camera calibration YAML)
    plane: Optional[Path] = None                # the plane of motion (calibrate-camera's)

    def scenario(self, base: Scenario) -> Scenario:
        values = {'conditions.slope': math.radians(self.slope_deg)}
        if self.voltage is not None:
            values['motor.voltage'] = self.voltage
        elif self.frequency is not None:
            values.update({'motor.voltage': 0.0, 'conditions.frequency': self.frequency})
        else:       # read_manifest refuses such a row: one of the two is required
            raise ManifestError(f'{self.video}: neither voltage_V nor frequency_hz')
        return base.with_values(values)


def load_manifest(path) -> List[FootageRun]:
    """Return the rows of a manifest; video paths relative to the manifest's folder."""
    path = Path(path)
    if not path.is_file():
        raise ManifestError(f'no such manifest: {path}')
    with open(path, newline='') as f:
        reader = csv.DictReader(row for row in f if row.strip() and not row.startswith('#'))
        names = [n.strip() for n in reader.fieldnames or []]
        reader.fieldnames = names
        unknown = [n for n in names if n not in MANIFEST_COLUMNS]
        if 'video' not in names or 'slope_deg' not in names or unknown:
            raise ManifestError(f'{path}: columns must be {", ".join(MANIFEST_COLUMNS)} (video, '
                                f'slope_deg, one of voltage_V/frequency_hz and one of px_per_m/'
                                f'marker_spacing_m required)'
                                + (f'; unknown: {", ".join(unknown)}' if unknown else ''))
        runs = []
        for line, row in enumerate(reader, start=2):
            runs.append(_row(path, line, {k: (v or '').strip() for k, v in row.items()
                                          if k is not None}))
    if not runs:
        raise ManifestError(f'{path}: no runs')
    return runs


def _row(path: Path, line: int, row: Dict[str, str]) -> FootageRun:
    where = f'{path}, row {line}'

    def number(name, positive=True):
        text = row.get(name, '')
        if not text:
            return None
        try:
            value = float(text)
        except ValueError:
            raise ManifestError(f'{where}: {name} = {text!r} is not a number') from None
        if not math.isfinite(value) or (positive and not value > 0):
            raise ManifestError(f'{where}: {name} = {text!r} must be a number > 0')
        return value

    if not row.get('video'):
        raise ManifestError(f'{where}: no video')
    slope = number('slope_deg', positive=False)
    if slope is None or abs(slope) > 90:
        raise ManifestError(f'{where}: slope_deg must be given, in [-90, 90]')
    files = {}
    for name in ('camera_calibration', 'plane'):
        if row.get(name):
            files[name] = path.parent / row[name]
            if not files[name].is_file():
                raise ManifestError(f'{where}: {name}: no such file: {files[name]}')
    run = FootageRun(path.parent / row['video'], slope, number('voltage_V'),
                     number('frequency_hz'), number('px_per_m'), number('marker_spacing_m'),
                     row.get('notes', ''), number('fps') or 0.0, **files)
    if run.video.is_dir():
        if not run.fps:
            raise ManifestError(f'{where}: {run.video} is a folder of frames: give its fps')
    elif not run.video.is_file():
        raise ManifestError(f'{where}: no such video file or folder of frames: {run.video}')
    if (run.voltage is None) == (run.frequency is None):
        raise ManifestError(f'{where}: give one of voltage_V and frequency_hz')
    if run.plane is not None and run.px_per_m is not None:
        raise ManifestError(f'{where}: px_per_m and plane both set the scale: give one')
    if run.px_per_m is None and run.marker_spacing is None and run.plane is None:
        raise ManifestError(f'{where}: give the scale: px_per_m, marker_spacing_m or plane')
    return run


# -- measuring ---------------------------------------------------------------------------------
@dataclass
class Measured:
    results: list                   # the tracker's FrameResults, every frame
    px_per_m: float
    scale_from: str                 # 'px_per_m', 'marker_spacing' or 'plane'
    speed: float                    # m/s, NaN without enough ok frames
    window: float                   # s the speed was measured over
    frames: int
    frames_ok: int
    perspective: str = ''           # the tracker's warning of a perspective along the track


def clip_speed(t, x, frequency: float) -> tuple:
    """
    Return (speed, window): the least-squares slope of x over the last whole wave cycles.

    Over all the samples when they are shorter than a cycle.
    """
    t, x = np.asarray(t, float), np.asarray(x, float)
    if t.size < 3:
        return float('nan'), 0.0
    span = t[-1] - t[0]
    cycles = math.floor(span * frequency + 1e-6) if frequency > 0 else 0
    window = cycles / frequency if cycles >= 1 else span
    keep = t >= t[-1] - window - 1e-9
    tc = t[keep] - t[keep].mean()
    return float(np.dot(tc, x[keep] - x[keep].mean()) / np.dot(tc, tc)), float(window)


def measure(run: FootageRun, frequency: float, config=None, center_x: float = 0.0) -> Measured:
    """
    Track one video (the scale from px_per_m, else from the marker spacing) and measure its speed.

    Raises VideoError for an unreadable video.
    """
    import dataclasses

    from saw_ros.vision import calibration, perspective
    from saw_ros.vision.camera import CameraModel
    from saw_ros.vision.offline import measure_plane, open_source, track_video
    from saw_ros.vision.tracker import TrackerConfig
    config = config or TrackerConfig()
    if run.marker_spacing is not None:
        config = dataclasses.replace(config, marker_spacing=run.marker_spacing)
    camera_kw: Dict[str, Any] = {'slope': math.radians(run.slope_deg), 'center_x': center_x}
    try:
        if run.camera_calibration is not None:
            camera_kw.update(calibration.read_lens(run.camera_calibration).camera_kw())
        if run.plane is not None:
            camera_kw['plane'] = tuple(calibration.read_plane(run.plane).ravel())
    except calibration.CalibrationError as exc:
        raise ManifestError(f'{run.video}: {exc}') from None
    if run.plane is not None:
        width, height = open_source(run.video, run.fps).size
        scale = CameraModel(width=width, height=height, **camera_kw).scale
        source = 'plane'
    elif run.px_per_m is not None:
        scale, source = run.px_per_m, 'px_per_m'
    else:
        # the scale where the robot is: a perspective along the track is measured too
        found = measure_plane(run.video, camera_kw, config, config.marker_spacing, run.fps)
        if found is None:
            raise ManifestError(f'{run.video}: the marker spacing could not be measured (no '
                                f'frame with both markers told apart): give px_per_m')
        scale, source = found.scale, 'marker_spacing'
        camera_kw = found.camera_kw(camera_kw)
    results, tracker = track_video(run.video, dict(camera_kw, scale=scale), config, run.fps)
    ok = [r for r in results if r.ok]
    speed, window = clip_speed([r.t for r in ok], [r.position.real for r in ok], frequency)
    along = tracker.perspective()
    seen = perspective.warning(along, f'{source} {scale:.1f} px/m') \
        if along is not None and along.significant else ''
    return Measured(results, scale, source, speed, window, len(results), len(ok), seen)


def simulate_conditions(scenarios: Sequence[Scenario]) -> List[tuple]:
    """
    (v_sim, ar_sim, steady_from, frequency, note) of each scenario, simulated as one batch.

    The speed is the campaign's: whole cycles after steady state (RunComparator, truth against
    itself). ``frequency``: the helix's, which a motor reaches under load (``run_frequency``).
    ``note``: why a speed is missing (not steady) and what to do, '' when there is one.
    """
    duration = max(duration_for(s.frequency) for s in scenarios)
    trajectory = simulate(list(scenarios), duration)
    out = []
    for i, s in enumerate(scenarios):
        comp = RunComparator(s.robot, s.frequency)
        for t, x in zip(trajectory.t, trajectory.q[:, i, 0]):
            comp.add_truth(t, x)
            comp.add_tracked(t, x)
        if s.motor.voltage > 0.0:
            for row in zip(trajectory.t, run_turns(trajectory, i)):
                comp.add_helix(*row)
        r = comp.result()
        out.append((r.v_sim, r.ar_sim, r.steady_from, r.frequency, '') if r.steady else
                   (float('nan'), float('nan'), float('nan'), run_frequency(trajectory, i),
                    missing_note(r, duration, s)))
    return out


@dataclass
class FootageResult:
    run: FootageRun
    condition: ConditionResult
    measured: Measured
    extra: dict = field(default_factory=dict)


def run_footage(runs: Sequence[FootageRun], base: Optional[Scenario] = None, config=None,
                progress=None) -> List[FootageResult]:
    base = base or Scenario()
    scenarios = [r.scenario(base) for r in runs]
    simulated = simulate_conditions(scenarios)
    if progress is not None:
        progress(0)
    out = []
    for run, s, simulation in zip(runs, scenarios, simulated):
        v_sim, ar_sim, steady_from, frequency, note = simulation
        # The real helix's speed under load is not measured: take the simulated one (its whole
        # cycles, and the v_theory the measured and simulated AR share).
        m = measure(run, frequency, config)
        vth = v_theory(s.robot, frequency)
        ar = m.speed / vth
        voltage = run.voltage if run.voltage is not None else \
            s.motor.dead_voltage + s.frequency / s.motor.hz_per_volt if s.motor.hz_per_volt > 0 \
            else float('nan')
        cond = ConditionResult(run.slope_deg, voltage, frequency, vth, v_sim, m.speed, ar_sim,
                               ar, abs(ar - ar_sim) / abs(ar_sim), steady_from, m.frames,
                               m.frames_ok, note=note)
        if not math.isfinite(m.speed):
            lost = (f'too few frames with both markers ({m.frames_ok} of {m.frames}) to measure '
                    f'a speed: look at the tracking with saw-ros track {run.video} --px-per-m '
                    f'{m.px_per_m:g} --plot track.png')
            cond.note = f'{cond.note}; {lost}' if cond.note else lost
        if m.perspective:
            cond.note = f'{cond.note}; {m.perspective}' if cond.note else m.perspective
        out.append(FootageResult(run, cond, m))
        if progress is not None:
            progress(1)
    return out


# -- outputs -----------------------------------------------------------------------------------
def _f(value, fmt='.6g'):
    return '' if value is None or (isinstance(value, float) and not math.isfinite(value)) \
        else format(value, fmt)


def write_footage_outputs(results: List[FootageResult], out) -> Dict[str, Path]:
    out = Path(out)
    paths = write_outputs([r.condition for r in results], out, measured='your footage')
    paths['targets'] = out / 'footage.csv'
    paths['footage_md'] = out / 'footage.md'
    frames_dir = out / 'frames'
    frames_dir.mkdir(parents=True, exist_ok=True)
    with open(paths['targets'], 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(TARGET_COLUMNS)
        for r in results:
            c, m, run = r.condition, r.measured, r.run
            w.writerow([run.video.name, _f(c.slope_deg), _f(run.voltage), _f(c.frequency),
                        _f(c.v_tracked), _f(c.ar_tracked), _f(m.window), _f(c.v_theory),
                        _f(c.v_sim), _f(c.ar_sim), _f(c.relative_error), m.frames, m.frames_ok,
                        _f(m.px_per_m), m.scale_from, run.notes])
    used = set()
    for r in results:
        stem = r.run.video.stem
        name, k = stem, 1
        while name in used:
            k += 1
            name = f'{stem}_{k}'
        used.add(name)
        path = frames_dir / f'{name}.csv'
        paths[f'frames {r.run.video.name}'] = path
        with open(path, 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow(FRAME_COLUMNS)
            for k, fr in enumerate(r.measured.results):
                w.writerow([k, f'{fr.t:.6f}', str(fr.status), *_xy(fr.front), *_xy(fr.back),
                            *_xy(fr.position),
                            '' if fr.pitch is None else f'{math.degrees(fr.pitch):.4f}'])
    paths['footage_md'].write_text(footage_markdown(results))
    return paths


def _xy(p):
    return ('', '') if p is None else (f'{p.real:.6f}', f'{p.imag:.6f}')


def footage_markdown(results: List[FootageResult]) -> str:
    summary = summarise([r.condition for r in results])
    lines = ['# Footage against simulation', '',
             'Each video tracked (two pink markers); measured speed = least-squares slope of the '
             'tracked position over the whole wave cycles at the end of the clip; simulated = '
             'mean over whole cycles after steady state; AR = speed / v_theory; relative error '
             '= |AR_measured - AR_sim| / AR_sim. Figures 17 and 18 and campaign.csv: '
             '"tracked" is measured on the footage.', '',
             '| video | slope (deg) | voltage (V) | f (Hz) | scale (px/m) | frames ok | window '
             '(s) | v measured (cm/s) | v sim (cm/s) | AR measured | AR sim | rel. error (%) | '
             'notes |', '|' + '---|' * 13]
    for r in results:
        c, m = r.condition, r.measured
        lines.append(f'| {r.run.video.name} | {c.slope_deg:g} | {_f(r.run.voltage, "g")} | '
                     f'{c.frequency:.3f} | {m.px_per_m:.1f} ({m.scale_from}) | '
                     f'{m.frames_ok}/{m.frames} | {m.window:.2f} | '
                     f'{shown(c.v_tracked, ".3f", why="-", scale=100)} | '
                     f'{shown(c.v_sim, ".3f", why="-", scale=100)} | '
                     f'{shown(c.ar_tracked, ".4f", why="-")} | '
                     f'{shown(c.ar_sim, ".4f", why="-")} | '
                     f'{shown(c.relative_error, ".2f", why="-", scale=100)} | {r.run.notes} |')
    lines += ['', '| voltage (V) | mean relative error (%) |', '|---|---|']
    for v, e in summary['mean_relative_error_by_voltage'].items():
        lines.append(f'| {v:g} | {shown(e, ".2f", why="-", scale=100)} |')
    lines.append(f'| all | {shown(summary["mean_relative_error"], ".2f", why="-", scale=100)} |')
    lines += notes_markdown([r.condition for r in results])
    return '\n'.join(lines) + '\n'


# -- footage with a known answer ---------------------------------------------------------------
SAMPLE_SIZE = (320, 180)         # px (small: the samples live in git)
SAMPLE_SCALE = 600.0             # px/m: 0.53 m x 0.3 m of track, markers 7 px across
SAMPLE_FPS = 30.0                # the paper filmed at 60; half the bytes
SAMPLES = (                      # name, slope (deg), voltage, cluttered
    ('level_6V.mp4', 0.0, 6.0, False),             # three slopes at 6 V: Figure 17 (A)'s fit
    ('climb_10deg_6V.mp4', 10.0, 6.0, False),
    ('descend_-10deg_6V.mp4', -10.0, 6.0, False),
    ('cluttered_level_4V.mp4', 0.0, 4.0, True),    # level at 4 and 6 V: (B)'s fit
)


def clutter_for(camera, gap: float, t_end: float, flicker: float = 0.0):
    """
    Return a busy scene for a clip seen by ``camera``.

    Red, orange-red and orange things (one passing in front), a magenta disc and a third pink
    marker on the wall away from the robot's line, a lighting gradient and optionally flicker
    (vision.scene).
    """
    from saw_ros.vision.scene import (HOT_PINK, MAGENTA, ORANGE, ORANGE_RED, RED, Clutter,
                                      SceneOptions)
    x0, x1 = camera.visible_x_range(0.0)
    mid = gap / 2.0
    half = 0.5 * camera.height / camera.scale
    top, bottom = mid + 0.75 * half, mid - 0.75 * half
    marker = (0.012, 0.012)
    things = (
        Clutter(RED, x0 + 0.06, top, (0.05, 0.05)),
        Clutter(ORANGE_RED, x1 - 0.07, top, (0.08, 0.04), 'box'),
        Clutter(ORANGE, x0 + 0.05, bottom, (0.04, 0.04), velocity=(0.5 * (x1 - x0) / t_end, 0.0),
                layer='front'),
        Clutter(MAGENTA, 0.5 * (x0 + x1), top, marker),
        Clutter(HOT_PINK, x1 - 0.05, bottom, marker),
    )
    return SceneOptions(clutter=things, gradient=0.3, gradient_angle=math.radians(30),
                        flicker=flicker)


def make_clip(scenario: Scenario, path, start: float = 1.2, duration: float = 2.0,
              fps: float = FPS, size=SAMPLE_SIZE, scale: float = SAMPLE_SCALE,
              cluttered: bool = False, noise: float = 0.0, texture: bool = False) -> dict:
    """
    Simulate ``scenario`` and write the frames of [start, start + duration) as an .mp4.

    Video time 0 is ``start``; the camera is centred on the robot's path over the clip. Returns
    the ground truth: {'t': frame times (video), 'x': true COM x, 'speed': least-squares speed over
    the clip's whole cycles, 'px_per_m', 'frequency', 'center_x', 'center_y'}.
    """
    from saw_ros.vision.camera import CameraModel
    from saw_ros.vision.frames import Renderer, RenderOptions
    from saw_ros.vision.scene import SceneOptions
    from saw_ros.vision.synthetic import simulate_run
    from saw_ros.vision.video import VideoWriter
    run = simulate_run(scenario, start + duration + 0.1)
    # (a motor turns the helix below its no-load frequency: the clip's cycles are the helix's)
    if run.trajectory is None:
        raise RuntimeError('simulate_run kept no trajectory')
    frequency = run_frequency(run.trajectory)
    n = int(round(duration * fps))
    times = start + np.arange(n) / fps
    xs = np.interp(times, run.t, run.x)
    gap = scenario.conditions.gap
    camera = CameraModel(width=int(size[0]), height=int(size[1]), scale=float(scale),
                         slope=scenario.conditions.slope,
                         center_x=float(0.5 * (xs[0] + xs[-1])), center_y=gap / 2.0)
    scene = clutter_for(camera, gap, duration) if cluttered else SceneOptions()
    renderer = Renderer(scenario.robot, gap, camera,
                        RenderOptions(noise=noise, exposure=1 / fps if cluttered else 0.0,
                                      texture=texture, seed=7), scene)
    with VideoWriter(path, fps, (camera.width, camera.height)) as writer:
        for t in times:
            writer.write(renderer.render(run.pose_at(t), (), run.pose_at, t))
    speed, window = clip_speed(times - start, xs, frequency)
    return {'t': times - start, 'x': xs, 'speed': speed, 'window': window,
            'px_per_m': camera.scale, 'frequency': frequency,
            'center_x': camera.center_x, 'center_y': camera.center_y}


def make_samples(folder, base: Optional[Scenario] = None, samples=SAMPLES) -> Path:
    """Write the sample clips and their manifest (manifest.csv) into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    base = base or Scenario()
    rows = []
    for k, (name, slope, volts, cluttered) in enumerate(samples):
        s = base.with_values({'conditions.slope': math.radians(slope), 'motor.voltage': volts})
        truth = make_clip(s, folder / name, fps=SAMPLE_FPS, cluttered=cluttered)
        scale = ('', '0.32') if k % 2 else (f'{truth["px_per_m"]:g}', '')
        rows.append([name, f'{slope:g}', f'{volts:g}', '', *scale,
                     f'generated from our simulation ({"cluttered" if cluttered else "clean"}); '
                     f'true clip speed {100 * truth["speed"]:.3f} cm/s'])
    manifest = folder / 'manifest.csv'
    with open(manifest, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(MANIFEST_COLUMNS)
        w.writerows(rows)
    return manifest


if __name__ == '__main__':
    import sys
    print(make_samples(sys.argv[1] if len(sys.argv) > 1 else 'samples/footage'))
