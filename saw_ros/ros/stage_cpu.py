"""
CPU of a node's per-frame stages, for its last log line: where a frame's CPU goes.

``time.thread_time`` (the calling thread's CPU, not wall time): on a loaded machine a stage's
wall time is mostly the wait for a core, its CPU is what it costs. One ``StageCpu`` per thread;
besides the stages it keeps the thread's whole CPU from its first frame to its last, so that
what no stage covers (the executor taking messages, the 1 kHz inputs of the camera) shows too.
"""
from __future__ import annotations

import time
from typing import Dict, Optional


class StageCpu:
    """Add each stage's CPU with ``add``, end each frame with ``frame``; read ``summary``."""

    def __init__(self, *stages: str):
        self.cpu: Dict[str, float] = dict.fromkeys(stages, 0.0)
        self.frames = 0
        self._first: Optional[float] = None     # the thread's CPU at the end of its first frame
        self._last = 0.0

    @staticmethod
    def now() -> float:
        return time.thread_time()

    def add(self, stage: str, since: float) -> float:
        """Add the CPU since ``since`` (a ``now()``) to ``stage``; return the time now."""
        now = time.thread_time()
        self.cpu[stage] += now - since
        return now

    def frame(self) -> None:
        """Close the current frame's stages: call it on their thread, once a frame."""
        self._last = time.thread_time()
        if self._first is None:
            self._first = self._last
        self.frames += 1

    def per_frame_ms(self) -> Dict[str, float]:
        """Return each stage's CPU per frame (ms), and 'thread': all of the thread's."""
        n = max(self.frames, 1)
        out = {k: 1e3 * v / n for k, v in self.cpu.items()}
        if self._first is not None and self.frames > 1:
            out['thread'] = 1e3 * (self._last - self._first) / (self.frames - 1)
        return out

    def summary(self) -> str:
        """Return 'cpu ms a frame: stage=x ... thread=y' (the stages of ``frames`` frames)."""
        return 'cpu ms a frame: ' + ' '.join(f'{k}={v:.3f}'
                                             for k, v in self.per_frame_ms().items())
