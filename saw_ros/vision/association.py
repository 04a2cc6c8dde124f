"""
Which candidate is which marker from frame to frame: the tracker's association.

5. Tracking: front and back keep their identity by prediction (last position + pixel velocity
   x elapsed time; a marker lost meanwhile is predicted from the other through the last
   back->front vector, the robot being rigid) and the cheapest assignment of candidates within
   ``gate`` pixels whose colour matches the marker's; a pair must keep the marker spacing
   measured so far (within 3 px or 2 %). A blob much larger than the marker (1.5x: something
   pink touching it) is not measured; a much smaller one (0.5x: mostly hidden) is not the marker;
   one smaller by 15 % or less round by 0.13 than it usually is (or by 6 times its usual
   scatter, for small markers) is partly hidden: its centroid is not its centre, the frame is
   'partial'. A marker for which another assignment fits within ``merge_distance`` / 2 px of
   the best is ambiguous: it is not measured. A third pink thing passing near the robot is thus
   ignored unless it is where the marker should be.

``Association`` is a part of ``tracker.Tracker`` (it reads the markers' tracks and what was
learned of them); it reads on its own here.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Dict, List, Optional, Tuple

from saw_ros.vision.markers import Candidate
from saw_ros.vision.measurement import MARKERS, TrackerState

MERGED = 1.5              # a blob this much larger than the tracked marker holds something else
PARTIAL = 0.5             # ... this much smaller: the marker is mostly hidden
# Tracking: a marker whose area falls below this fraction of its own (or by 6 times its usual
# scatter, for small markers whose area and roundness jump from frame to frame) is partly hidden
PARTIAL_AREA = 0.85
# ... or less round than it was by this much (a 14 px disc: 0.92-1; with noise, blur, lens and
# JPEG 70, down by 0.11 at worst; cut by an edge so that its centroid moves 0.6 px: 0.74-0.8
# instead of 0.96; a 7 px disc through mp4: 0.70-0.99)
PARTIAL_ROUND = 0.13
SCATTER = 6.0
SCATTER_FRAMES = 10       # measurements of a marker before it can be judged partly hidden
SPACING_PX = 3.0          # tracking: the marker spacing may change by max(this, ...)
SPACING_FRACTION = 0.02   # ... this fraction of it from frame to frame


@dataclass
class _Track:
    p: Optional[complex] = None       # last measured (ideal) pixel position
    t: float = 0.0                    # when
    v: complex = 0j                   # px/s

    def predict(self, t: float) -> complex:
        assert self.p is not None, 'a track predicts once it has a position'
        return self.p + self.v * (t - self.t)

    def update(self, p: complex, t: float) -> None:
        if self.p is not None and t > self.t:
            v = (p - self.p) / (t - self.t)
            self.v = v if self.v == 0 else 0.5 * (self.v + v)
        self.p, self.t = p, t


class Association(TrackerState):
    """The tracker's association: prediction, assignment, markers partly hidden."""

    def _predict(self, t: float) -> Dict[str, complex]:
        front, back = self._tracks['front'], self._tracks['back']
        pf, pb = front.predict(t), back.predict(t)
        if self._vector is not None:           # a marker lost meanwhile follows the other
            if front.t < back.t:
                pf = pb + self._vector
            elif back.t < front.t:
                pb = pf - self._vector
        return {'front': pf, 'back': pb}

    def _track(self, cands: List[Candidate], t: float):
        """{'front': Candidate or None, 'back': ...}, whether it was ambiguous, partial markers."""
        cfg = self.config
        gate = cfg.gate
        pred = self._predict(t)
        near: Dict[str, List[Tuple[Optional[int], float]]] = {}
        for name in MARKERS:
            colour, area = self._colour[name], self._area[name]
            near[name] = []
            for k, c in enumerate(cands):
                d = abs(c.q - pred[name])
                if d > gate:
                    continue
                if colour is not None and not abs(c.colour - colour) <= cfg.colour_tolerance:
                    continue
                if area is not None and c.area < PARTIAL * area:
                    continue
                near[name].append((k, d))
        spacing = self._spacing
        tol = max(SPACING_PX, SPACING_FRACTION * spacing) if spacing else math.inf
        options: List[Tuple[float, Optional[int], Optional[int]]] = []
        none: List[Tuple[Optional[int], float]] = [(None, gate)]
        for i, df in [*near['front'], *none]:
            for j, db in [*near['back'], *none]:
                if i is not None and i == j:
                    continue
                if i is not None and j is not None and spacing is not None and \
                        abs(abs(cands[i].q - cands[j].q) - spacing) > tol:
                    continue
                options.append((df + db, i, j))
        options.sort(key=lambda o: o[0])
        cost, i, j = options[0]
        found = {'front': None if i is None else cands[i],
                 'back': None if j is None else cands[j]}
        ambiguous = False
        partial = []
        margin = 0.5 * cfg.merge_distance
        for slot, name in ((1, 'front'), (2, 'back')):
            chosen = options[0][slot]
            if chosen is None:
                continue
            chosen = int(chosen)
            area = self._area[name]
            rival = any(o[slot] is not None and o[slot] != chosen and o[0] <= cost + margin
                        for o in options[1:])
            if rival or (area is not None and cands[chosen].area > MERGED * area):
                found[name] = None
                ambiguous = True
            elif area is not None and self._partial(name, cands[chosen]):
                # Partly hidden: the visible part's centroid is not the marker's centre.
                found[name] = None
                partial.append(name)
        return found, ambiguous, partial

    def _partial(self, name: str, c: Candidate) -> bool:
        """Whether a marker's blob is smaller or less round than it usually is: partly hidden."""
        area, roundness = self._area[name], self._round[name]
        d_area, d_round, n = self._scatter[name]
        if n < SCATTER_FRAMES or area is None or roundness is None:
            return False            # (too few measurements to know what is usual)
        return c.area < area - max((1.0 - PARTIAL_AREA) * area, SCATTER * d_area) or \
            c.roundness < roundness - max(PARTIAL_ROUND, SCATTER * d_round)
