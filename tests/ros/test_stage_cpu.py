"""A node's per-frame CPU clock: stages and the whole thread, per frame."""
import time

from saw_ros.ros.stage_cpu import StageCpu


def _spin(seconds: float) -> None:
    """Burn ``seconds`` of this thread's CPU."""
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


def test_stages_and_the_thread_per_frame():
    clock = StageCpu('decode', 'track')
    for _ in range(5):
        t = clock.add('decode', _start_after(clock, 0.002))
        _spin(0.004)
        clock.add('track', t)
        _spin(0.001)                   # in no stage: the thread's share only
        clock.frame()
    ms = clock.per_frame_ms()
    assert 1.9 < ms['decode'] < 2.6 and 3.9 < ms['track'] < 4.6
    # frames 2..5 each: 2 + 4 + 1 ms
    assert 6.9 < ms['thread'] < 7.8
    assert clock.summary().startswith('cpu ms a frame: decode=2.')


def _start_after(clock: StageCpu, seconds: float) -> float:
    t = clock.now()
    _spin(seconds)
    return t


def test_no_frame_says_no_thread_figure():
    clock = StageCpu('render')
    assert clock.per_frame_ms() == {'render': 0.0}
    clock.frame()
    assert 'thread' not in clock.per_frame_ms()
