"""docs/calibration.md's flexibility section quotes the committed fits (issue 31)."""
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / 'docs' / 'calibration.md'


def section() -> str:
    text = DOC.read_text()
    return text[text.index('## Structural flexibility'):]


def row(text: str, label: str) -> list:
    for line in text.splitlines():
        if line.startswith(f'| {label} |'):
            return [cell.strip() for cell in line.strip('|').split('|')]
    raise AssertionError(f'no row {label!r} in docs/calibration.md')


@pytest.mark.parametrize('fit, column', [('flexures', 2), ('walls', 3)])
def test_the_fit_table_is_the_committed_result(fit, column):
    result = json.loads((ROOT / 'docs' / 'calibration' / fit / 'result.json').read_text())
    text = section()
    targets = {t['label']: t for t in result['targets']}
    speeds = ', '.join(f'{targets[label]["error_calibrated_pct"]:.1f}' for label in
                       ('speed +20 deg 6 V', 'speed +20 deg 4 V', 'speed -20 deg 7 V')) + ' %'
    assert row(text, 'speeds, error')[column] == speeds
    for label, key in (('AR level (A1)', 'AR +0 deg 1 Hz'), ('AR vertical (A2)',
                                                             'AR +90 deg 1 Hz')):
        t = targets[key]
        assert row(text, label)[column] == (f'{t["calibrated"]:.3f} '
                                            f'({t["error_calibrated_pct"]:.1f} %)')
    claims = result['claims']['calibrated']
    assert row(text, 'claims held, not trained on')[column] == \
        f'**{claims["held_untrained"]} of {claims["untrained"]}**'
    values = {p['name']: p['value'] for p in result['parameters']}
    motor = row(text, 'the motor: hz_per_volt, R, tau_f')[column]
    assert motor.startswith(f'{values["motor.hz_per_volt"]:.3f}, '
                            f'{values["motor.resistance"]:.1f}, ')
    structure = row(text, 'the structure')[column]
    if fit == 'flexures':
        assert f'{values["flexure.stiffness"]:.0f} N/m' in structure
        assert f'{values["flexure.damping"]:.3f} N s/m' in structure
    else:
        assert f'{values["surface.foundation_stiffness"]:.2e}'.replace('e+0', 'e') in structure
        assert f'{values["surface.bending_stiffness"]:.2e}'.replace('e-0', 'e-') in structure
    lost = [c for c in claims['not_held'] if c not in result['claims']['defaults']['not_held']]
    assert all(c in text for c in lost)
