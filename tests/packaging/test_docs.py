"""
The docs stay true (issue 20).

Nothing in the repository points outside it, every relative link in the docs resolves, the
command table lists every subcommand, the cheap commands the README shows run, and the numbers
it quotes are the generated ones, which a fresh run of the model reproduces.
"""
import math
from pathlib import Path
import re
import subprocess
import sys

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / 'README.md'
# Written in pieces so that this file does not match itself.
OUTSIDE = ('..' + '/shared', 'shared' + '/docs', '/' + 'work/', 'shared' + '/seed')
LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)\)')


def tracked_files():
    try:
        out = subprocess.run(['git', 'ls-files', '-z'], cwd=ROOT, capture_output=True,
                             timeout=30)
    except FileNotFoundError:
        pytest.skip('git is not installed: the tracked files cannot be listed')
    if out.returncode != 0:
        pytest.skip('not a git checkout (an installed copy): no tracked files to check')
    return [ROOT / name for name in out.stdout.decode().split('\0') if name]


def markdown_files():
    return [README, ROOT / 'bags' / 'README.md', ROOT / 'samples' / 'footage' / 'README.md',
            *sorted((ROOT / 'docs').rglob('*.md'))]


def test_no_file_refers_to_paths_outside_the_repository():
    found = []
    for path in tracked_files():
        if not path.is_file():
            continue        # deleted in the working tree, not yet committed
        data = path.read_bytes()
        if b'\0' in data[:8192]:
            continue        # binary: images, bags, videos
        for number, line in enumerate(data.decode('utf-8', 'replace').splitlines(), 1):
            for needle in OUTSIDE:
                if needle in line:
                    found.append(f'{path.relative_to(ROOT)}:{number}: {needle}')
    assert not found, 'paths outside the repository:\n' + '\n'.join(found)


@pytest.mark.parametrize('doc', markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(doc):
    broken = []
    for target in LINK.findall(doc.read_text()):
        if '://' in target or target.startswith(('mailto:', '#')):
            continue
        path = (doc.parent / target.split('#')[0]).resolve()
        if not path.exists() or ROOT not in path.parents and path != ROOT:
            broken.append(target)
    assert not broken, f'{doc.relative_to(ROOT)}: links that do not resolve: {broken}'


def subcommands():
    from saw_ros.cli.main import build_parser
    parser = build_parser()
    action = next(a for a in parser._actions if a.dest == 'command')
    return sorted(action.choices)


def readme_section(title: str) -> str:
    text = README.read_text()
    start = text.index(f'\n## {title}')
    end = text.find('\n## ', start + 1)
    return text[start:end if end > 0 else None]


def test_the_command_table_lists_every_subcommand():
    table = readme_section('The offline command `saw-ros`')
    listed = set(re.findall(r'^\| `saw-ros ([a-z0-9-]+)', table, re.M))
    assert listed == set(subcommands())


def readme_commands():
    """Return the lines of the README's shell blocks that start with saw-ros (comments cut)."""
    commands = []
    for block in re.findall(r'```bash\n(.*?)```', README.read_text(), re.S):
        for line in block.splitlines():
            line = line.split('  #')[0].strip()
            if line.startswith('saw-ros '):
                commands.append(line.split()[1:])
    return commands


# What the README shows that is cheap enough for the tests (seconds each): the rest (demo, the
# 20-condition campaign, figures, bench, calibrate) is run by its own tests and scripts/main.sh.
def cheap(args):
    return args[0] in ('statics', 'simulate', 'track') or '--help' in args or '--videos' in args


def test_the_readme_shows_the_first_ten_minutes():
    shown = {c[0] for c in readme_commands() if cheap(c)}
    assert {'statics', 'simulate', 'track', 'campaign'} <= shown


@pytest.mark.parametrize('args', [c for c in readme_commands() if cheap(c)] + [['--help']],
                         ids=' '.join)
def test_readme_command_runs(args, tmp_path):
    # Run from a scratch folder, as the commands write under ./out by default; the README's
    # paths (samples/...) are relative to the repository.
    args = [str(ROOT / a) if (ROOT / a).exists() and '/' in a else a for a in args]
    r = subprocess.run([sys.executable, '-m', 'saw_ros.cli.main', *args], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert 'Traceback' not in r.stderr and r.stdout.strip()


def test_every_subcommand_answers_help(tmp_path, monkeypatch, capsys):
    """``saw-ros NAME --help`` for every subcommand, in this process (argparse's own exit)."""
    from saw_ros.cli.main import main
    monkeypatch.chdir(tmp_path)
    for name in subcommands():
        with pytest.raises(SystemExit) as done:
            main([name, '--help'])
        out, err = capsys.readouterr()
        assert done.value.code == 0, (name, err)
        assert out.startswith('usage: saw-ros ') and f' {name}' in out.splitlines()[0], \
            (name, out[:200])
    assert list(tmp_path.iterdir()) == [], 'a --help wrote a file'


# -- the numbers the README and docs quote -----------------------------------------------------
def fidelity_row(claim: str) -> list:
    for line in (ROOT / 'docs' / 'fidelity.md').read_text().splitlines():
        if line.startswith(f'| {claim} |'):
            return [cell.strip() for cell in line.strip('|').split('|')]
    raise AssertionError(f'claim {claim} is not in docs/fidelity.md')


def ours(claim: str) -> str:
    """Return the first number of the 'ours' column of a claim in docs/fidelity.md."""
    return re.search(r'-?\d+\.\d+', fidelity_row(claim)[4]).group()


def campaign_reference_error() -> str:
    text = (ROOT / 'docs' / 'campaign' / 'campaign.md').read_text()
    return re.search(r'speeds the paper states: mean relative error (\d+\.\d) %', text).group(1)


def test_the_readme_quotes_the_generated_numbers():
    text = ' '.join(README.read_text().split())
    quoted = [
        f'AR {ours("A1")} on the level and {ours("A2")} climbing vertically',
        f'under 2 % after {ours("C2")} s and under 0.2 % after {ours("C3")} s',
        f'({ours("S1")} deg, {ours("S2")} m g, {ours("S5")} deg)',
        f'{campaign_reference_error()} % from the three speeds the paper measured',
        f'{v_theory_cm_s()} cm/s at 1 Hz',
        f'the soft surfaces give way, {ours("A1")} here',
        f'Tracking against simulation differs by about {campaign_tracking_error()} %',
    ]
    missing = [q for q in quoted if q not in text]
    assert not missing, f'README.md does not say (or says other numbers than): {missing}'


def v_theory_cm_s() -> str:
    from saw_ros.core import Scenario, v_theory
    return f'{100 * v_theory(Scenario().robot, 1.0):.2f}'


def campaign_tracking_error() -> str:
    text = (ROOT / 'docs' / 'campaign' / 'campaign.md').read_text()
    return f'{float(re.search(r"^[|] all [|] ([0-9.]+) [|]", text, re.M).group(1)):.2f}'


def test_the_main_jobs_real_time_factor_and_the_viewers_distance_are_current():
    from saw_ros.cli.main import build_parser
    parser = build_parser()
    demo = next(a for a in parser._actions if a.dest == 'command').choices['demo']
    rtf = demo.get_default('real_time_factor')
    text = ' '.join(README.read_text().split())
    assert f'at real-time factor {rtf:g}: about' in text
    assert f"main job's real-time factor {rtf:g}" in text
    duration = demo.get_default('duration')
    speed = float(ours('A1')) * float(v_theory_cm_s())
    viewers = ' '.join((ROOT / 'docs' / 'viewers.md').read_text().split())
    assert (f'at {speed:.1f} cm/s (AR {ours("A1")} of v_theory {v_theory_cm_s()} cm/s at 1 Hz) '
            f"the robot crosses about {round(speed * duration, -1):.0f} cm in the main job's "
            f'{duration:g} s') in viewers


def test_the_statics_quoted_are_the_closed_forms():
    from saw_ros.core import statics
    assert f'{math.degrees(statics.top_surface_needed_above(0.0, 0.4)):.2f}' == ours('S1')
    assert f'{math.degrees(statics.top_surface_needed_above(0.5, 0.8)):.2f}' == ours('S5')
    total = statics.minimal_normal_forces(math.pi / 2, 0.0, 0.4)[2]
    assert f'{float(total):.3f}' == ours('S2')


def test_the_quoted_advance_ratios_and_convergence_times_match_a_fresh_run():
    from saw_ros.analysis.figures import sweeps
    ar = sweeps.run_wave_batch([sweeps.point(0.0), sweeps.point(90.0)], sweeps.FULL)
    assert f'{ar[sweeps.point(0.0)]:.3f}' == ours('A1')
    assert f'{ar[sweeps.point(90.0)]:.3f}' == ours('A2')
    m = sweeps.run_timeseries()['metrics']
    assert f'{m.cci_2pct_after:.2f}' == ours('C2')
    assert f'{m.cci_02pct_after:.2f}' == ours('C3')


def test_the_quoted_error_against_the_measured_speeds_matches_a_fresh_run():
    # The campaign's simulation half at the paper's three stated points, compared as the
    # campaign does (tracking replaced by the truth at the camera's frame times).
    from saw_ros.analysis import campaign
    from saw_ros.analysis.compare import find_reference, load_reference, reference_error
    from saw_ros.analysis.compare import RunComparator
    from saw_ros.core import Scenario, simulate
    from saw_ros.core.metrics import run_turns
    points = load_reference(ROOT / 'msg_config' / 'reference_paper.csv')
    assert len(points) == 3
    everything = [Scenario().with_values({'conditions.slope': math.radians(s),
                                          'motor.voltage': v})
                  for v in campaign.PAPER_VOLTAGES for s in campaign.PAPER_SLOPES_DEG]
    duration = max(campaign.duration_for(s.frequency) for s in everything)
    scenarios = [Scenario().with_values({'conditions.slope': math.radians(p.slope_deg),
                                         'motor.voltage': p.voltage}) for p in points]
    trajectory = simulate(scenarios, duration)
    errors = []
    for i, s in enumerate(scenarios):
        comp = RunComparator(s.robot, s.frequency)
        x = trajectory.q[:, i, 0]
        for row in zip(trajectory.t, x):
            comp.add_truth(*row)
        for row in zip(trajectory.t, run_turns(trajectory, i)):
            comp.add_helix(*row)
        frames = np.arange(1, int(math.floor(trajectory.t[-1] * 60 + 1e-9)) + 1) / 60
        for row in zip(frames, np.interp(frames, trajectory.t, x)):
            comp.add_tracked(*row)
        r = comp.result()
        point = find_reference(points, math.degrees(s.conditions.slope), s.motor.voltage)
        errors.append(reference_error(point, r.v_sim, r.v_theory))
    assert f'{100 * np.mean(errors):.1f}' == campaign_reference_error()


def test_the_model_page_lists_every_parameter_with_its_default():
    from saw_ros.core import Scenario
    rows = re.findall(r'^\| `([a-z_]+\.[a-z_]+)` \| ([^|]+) \|',
                      (ROOT / 'docs' / 'model.md').read_text(), re.M)
    table = {name: value.strip() for name, value in rows}
    defaults = Scenario().flat()
    assert set(table) == set(defaults)
    wrong = {n: (table[n], v) for n, v in defaults.items() if float(table[n]) != float(v)}
    assert not wrong, f'docs/model.md defaults differ from saw_ros/core/params.py: {wrong}'


PATH_IN_TEXT = re.compile(r'`((?:saw_ros|tests|docs|msg_config|scripts|samples|bags)/[^`\s]*)`')


@pytest.mark.parametrize('doc', markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_repository_path_named_in_the_docs_exists(doc):
    # A file the docs name in code style (`saw_ros/ros/qos.py`) must still be there: the docs
    # once sent readers to a common.py that no longer existed.
    missing = [p for p in PATH_IN_TEXT.findall(doc.read_text())
               if not any(c in p for c in '<>*{') and not (ROOT / p).exists()]
    assert not missing, f'{doc.relative_to(ROOT)} names files that do not exist: {missing}'


def test_the_benchmark_table_lists_every_bench_key():
    from saw_ros.cli.commands.bench import modules
    table = readme_section('Benchmarks')
    listed = set(re.findall(r'`([a-z0-9_]+)`', table))
    missing = [k for _, module in modules() for k in module.KEYS if k not in listed]
    assert not missing, f'bench keys missing from the README: {missing}'


def test_the_model_pages_numbers_follow_from_the_code():
    from saw_ros.core import Scenario, v_theory, worm
    s = Scenario()
    model = ' '.join((ROOT / 'docs' / 'model.md').read_text().split())
    worm_page = ' '.join((ROOT / 'docs' / 'worm-model.md').read_text().split())
    kn, p = s.surface.normal_stiffness, s.surface.hertz_exponent
    squeeze = (s.robot.height - s.conditions.gap) / 2
    expected = {
        model: [f'{100 * v_theory(s.robot, 1.0):.2f} cm per helix turn',
                f'{s.robot.height * 1000:.0f} mm tall robot squeezed {squeeze * 1000:.0f} mm',
                f'1200 taken as such gives {1200 * 0.006 ** p:.2f} N per tip at 6 mm',
                f'{kn:.0f}'[:-3] + ' ' + f'{kn:.0f}'[-3:] + f' N/m^1.5 gives the measured 1200 N/m'
                f' x 6 mm = {kn * 0.006 ** p:.1f} N',
                f'm length^2 / 12 = {s.robot.inertia:.1e} kg m^2'.replace('e-03', 'e-3'),
                f'L / 9 = {s.robot.link * 1000:.1f} mm'],
        worm_page: [f'mu F_m | {worm.CALIBRATED_MOVING_FRICTION:.2f} N',
                    f'k_t of Figure 21 | {worm.FIGURE21_STIFFNESS:.0f} N/m',
                    f'{worm.zero_advance_stiffness(s):.0f} N/m on the level',
                    f'about {worm.anchor_normal_force(worm.WormParams(), s):.0f} N at the '
                    'defaults',
                    'this worm gives {:.2f} / {:.2f}'.format(
                        worm.closed_form(s).advance_ratio,
                        worm.closed_form(s.with_values({'conditions.slope': math.pi / 2}))
                        .advance_ratio)],
    }
    missing = [q for text, quotes in expected.items() for q in quotes if q not in text]
    assert not missing, f'docs/model.md or docs/worm-model.md do not say: {missing}'
