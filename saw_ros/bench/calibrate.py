"""
The shipped calibration from scratch (issue 13): its wall time and what it reaches.

The same run as ``saw-ros calibrate --workers 2`` with the shipped defaults (the paper's targets,
the default parameters and budget): optimisation, sensitivity and the fidelity report's claims
with the calibrated set. ``quick`` runs a fifth of the generations and the claims on the quick
grids (its numbers are then those of a shorter fit, not the shipped one).
"""
import tempfile
import time

from saw_ros.analysis import calibrate as cal
from saw_ros.core.pool import LocalPool

KEYS = ['calibrate_s', 'measured_speed_error_pct', 'ar_level_calibrated',
        'ar_vertical_calibrated', 'claims_held_calibrated']


def run(quick=False):
    settings = cal.Settings()
    if quick:
        settings.generations = max(1, settings.generations // 5)
    with tempfile.TemporaryDirectory() as out, LocalPool(2) as pool:
        start = time.perf_counter()
        result = cal.calibrate(cal.paper_targets(), cal.default_parameters(), out, settings,
                               pool=pool, plots=True, claims='quick' if quick else 'full')
        elapsed = time.perf_counter() - start
    d = result.data
    ar = {t['claim']: t['calibrated'] for t in d['targets'] if t['claim']}
    return {'calibrate_s': round(elapsed, 1),
            'measured_speed_error_pct': round(cal.speed_error_pct(d), 2),
            'ar_level_calibrated': round(ar['A1'], 3),
            'ar_vertical_calibrated': round(ar['A2'], 3),
            'claims_held_calibrated': d['claims']['calibrated']['held_untrained']}
