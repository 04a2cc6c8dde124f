"""A number that cannot be computed is said in words with the reason, never printed as nan."""
from pathlib import Path
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[2]
VIDEO = ROOT / 'samples' / 'footage' / 'level_6V.mp4'


def _saw_ros(args, cwd):
    exe = Path(sys.executable).parent / 'saw-ros'
    argv = [str(exe)] if exe.exists() else [sys.executable, '-m', 'saw_ros.cli.main']
    return subprocess.run(argv + args, cwd=cwd, capture_output=True, text=True, timeout=300,
                          stdin=subprocess.DEVNULL)


def test_footage_campaign_row_that_never_settles_says_why_and_what_to_do(tmp_path):
    """At 3 Hz the simulated robot does not settle within the campaign's 4 s (issue 20)."""
    shutil.copy(VIDEO, tmp_path / 'clip.mp4')
    (tmp_path / 'manifest.csv').write_text('video,slope_deg,voltage_V,frequency_hz,px_per_m\n'
                                           'clip.mp4,0,,3,600\nclip.mp4,0,6,,600\n')
    done = _saw_ros(['campaign', '--videos', 'manifest.csv', '--out', 'out'], tmp_path)
    assert 'nan' not in done.stdout.lower() and 'nan' not in done.stderr.lower(), done.stdout
    assert 'Traceback' not in done.stderr
    assert 'simulated no steady speed: no error' in done.stdout
    assert 'why: the simulated speed did not settle' in done.stdout
    assert 'within the 4 s simulated at 3.00 Hz' in done.stdout
    assert 'saw-ros simulate --slope-deg 0 --frequency 3 --duration 16' in done.stdout
    assert 'overall: ' in done.stdout and '(over 1 of 2 rows)' in done.stdout
    assert done.returncode == 1 and '1 of 2 rows could not be compared' in done.stderr
    for name in ('footage.md', 'campaign.md'):
        text = (tmp_path / 'out' / name).read_text()
        assert 'nan' not in text.lower() and '1 of 2 rows have no comparison' in text, name


def test_simulate_without_a_turning_helix_or_a_steady_state_says_so(tmp_path):
    still = _saw_ros(['simulate', '--quiet', '--frequency', '0', '--duration', '0.5'], tmp_path)
    assert still.returncode == 0 and 'nan' not in still.stdout
    assert 'AR                  not defined: the helix does not turn (0 Hz)' in still.stdout
    short = _saw_ros(['simulate', '--quiet', '--duration', '0.4'], tmp_path)
    assert short.returncode == 0 and 'nan' not in short.stdout
    assert 'steady state not reached within 0.4 s: run longer (--duration 0.8)' in short.stdout


def test_simulate_and_track_write_their_plots(tmp_path):
    done = _saw_ros(['simulate', '--quiet', '--duration', '1', '--plot', 'sim.png'], tmp_path)
    assert done.returncode == 0 and (tmp_path / 'sim.png').stat().st_size > 10000
    done = _saw_ros(['track', str(VIDEO), '--px-per-m', '600', '--plot', 'p/track.png'],
                    tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / 'p' / 'track.png').stat().st_size > 10000
    assert 'plot: p/track.png' in done.stdout
    # Not a terminal: no progress bar lines in what a log or a pipe receives.
    assert '%|' not in done.stderr and '\r' not in done.stderr


def test_footage_without_markers_says_there_is_no_measured_speed(tmp_path):
    import numpy as np

    from saw_ros.vision.video import VideoWriter
    with VideoWriter(tmp_path / 'black.mp4', 30.0, (320, 180)) as w:
        for _ in range(30):
            w.write(np.zeros((180, 320, 3), np.uint8))
    (tmp_path / 'manifest.csv').write_text('video,slope_deg,voltage_V,px_per_m\n'
                                           'black.mp4,0,6,600\n')
    done = _saw_ros(['campaign', '--videos', 'manifest.csv', '--out', 'out'], tmp_path)
    assert 'nan' not in done.stdout.lower() and 'Traceback' not in done.stderr
    assert 'measured no speed (0/30 frames ok)' in done.stdout
    assert 'why: too few frames with both markers (0 of 30)' in done.stdout
    assert 'saw-ros track black.mp4 --px-per-m 600 --plot track.png' in done.stdout
    assert 'overall: not computed: no row here has both speeds' in done.stdout
    assert done.returncode == 1
