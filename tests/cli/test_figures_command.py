"""`saw-ros figures` and `saw-ros statics` write and print what they promise."""
import csv

import pytest

from saw_ros.cli.main import main


def test_figures_quick_subset_writes_png_csv_and_report(tmp_path, capsys):
    assert main(['figures', '--out', str(tmp_path), '--only', '4,9,20', '--quick',
                 '--quiet', '--calibrated', 'none']) == 0
    figs = tmp_path / 'figures'
    for n in ('4', '9', '20'):
        png, table = figs / f'figure{n}.png', figs / f'figure{n}.csv'
        assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
        assert 5_000 < png.stat().st_size < 400_000
        rows = list(csv.reader(open(table)))
        assert len(rows) > 5
    assert not (figs / 'figure10.png').exists()
    header = next(csv.reader(open(figs / 'figure9.csv')))
    assert header == ['slope_deg', 'ar_gap_40mm', 'ar_gap_45mm', 'ar_gap_50mm']
    report = (tmp_path / 'fidelity.md').read_text()
    assert '| id | where | claim | paper | ours | tolerance | held |' in report
    assert '| G3 |' in report and '| S1 |' in report and '| W5 |' in report
    assert '| K1 |' not in report          # figure 10 was not requested
    assert 'figures/figure9.png' in report


def test_figures_report_shows_the_calibrated_set_beside_the_defaults(tmp_path, capsys):
    # A calibrated file as `saw-ros calibrate --write-config` writes it, trained on A1 and A2.
    from saw_ros.analysis.calibrate import calibrated_yaml
    from saw_ros.interface.config import config_path
    path = tmp_path / 'calibrated.yaml'
    path.write_text(calibrated_yaml(config_path('simulator.yaml').read_text(),
                                    {'surface.restitution': 0.5}, ['test'], ['A1', 'A2']))
    assert main(['figures', '--out', str(tmp_path), '--only', '11', '--quick', '--quiet',
                 '--calibrated', str(path)]) == 0
    report = (tmp_path / 'fidelity.md').read_text()
    assert '| id | where | claim | paper | defaults | calibrated | tolerance | held (defaults) ' \
        '| held (calibrated) |' in report
    assert '| A1 *trained* |' in report and '| F1 |' in report
    assert 'surface.restitution = 0.5' in report
    assert 'not trained on' in capsys.readouterr().err
    assert main(['figures', '--out', str(tmp_path), '--calibrated', str(tmp_path / 'no.yaml'),
                 '--quick']) == 2


def test_figures_rejects_unknown_figure(tmp_path, capsys):
    assert main(['figures', '--out', str(tmp_path), '--only', '5']) == 2
    assert 'unknown figure' in capsys.readouterr().err


def test_statics_prints_the_figure4_thresholds(capsys):
    assert main(['statics']) == 0
    out = capsys.readouterr().out
    assert '21.80 deg' in out and '15.68 deg' in out and 'every slope' in out
    assert '2.500 mg' in out          # case A total at 90 deg


def test_statics_custom_case_and_errors(capsys):
    assert main(['statics', '--slope-deg', '10', '--fext-mg', '0', '--mu', '0.4']) == 0
    assert 'not needed' in capsys.readouterr().out
    assert main(['statics', '--mu', '0.4']) == 2
    assert main(['statics', '--slope-deg', '120']) == 2


@pytest.mark.slow
def test_benchmark_reports_figures_s():
    from saw_ros.bench import figures
    assert figures.KEYS == ['figures_s']
    result = figures.run(quick=True)
    assert set(result) == {'figures_s'} and 0 < result['figures_s'] < 60
