"""Wall time of the whole figure set (issue 7): every sweep, PNG, CSV and the report."""
import tempfile
import time

KEYS = ['figures_s']


def run(quick=False):
    from saw_ros.analysis.figures import reproduce
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        reproduce(out, quick=quick)
        return {'figures_s': round(time.perf_counter() - start, 2)}
