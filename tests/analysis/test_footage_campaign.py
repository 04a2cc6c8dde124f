"""
saw-ros campaign --videos (issue 12).

The sample manifest's footage (made from our own simulation, one clip cluttered) tracked and
compared with the simulated conditions: relative errors under 2 %, figures and tables written;
manifest errors refused with the row.
"""
import csv
from pathlib import Path

import pytest

from saw_ros.analysis.footage import load_manifest, ManifestError, TARGET_COLUMNS
from saw_ros.cli.main import main

SAMPLES = Path(__file__).resolve().parents[2] / 'samples' / 'footage' / 'manifest.csv'


def test_sample_manifest_through_the_command(tmp_path, capsys):
    out = tmp_path / 'out'
    assert main(['campaign', '--videos', str(SAMPLES), '--out', str(out), '--quiet']) == 0
    text = capsys.readouterr().out
    assert '4 videos' in text
    for name in ('figure17_speed.png', 'figure18_ar.png', 'campaign.csv', 'campaign.md',
                 'footage.csv', 'footage.md'):
        assert (out / name).stat().st_size > 0, name
    with open(out / 'footage.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == TARGET_COLUMNS
    assert len(rows) == 4
    for row in rows:
        assert float(row['relative_error']) < 0.02, row
        assert int(row['frames_ok']) >= int(row['frames']) - 2, row
        frames = out / 'frames' / (Path(row['video']).stem + '.csv')
        with open(frames, newline='') as f:
            statuses = [r['status'] for r in csv.DictReader(f)]
        assert len(statuses) == int(row['frames']) and statuses.count('ok') == int(
            row['frames_ok'])
    assert {r['scale_from'] for r in rows} == {'px_per_m', 'marker_spacing'}


def test_manifest_errors_name_the_row(tmp_path):
    bad = tmp_path / 'm.csv'
    for name in ('a.mp4', 'b.mp4'):
        (tmp_path / name).write_bytes(b'')
    bad.write_text('video,slope_deg,voltage_V,frequency_hz,px_per_m,marker_spacing_m,notes\n'
                   'a.mp4,0,6,,600,,\n'
                   'b.mp4,0,,,600,,\n')
    with pytest.raises(ManifestError, match='row 3.*voltage_V'):
        load_manifest(bad)
    bad.write_text('video,slope_deg,voltage_V\na.mp4,0,6\n')
    with pytest.raises(ManifestError, match='scale'):
        load_manifest(bad)
    bad.write_text('video,slope,voltage_V\n')
    with pytest.raises(ManifestError, match='columns'):
        load_manifest(bad)


def test_missing_video_is_a_user_error(tmp_path, capsys):
    manifest = tmp_path / 'm.csv'
    manifest.write_text('video,slope_deg,voltage_V,px_per_m\nnothing.mp4,0,6,600\n')
    assert main(['campaign', '--videos', str(manifest), '--out', str(tmp_path / 'o')]) != 0
    assert 'nothing.mp4' in capsys.readouterr().err


def test_a_folder_of_frames_is_footage_as_its_video_is(tmp_path, capsys):
    """The same clip as frame images (manifest column fps) measures the same speed (issue 21)."""
    import cv2
    from saw_ros.vision.video import read_frames, video_info
    clip = SAMPLES.parent / 'level_6V.mp4'
    fps = video_info(clip)[0]
    folder = tmp_path / 'level_frames'
    folder.mkdir()
    for k, _, frame in read_frames(clip):
        cv2.imwrite(str(folder / f'frame_{k:04d}.png'), frame)
    header = 'video,slope_deg,voltage_V,px_per_m,fps\n'
    manifest = tmp_path / 'm.csv'
    manifest.write_text(header + f'{clip},0,6,600,\nlevel_frames,0,6,600,{fps}\n')
    out = tmp_path / 'out'
    assert main(['campaign', '--videos', str(manifest), '--out', str(out), '--quiet']) == 0
    with open(out / 'footage.csv', newline='') as f:
        video, frames = list(csv.DictReader(f))
    assert frames['frames'] == video['frames'] and frames['frames_ok'] == video['frames_ok']
    assert float(frames['v_measured']) == pytest.approx(float(video['v_measured']), rel=1e-3)
    # Without its frame rate a folder is refused, naming the row.
    manifest.write_text(header + 'level_frames,0,6,600,\n')
    with pytest.raises(ManifestError, match='row 2.*folder of frames.*fps'):
        load_manifest(manifest)


def test_a_calibrated_camera_in_the_manifest(tmp_path):
    """camera_calibration and plane columns: a clip filmed at yaw 18 deg measures its speed."""
    import cv2
    import numpy as np

    from saw_ros.analysis.footage import measure
    from saw_ros.vision import calibration
    from saw_ros.vision.footage import Shot
    from saw_ros.vision.tracker import TrackerConfig
    shot = Shot(duration=2.5, fps=30.0, width=640, height=360, scale=600.0, yaw_deg=18.0,
                pitch_deg=10.0, dist_coeffs=(-0.12, 0.0, 0.0, 0.0), quality=90)
    (tmp_path / 'run').mkdir()
    for k, _, frame in shot.frames():
        cv2.imwrite(str(tmp_path / 'run' / f'{k:03d}.png'), frame)
    lens = shot.lens()
    calibration.write_lens(tmp_path / 'camera.yaml', calibration.Lens(
        640, 360, lens.K, np.array([-0.12, 0.0, 0.0, 0.0, 0.0])), 'the generator')
    calibration.write_plane(tmp_path / 'plane.yaml', shot.plane(), 0.0, 'the generator')
    manifest = tmp_path / 'm.csv'
    manifest.write_text('video,slope_deg,frequency_hz,fps,camera_calibration,plane\n'
                        'run,0,1.5,30,camera.yaml,plane.yaml\n')
    run, = load_manifest(manifest)
    m = measure(run, 1.5, TrackerConfig())
    assert m.scale_from == 'plane'
    assert m.speed == pytest.approx(shot.mean_speed(), rel=0.01)
    manifest.write_text('video,slope_deg,frequency_hz,fps,px_per_m,plane\n'
                        'run,0,1.5,30,600,plane.yaml\n')
    with pytest.raises(ManifestError, match='px_per_m and plane both set the scale'):
        load_manifest(manifest)
    manifest.write_text('video,slope_deg,frequency_hz,fps,plane\nrun,0,1.5,30,none.yaml\n')
    with pytest.raises(ManifestError, match='plane: no such file'):
        load_manifest(manifest)


def test_a_perspective_with_one_scale_is_in_the_notes(tmp_path):
    """px_per_m for a camera yawed 18 deg: the condition's note says so (the tables show it)."""
    import cv2

    from saw_ros.analysis.footage import run_footage
    from saw_ros.vision.footage import Shot
    shot = Shot(duration=2.5, fps=30.0, width=640, height=360, scale=600.0, yaw_deg=18.0,
                pitch_deg=10.0, quality=90)
    (tmp_path / 'run').mkdir()
    for k, _, frame in shot.frames():
        cv2.imwrite(str(tmp_path / 'run' / f'{k:03d}.png'), frame)
    manifest = tmp_path / 'm.csv'
    manifest.write_text('video,slope_deg,frequency_hz,fps,px_per_m\nrun,0,1.5,30,580\n')
    result, = run_footage(load_manifest(manifest))
    assert 'perspective' in result.condition.note and 'calibrate the plane' in \
        result.condition.note
