"""The main job's consumers run under SCHED_BATCH, the simulator under the default policy."""
import os
import sys

import pytest
from saw_ros.graph.process import ManagedProcess

REPORT = ('import os, threading; r = []; t = threading.Thread(target=lambda: r.append('
          'os.sched_getscheduler(0))); t.start(); t.join(); '
          'print(os.sched_getscheduler(0), r[0])')


@pytest.mark.skipif(not hasattr(os, 'SCHED_BATCH'), reason='Linux scheduling policies only')
@pytest.mark.parametrize('batch', [True, False])
def test_a_batch_process_and_the_threads_it_starts_run_under_sched_batch(tmp_path, batch):
    p = ManagedProcess('policy', [sys.executable, '-c', REPORT], dict(os.environ), tmp_path,
                       batch=batch)
    assert p.wait(30) == 0
    main, thread = map(int, p.output().split())
    want = os.SCHED_BATCH if batch else os.SCHED_OTHER
    assert (main, thread) == (want, want)
