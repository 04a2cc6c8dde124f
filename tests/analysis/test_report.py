"""The main job's report: the comparison as text, and report.png from a recording."""
from pathlib import Path

from saw_ros.analysis.report import format_comparison, write_report

BAGS = Path(__file__).resolve().parents[2] / 'bags'
STEADY = {'status': 'steady', 'ar_sim': 0.75444, 'ar_tracked': 0.75445,
          'relative_error': 1.3e-5, 'v_theory_m_s': 0.0703, 'v_sim_m_s': 0.0530,
          'v_tracked_m_s': 0.05301, 'steady_from_s': 0.58, 'window_s': 2.0,
          'slope_deg': 0.0, 'frequency_hz': 1.2,
          'reference_error_sim': 0.14, 'reference_source': 'Figure 17'}


def test_a_steady_comparison_is_printed_line_by_line():
    lines = format_comparison(STEADY).splitlines()
    assert lines[0].split() == ['AR', 'simulation', '0.7544']
    assert lines[2].split() == ['relative', 'error', '0.00', '%']
    assert lines[-1] == 'simulation vs measured (paper): 14.0 % (Figure 17)'
    without_reference = dict(STEADY, reference_error_sim=float('nan'))
    assert len(format_comparison(without_reference).splitlines()) == len(lines) - 1


def test_an_unsteady_comparison_says_its_status():
    assert format_comparison({'status': 'waiting for steady state'}) == \
        'comparison: waiting for steady state'
    assert format_comparison({}) == 'comparison: no result'


def test_the_report_is_drawn_from_the_recording(tmp_path):
    path = write_report(BAGS / 'reference_default', {'status': 'transient'}, tmp_path)
    assert path == tmp_path / 'report.png'
    assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    path.unlink()
    assert write_report(BAGS / 'reference_default', STEADY, tmp_path).stat().st_size > 10_000
