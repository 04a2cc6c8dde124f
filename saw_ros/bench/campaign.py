"""Wall time of the paper's 20-condition campaign (simulation, camera, tracker), in-process."""
import time

from saw_ros.analysis.campaign import PAPER_SLOPES_DEG, PAPER_VOLTAGES, run_campaign

KEYS = ['campaign_s']


def run(quick=False):
    slopes = PAPER_SLOPES_DEG[::2] if quick else PAPER_SLOPES_DEG
    start = time.perf_counter()
    run_campaign(slopes, PAPER_VOLTAGES, workers=2)
    return {'campaign_s': round(time.perf_counter() - start, 2)}
