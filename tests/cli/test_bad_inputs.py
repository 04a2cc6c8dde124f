"""
Bad input to every `saw-ros` subcommand: exit code 2, one line naming the input, no traceback.

The table is what a newcomer types wrong (issue 20); add every mistake a user finds. Each case
runs `saw-ros` as a user would, in a fresh folder (nothing lands in the repository), with a time
limit: a check that comes after the long work would show as a timeout.
"""
from pathlib import Path
import shlex
import shutil
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
VIDEO = str(ROOT / 'samples' / 'footage' / 'level_6V.mp4')
MANIFEST = str(ROOT / 'samples' / 'footage' / 'manifest.csv')
BAG = str(ROOT / 'bags' / 'reference_default')        # no camera frames in it
CAMERA_BAG = str(ROOT / 'bags' / 'reference_camera')
TIMEOUT_S = 90.0

# (subcommand and arguments, a piece of the one line it must print); {d} is the case's folder,
# which holds text.txt, text.mp4 (text with a video's name), bad.yaml (not YAML), list.yaml
# (YAML, not a mapping), a folder dir/ and manifests whose rows are wrong.
CASES = [
    ('', 'required: COMMAND'),
    ('nosuch', "invalid choice: 'nosuch'"),
    # statics
    ('statics --slope-deg 100', '--slope-deg = 100 is out of range: allowed [-90, 90] deg'),
    ('statics --slope-deg nan', '--slope-deg = nan'),
    ('statics --slope-deg abc', "--slope-deg: invalid float value: 'abc'"),
    ('statics --mass -1', '--mass = -1 is out of range: allowed (0, inf) kg'),
    ('statics --mu 0 --fext-mg 1', '--mu = 0 is out of range'),
    ('statics --mu 0.5', 'give both --fext-mg and --mu'),
    ('statics --mu 1 --fext-mg inf', '--fext-mg = inf'),
    ('statics --slopes 3', 'unrecognized arguments: --slopes 3'),
    # simulate
    ('simulate --duration -1', '--duration -1: must be a finite time > 0 s'),
    ('simulate --duration nan', '--duration nan'),
    ('simulate --duration inf', '--duration inf'),
    ('simulate --slope-deg 100', '--slope-deg = 100 is out of range: allowed [-90, 90] deg'),
    ('simulate --gap-mm 10', 'conditions.gap = 0.01 m is invalid'),
    ('simulate --kn -5', '--kn = -5 is out of range'),
    ('simulate --mu 9', '--mu = 9 is out of range: allowed [0, 5]'),
    ('simulate --frequency -1', '--frequency = -1 is out of range'),
    ('simulate --voltage 100', '--voltage = 100 is out of range: allowed [0, '),
    ('simulate --set foo=1', '--set foo: unknown parameter'),
    ('simulate --set surface.restitution', "--set 'surface.restitution': write NAME=VALUE"),
    ('simulate --set surface.restitution=abc', "'abc' is not a number"),
    ('simulate --set surface.restitution=2', '--set surface.restitution = 2 is out of range'),
    ('simulate --set robot.wave_links=2.5', 'must be an integer'),
    ('simulate --params-file {d}/none.yaml', '--params-file {d}/none.yaml: no such'),
    ('simulate --params-file {d}/bad.yaml', '--params-file {d}/bad.yaml: is not valid YAML'),
    ('simulate --params-file {d}/list.yaml', 'is not a parameter file'),
    ('simulate --params-file {d}/dir', 'is a folder'),
    ('simulate --params-file {d}/typo.yaml', 'not parameters of the simulator: surface.stifness'),
    ('simulate --params-file ' + str(ROOT / 'msg_config' / 'camera.yaml'),
     'not parameters of the simulator: '),
    ('simulate --set integration.dt=0', '--set integration.dt = 0 is out of range'),
    ('simulate --set walls.mass=-1e-9', '--set walls.mass = -1e-09 is out of range: allowed '
     '[0, 100] kg/m'),
    ('simulate --set walls.mass=100.001', '--set walls.mass = 100.001 is out of range'),
    ('simulate --set walls.damping=-1', '--set walls.damping = -1 is out of range'),
    ('simulate --set walls.damping=1.1e6', '--set walls.damping = 1.1e+06 is out of range: '
     'allowed [0, 1e+06] N s/m^2'),
    ('statics --mass 1e400', '--mass = inf is invalid'),
    ('calibrate --quick --params motor.hz_per_volt:a:b', 'bounds must be numbers'),
    ('track ' + VIDEO + ' --px-per-m 600 --roi 0,0,0,0', 'tracker roi'),
    ('simulate --csv ""', 'must end in .csv'),
    ('simulate --params-file ' + VIDEO, 'is not a text parameter file'),
    ('simulate --csv {d}/text.txt/run.csv', 'cannot be written: {d}/text.txt is a file'),
    ('simulate --csv {d}/run.txt', '--csv {d}/run.txt: must end in .csv'),
    ('simulate --csv {d}/dir.csv', '--csv {d}/dir.csv: is a folder'),
    ('simulate --plot {d}/run.jpg', '--plot {d}/run.jpg: must end in .png'),
    # render
    ('render {d}/out.txt', 'OUTPUT {d}/out.txt: must end in .mp4 or .avi'),
    ('render {d}/text.txt/out.mp4', 'cannot be written'),
    ('render {d}/out.mp4 --duration -1', '--duration = -1 is out of range: allowed (0, inf) s'),
    ('render {d}/out.mp4 --fps 0', '--fps = 0 is out of range'),
    ('render {d}/out.mp4 --px-per-m -1', '--px-per-m = -1 is out of range'),
    ('render {d}/out.mp4 --width 8', '--width = 8 is out of range: allowed [16, inf) px'),
    ('render {d}/out.mp4 --gap 0.01', 'conditions.gap = 0.01 m is invalid'),
    ('render {d}/out.mp4 --slope-deg 91', '--slope-deg = 91 is out of range'),
    ('render {d}/out.mp4 --noise -1', '--noise = -1 is out of range'),
    ('render', 'required: output'),
    ('render {d}/out.mp4 --flexure-stiffness 0.5', 'flexure.stiffness = 0.5 N/m is invalid'),
    ('render {d}/out.mp4 --flexure-stiffness 1.1e9',
     '--flexure-stiffness = 1.1e+09 is out of range: allowed [0, 1e+09] N/m'),
    ('render {d}/out.mp4 --flexure-damping 1001', '--flexure-damping = 1001 is out of range'),
    # track
    ('track {d}/none.mp4 --px-per-m 600', 'VIDEO {d}/none.mp4: no such video file'),
    ('track {d}/text.mp4 --px-per-m 600', 'VIDEO {d}/text.mp4: not a video OpenCV can decode'),
    ('track {d}/text.txt --px-per-m 600', 'not a video OpenCV can decode'),
    ('track {d}/dir --px-per-m 600', 'VIDEO {d}/dir: is a folder'),
    ('track ' + VIDEO, 'give the scale'),
    ('track ' + VIDEO + ' --px-per-m -5', '--px-per-m = -5 is out of range'),
    ('track ' + VIDEO + ' --px-per-m 600 --csv {d}/track.txt', 'must end in .csv'),
    ('track ' + VIDEO + ' --px-per-m 600 --csv {d}/text.txt/t.csv', 'cannot be written'),
    ('track ' + VIDEO + ' --px-per-m 600 --plot {d}/p.pdf', 'must end in .png'),
    ('track ' + VIDEO + ' --px-per-m 600 --fps -1', '--fps = -1 is out of range'),
    ('track ' + VIDEO + ' --px-per-m 600 --slope-deg 100', '--slope-deg = 100'),
    ('track ' + VIDEO + ' --px-per-m 600 --center-x nan', '--center-x = nan'),
    ('track ' + VIDEO + ' --px-per-m 600 --roi 1,2', 'argument --roi'),
    ('track ' + VIDEO + ' --marker-spacing-m -1', 'marker_spacing'),
    ('track ' + VIDEO + ' --px-per-m 600 --dist-coeffs 0,0,0,0', 'go together'),
    ('track ' + BAG + ' --px-per-m 600', 'holds no frames'),
    ('track {d}/none.mcap --px-per-m 600', 'none.mcap'),
    ('track ' + VIDEO + ' --px-per-m 600 --camera-calibration {d}/list.yaml',
     'camera calibration {d}/list.yaml: not a YAML mapping'),
    ('track ' + VIDEO + ' --plane {d}/bad.yaml', 'plane {d}/bad.yaml: not YAML'),
    ('track ' + VIDEO + ' --plane-points 1,2,3,4', 'the plane needs 4 or more points'),
    ('track ' + VIDEO + ' --px-per-m 600 --plane-points 1,2,3,4', 'both set the scale'),
    ('track ' + VIDEO + ' --plane-points 1,2,3,4 --plane {d}/bad.yaml', 'give the plane once'),
    ('calibrate-camera {d}/none.mp4 --board chessboard:9x6:0.025',
     'VIDEO {d}/none.mp4: no such video file'),
    ('calibrate-camera ' + VIDEO + ' --board chessboard:9x6', 'give chessboard:COLSxROWS'),
    ('calibrate-camera ' + VIDEO + ' --board charuco:7x5:0.04:0.05',
     'must be smaller than the square'),
    ('calibrate-camera ' + VIDEO + ' --board chessboard:9x6:0.025 -o {d}/c.yaml',
     'too few views of the board: 0 views with the board of 60 frames'),
    ('calibrate-camera ' + VIDEO + ' --board chessboard:9x6:0.025 -o {d}/c.txt',
     '--output {d}/c.txt: must end in .yaml'),
    ('calibrate-camera --board chessboard:9x6:0.025', 'give VIDEO'),
    ('calibrate-camera --board chessboard:9x6:0.025 --lens {d}/bad.yaml --plane-image '
     '{d}/text.txt', 'camera calibration {d}/bad.yaml: not YAML'),
    ('calibrate-camera --board chessboard:9x6:0.025 --plane-image {d}/text.txt',
     'not a picture OpenCV can read'),
    ('calibrate-camera ' + VIDEO + ' --board chessboard:9x6:0.025 --plane-image {d}/none.png',
     '--plane-image {d}/none.png: no such picture'),
    # campaign
    ('campaign --reference {d}/none.csv', '--reference {d}/none.csv: no such reference file'),
    ('campaign --reference {d}/text.txt', 'needs columns slope_deg, voltage_V'),
    ('campaign --reference ' + VIDEO, 'is not a text reference file'),
    ('campaign --slopes abc', "--slopes 'abc': expects comma-separated numbers"),
    ('campaign --slopes=100', '--slopes = 100 is out of range: allowed [-90, 90] deg'),
    ('campaign --voltages=-1', '--voltages = -1 is out of range: allowed [0, '),
    ('campaign --voltages ,', '--voltages is empty'),
    ('campaign --out {d}/text.txt', '--out {d}/text.txt: is a file, not a folder'),
    ('campaign --workers 0', '--workers must be at least 1'),
    ('campaign --scheduler-timeout -1', '--scheduler-timeout -1'),
    ('campaign --gap-mm 5', 'conditions.gap = 0.005 m is invalid'),
    ('campaign --videos {d}/none.csv', '--videos {d}/none.csv: no such manifest'),
    ('campaign --videos {d}/text.txt', 'columns must be video, slope_deg'),
    ('campaign --videos ' + VIDEO, 'is not a text manifest'),
    ('campaign --videos {d}/frames_no_fps.csv', 'dir is a folder of frames: give its fps'),
    ('campaign --videos {d}/text_video.csv', 'video {d}/text.mp4: not a video OpenCV can decode'),
    ('campaign --videos {d}/no_video.csv', 'no such video file'),
    ('campaign --videos {d}/volts.csv', 'motor.voltage = 99 is out of range'),
    ('campaign --videos {d}/no_scale.csv', 'give the scale'),
    ('campaign --videos ' + MANIFEST + ' --out {d}/text.txt', 'is a file, not a folder'),
    # figures
    ('figures --only 5', 'unknown figure(s) 5'),
    ('figures --out {d}/text.txt', '--out {d}/text.txt: is a file, not a folder'),
    ('figures --calibrated {d}/none.yaml', '--calibrated {d}/none.yaml: no such'),
    ('figures --calibrated {d}/bad.yaml', 'is not valid YAML'),
    ('figures --workers 0', '--workers must be at least 1'),
    # calibrate
    ('calibrate --quick --targets {d}/none.csv', '--targets {d}/none.csv: no such'),
    ('calibrate --quick --targets {d}/text.txt', 'needs columns slope_deg'),
    ('calibrate --quick --targets ' + VIDEO, 'is not a text targets file'),
    ('calibrate --quick --params surface.stiffness', "unknown parameter 'surface.stiffness'"),
    ('calibrate --quick --params motor.resistance:5:1', 'must be finite, low < high'),
    ('calibrate --quick --generations 0', '--generations must be at least 1'),
    ('calibrate --quick --popsize 1', '--popsize must be at least 2'),
    ('calibrate --quick --seed -1', '--seed = -1 is out of range'),
    ('calibrate --quick --out {d}/text.txt', 'is a file, not a folder'),
    ('calibrate --quick --write-config {d}/c.txt', 'must end in .yaml or .yml'),
    ('calibrate --quick --write-config {d}/text.txt/c.yaml', 'cannot be written'),
    ('calibrate --quick --write-worse', '--write-worse applies to --write-config'),
    ('calibrate --resume {d}/dir', 'nothing to resume'),
    ('calibrate --resume {d}/text.txt', 'is a file, not a folder'),
    ('calibrate --resume {d}/dir --targets x.csv', 'do not give'),
    # demo: refused before any node starts
    ('demo --duration -1', '--duration = -1 is out of range'),
    ('demo --real-time-factor -1', '--real-time-factor = -1 is out of range'),
    ('demo --out {d}/text.txt', 'is a file, not a folder'),
    ('demo --slope-deg 100', '--slope-deg = 100'),
    ('demo --params-file {d}/bad.yaml', 'is not valid YAML'),
    # shape-drive
    ('shape-drive --voltage 0', '--voltage must be above 0 V'),
    ('shape-drive --generations 0', '--generations 0: must be at least 1'),
    ('shape-drive --out {d}/text.txt', '--out {d}/text.txt: is a file, not a folder'),
    ('shape-drive --slope-deg 100', '--slope-deg = 100'),
    ('shape-drive --flexure-stiffness -1', '--flexure-stiffness = -1 is out of range: allowed'),
    ('shape-drive --flexure-stiffness 2e9', '--flexure-stiffness = 2e+09 is out of range'),
    ('shape-drive --flexure-stiffness 0.5', 'flexure.stiffness = 0.5 N/m is invalid'),
    ('shape-drive --flexure-damping-ratio 0.7', '--flexure-damping-ratio: the links are rigid'),
    ('shape-drive --flexure-stiffness 1463 --flexure-damping-ratio -0.1',
     '--flexure-damping-ratio = -0.1 is out of range'),
    ('shape-drive --flexure-stiffness 1463 --flexure-damping-ratio nan',
     '--flexure-damping-ratio = nan is invalid'),
    ('shape-drive --flexure-stiffness 1e9 --flexure-damping-ratio 1',
     'flexure.damping = 4000 is out of range: allowed [0, 1000] N s/m'),
    # compliant
    ('compliant --out {d}/text.txt', '--out {d}/text.txt: is a file, not a folder'),
    ('compliant --slope-deg 100', '--slope-deg = 100'),
    ('compliant --set surface.foundation_stiffness=1e5', 'bending walls'),
    ('compliant --slopes=91', '--slopes = 91 is out of range: allowed [-90, 90] deg'),
    ('compliant --slopes=-90.5', '--slopes = -90.5 is out of range'),
    ('compliant --slopes ,', '--slopes is empty'),
    ('compliant --slopes 0,nan', '--slopes = nan'),
    # design
    ('design --size 0', '--size 0: a hypercube needs at least 1 geometry'),
    ('design --method grid --size 1', '--size 1: a grid needs at least 2 levels'),
    ('design --method grid --size 30', 'more than the 20000 runs'),
    ('design --method tree', "invalid choice: 'tree'"),
    ('design --walls glass,rigid', "--walls 'glass,rigid': unknown glass"),
    ('design --walls ,', '--walls is empty'),
    ('design --range robot.mass=0.1:0.2', '--range robot.mass is not swept'),
    ('design --range robot.amplitude=0.02:0.01', 'must be below the high end'),
    ('design --range robot.amplitude=0.02', 'expects NAME=LOW:HIGH'),
    ('design --range robot.amplitude=a:b', 'LOW and HIGH must be numbers'),
    ('design --range robot.wave_links=0:30', '--range robot.wave_links = 0 is out of range'),
    ('design --range flexure.stiffness=0:1e4', 'log scale'),
    ('design --measure-s 0', '--measure-s 0: the window must hold at least 1 s'),
    ('design --measure-s 0.5', '--measure-s 0.5: the window must hold at least 1 s'),
    ('design --seed -1', '--seed -1: must be 0 or more'),
    ('design --range robot.amplitude=nan:0.01', 'LOW and HIGH must be finite numbers'),
    ('design --settle-s nan', '--settle-s nan: must be a time in [0, 60] s'),
    ('design --voltage 0', 'needs the motor'),
    ('design --set flexure.stiffness=1000', 'sets the walls and the flexures itself'),
    ('design --out {d}/text.txt', '--out {d}/text.txt: is a file, not a folder'),
    ('design --workers 0', '--workers must be at least 1'),
    # bench
    ('bench --only nosuch', "unknown benchmark(s) ['nosuch']"),
    ('bench --only core --logs {d}/text.txt', '--logs {d}/text.txt: is a file, not a folder'),
    # bag
    ('bag', 'required: ACTION'),
    ('bag info {d}/none', 'none'),
    ('bag info {d}/text.txt', 'is not an MCAP file'),
    ('bag play {d}/none', 'no bag at {d}/none'),
    ('bag play {d}/text.txt', 'is not an MCAP file'),
    ('bag play ' + BAG + ' -r 0', '--rate = 0 is out of range'),
    ('bag play ' + BAG + ' -r nan', '--rate = nan'),
    ('bag video {d}/none', 'none'),
    ('bag video {d}/text.txt', 'is not an MCAP file'),
    ('bag video ' + BAG, 'holds no frames'),
    ('bag video ' + CAMERA_BAG + ' --topic /clock', '/clock is not an image topic'),
    ('bag video ' + CAMERA_BAG + ' --topic /nosuch', 'holds no frames on /nosuch'),
    ('bag video ' + CAMERA_BAG + ' -o {d}/camera.txt', 'must end in .mp4 or .avi'),
    ('bag video ' + CAMERA_BAG + ' -o {d}/text.txt/c.mp4', 'cannot be written'),
    ('bag record -o {d}/text.txt', 'exists already'),
    ('bag record -o {d}/text.txt/bag', 'cannot be written'),
    ('bag record "bad topic"', "topic 'bad topic': not a valid ROS topic name"),
    ('bag reindex {d}/none', 'is not a bag directory'),
    ('bag reindex {d}/text.txt', 'is not a bag directory'),
    ('bag reindex {d}/dir', 'holds no .mcap file'),
    ('bag info {d}/dir', 'holds no .mcap file'),
    ('bag frobnicate', "invalid choice: 'frobnicate'"),
    # sros2-policy
    ('sros2-policy --out {d}/text.txt/policy.xml', '--out {d}/text.txt/policy.xml: cannot write'),
    ('sros2-policy --out {d}/dir', '--out {d}/dir: cannot write'),
    ('sros2-policy --enclave x', 'unrecognized arguments: --enclave x'),
]


def _saw_ros():
    """Return the installed command next to this interpreter, else the module it runs."""
    exe = Path(sys.executable).parent / 'saw-ros'
    return [str(exe)] if exe.exists() else [sys.executable, '-m', 'saw_ros.cli.main']


def make_folder(path: Path) -> Path:
    """Fill ``path`` with the inputs the table's cases name ({d})."""
    path.mkdir(parents=True, exist_ok=True)
    (path / 'text.txt').write_text('hello\n')
    (path / 'text.mp4').write_text('not a video\n')
    (path / 'bad.yaml').write_text('simulator: [1,\n')
    (path / 'list.yaml').write_text('- 1\n- 2\n')
    (path / 'typo.yaml').write_text('simulator:\n  ros__parameters:\n    '
                                    'surface.stifness: 3\n')
    (path / 'dir').mkdir()
    (path / 'dir.csv').mkdir()
    header = 'video,slope_deg,voltage_V,px_per_m\n'
    (path / 'text_video.csv').write_text(header + 'text.mp4,0,6,600\n')
    (path / 'no_video.csv').write_text(header + 'none.mp4,0,6,600\n')
    shutil.copy(VIDEO, path / 'level.mp4')
    (path / 'volts.csv').write_text(header + 'level.mp4,0,99,600\n')
    (path / 'no_scale.csv').write_text(header + 'level.mp4,0,6,\n')
    (path / 'frames_no_fps.csv').write_text(header + 'dir,0,6,600\n')
    return path


MADE = {'text.txt', 'text.mp4', 'bad.yaml', 'list.yaml', 'typo.yaml', 'dir', 'dir.csv',
        'text_video.csv', 'no_video.csv', 'level.mp4', 'volts.csv', 'no_scale.csv',
        'frames_no_fps.csv'}

# One Python runs the whole table (a process start per case cost 140 s of the suite): each case
# in a folder of its own, saw-ros's main() with the case's arguments, what it printed on
# stderr and its exit code; an exception that escaped main() comes back as its traceback.
WORKER = """
import contextlib, io, json, os, sys, traceback
from saw_ros.cli.main import main
out = []
for folder, args in json.load(sys.stdin):
    os.chdir(folder)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(args)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        except BaseException:
            code = 'exception'
            err.write(traceback.format_exc())
    out.append({'code': code, 'err': err.getvalue(), 'files': sorted(os.listdir(folder))})
print(json.dumps(out))
"""


@pytest.fixture(scope='module')
def outcomes(tmp_path_factory):
    """Run every case of the table in one Python; {command: (folder, outcome)}."""
    import json
    root = tmp_path_factory.mktemp('bad_inputs')
    jobs, folders = [], []
    for i, (command, _) in enumerate(CASES):
        folder = make_folder(root / f'case_{i}')
        folders.append(folder)
        jobs.append([str(folder), [a.replace('{d}', str(folder)) for a in shlex.split(command)]])
    done = subprocess.run([sys.executable, '-c', WORKER], input=json.dumps(jobs),
                          capture_output=True, text=True, timeout=TIMEOUT_S * 3, cwd=root)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads(done.stdout.strip().splitlines()[-1])
    return {command: (folder, result)
            for (command, _), folder, result in zip(CASES, folders, results)}


@pytest.mark.parametrize('command, expected', CASES, ids=[c or '(none)' for c, _ in CASES])
def test_bad_input_is_one_line_and_exit_code_2(outcomes, command, expected):
    folder, result = outcomes[command]
    err = result['err']
    assert 'Traceback' not in err, err
    assert len(err.strip().splitlines()) == 1, err
    assert expected.replace('{d}', str(folder)) in err, err
    assert result['code'] == 2, (result['code'], err)
    assert err.startswith('saw-ros'), err
    # Refused before anything was written: the folder holds only what the fixture made.
    assert set(result['files']) == MADE


# A few of them as a user types them, each its own `saw-ros` process.
@pytest.mark.parametrize('command, expected', [
    c for c in CASES if c[0] in ('', 'statics --slope-deg 100', 'bag info {d}/text.txt',
                                 'campaign --videos {d}/text_video.csv')])
def test_bad_input_from_the_command_line(tmp_path, command, expected):
    folder = make_folder(tmp_path / 'case')
    args = [a.replace('{d}', str(folder)) for a in shlex.split(command)]
    done = subprocess.run(_saw_ros() + args, cwd=folder, capture_output=True, text=True,
                          timeout=TIMEOUT_S, stdin=subprocess.DEVNULL)
    err = done.stderr
    assert 'Traceback' not in err and len(err.strip().splitlines()) == 1, err
    assert expected.replace('{d}', str(folder)) in err and done.returncode == 2, err
    assert {p.name for p in folder.iterdir()} == MADE


def test_every_subcommand_has_bad_inputs_in_the_table():
    """A new subcommand comes with its rows: the table is the error path's specification."""
    from saw_ros.cli.main import build_parser
    parser = build_parser()
    names = parser._subparsers._group_actions[0].choices
    tried = {c.split()[0] for c, _ in CASES if c}
    assert not set(names) - tried, f'no bad input tried for: {sorted(set(names) - tried)}'
