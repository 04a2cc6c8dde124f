"""DDS domains of concurrent runs: two processes (two pytest workers) never share one."""
import json
import subprocess
import sys

CHILD = """
import json, sys, time
from saw_ros.graph import process
kept = process.reserve_domain(keep=True)
others = [process.reserve_domain() for _ in range(3 * process.HELD_DOMAINS)]
print(json.dumps({'kept': kept, 'held': sorted(process._held)}), flush=True)
sys.stdin.read()     # hold every lock until the test has looked at both processes
"""


def test_a_kept_domain_stays_its_process_own_after_many_more_reservations():
    procs = [subprocess.Popen([sys.executable, '-c', CHILD], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True) for _ in range(2)]
    try:
        seen = [json.loads(p.stdout.readline()) for p in procs]
    finally:
        for p in procs:
            p.communicate('', timeout=30)
    a, b = seen
    # 48 reservations each, 16 kept as held: the kept one was never handed on (to the other
    # process, nor back to its own) and no id is held by both.
    assert a['kept'] != b['kept']
    assert a['kept'] not in b['held'] and b['kept'] not in a['held']
    assert a['kept'] not in a['held'] and b['kept'] not in b['held']
    assert not set(a['held']) & set(b['held'])
