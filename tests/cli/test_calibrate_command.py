"""`saw-ros calibrate`: a quick run from footage.csv writes its outputs; mistakes are one line."""
import json

from saw_ros.cli.main import main
from saw_ros.interface.config import load_parameters

FOOTAGE = """\
video,slope_deg,voltage_V,frequency_hz,v_measured,ar_measured,window_s,v_theory,v_sim,ar_sim,\
relative_error,frames,frames_ok,px_per_m,scale_from,notes
level_6V.mp4,0,6,1.44,0.0755,0.747,1.38,0.101,0.0755,0.7475,7.5e-05,60,60,600,px_per_m,
climb_10deg_5V.mp4,10,5,1.2,0.0623,0.740,1.66,0.084,0.0623,0.739,0.0006,60,60,600,px_per_m,
"""


def test_quick_calibration_from_footage_writes_results_and_parameter_file(tmp_path, capsys):
    targets = tmp_path / 'footage.csv'
    targets.write_text(FOOTAGE)
    out, yaml_path = tmp_path / 'run', tmp_path / 'calibrated.yaml'
    assert main(['calibrate', '--targets', str(targets), '--params', 'motor.hz_per_volt',
                 'surface.restitution:0.5:1.0', '--quick', '--out', str(out),
                 '--write-config', str(yaml_path)]) == 0
    printed = capsys.readouterr()
    assert 'speed +10 deg 5 V' in printed.out and 'claims held' in printed.out
    for name in ('state.pkl', 'history.csv', 'result.json', 'fit.png', 'sensitivity.png',
                 'convergence.png'):
        assert (out / name).stat().st_size > 0, name
    result = json.loads((out / 'result.json').read_text())
    assert result['generations'] == 3 and result['popsize'] == 6
    assert [t['name'] for t in result['targets']] == ['level_6V.mp4', 'climb_10deg_5V.mp4']
    assert result['trained_claims'] == []
    assert result['claims']['calibrated']['untrained'] == 34
    values = load_parameters(yaml_path, 'simulator')
    fitted = {p['name']: p['value'] for p in result['parameters']}
    assert values['motor.hz_per_volt'] == fitted['motor.hz_per_volt']
    assert 0.5 <= values['surface.restitution'] <= 1.0
    # Resuming a finished run with more generations continues it.
    assert main(['calibrate', '--resume', str(out), '--generations', '4', '--quiet']) == 0
    assert json.loads((out / 'result.json').read_text())['generations'] == 4


def test_mistakes_are_one_line_errors(tmp_path, capsys):
    assert main(['calibrate', '--params', 'surface.stiffness', '--quick']) == 2
    assert "unknown parameter 'surface.stiffness'" in capsys.readouterr().err
    assert main(['calibrate', '--params', 'surface.restitution:0:2', '--quick']) == 2
    assert 'outside its allowed range' in capsys.readouterr().err
    assert main(['calibrate', '--targets', str(tmp_path / 'none.csv'), '--quick']) == 2
    assert 'no such targets file' in capsys.readouterr().err
    assert main(['calibrate', '--resume', str(tmp_path), '--quick']) == 2
    assert 'nothing to resume' in capsys.readouterr().err
    assert main(['calibrate', '--resume', str(tmp_path), '--params', 'surface.restitution']) == 2
    assert 'do not give' in capsys.readouterr().err


def test_without_the_optimiser_package_calibrate_says_what_to_install(tmp_path, monkeypatch,
                                                                      capsys):
    """A ROS install from rosdep lacks cmaes (no rosdep key): one line, not a traceback."""
    import sys
    monkeypatch.setitem(sys.modules, 'cmaes', None)          # import cmaes -> ImportError
    assert main(['calibrate', '--quick', '--out', str(tmp_path / 'run')]) == 2
    err = capsys.readouterr().err
    assert 'pip install cmaes==0.13.1' in err and 'Traceback' not in err
    assert not (tmp_path / 'run').exists()


def test_a_fit_worse_than_its_start_does_not_write_the_config_unless_asked(tmp_path, capsys):
    """Targets the defaults already meet: any short fit ends worse, and says what to do."""
    from saw_ros.analysis import calibrate as cal
    targets = tmp_path / 'own.csv'
    targets.write_text(FOOTAGE)
    # The defaults' own speeds as the measurements: the start fits them exactly.
    own = cal.Model(cal.load_targets(targets)).outcomes([{}])[0]
    rows = FOOTAGE.splitlines()
    lines = [rows[0]] + [','.join(r.split(',')[:4] + [repr(float(v))] + r.split(',')[5:])
                         for r, v in zip(rows[1:], own)]
    targets.write_text('\n'.join(lines) + '\n')
    out, yaml_path = tmp_path / 'run', tmp_path / 'calibrated.yaml'
    args = ['calibrate', '--targets', str(targets), '--params', 'motor.hz_per_volt', '--quick',
            '--quiet', '--out', str(out), '--write-config', str(yaml_path)]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert not yaml_path.exists()
    assert f'did not write {yaml_path}' in err and 'worse than the parameters it started from' \
        in err and f'--resume {out} --generations 60' in err and '--write-worse' in err
    result = json.loads((out / 'result.json').read_text())
    assert result['loss'] > result['loss_default']
    assert main(args + ['--write-worse']) == 0
    assert yaml_path.is_file()
    assert main(['calibrate', '--quick', '--write-worse']) == 2
    assert '--write-worse applies to --write-config' in capsys.readouterr().err
