"""
Which two pink things are the robot's markers: the tracker's acquisition.

4. Acquisition (no marker tracked yet, or both lost for ``reacquire_after`` frames, which also
   forgets what was learned of the pair: spacing, vector, size, colour, unless given): a marker
   is pink in absolute terms (colour (B - G) / (R - G) >= ``colour_min``: red and shadowed red
   are 0-0.2), round, of a ``marker_diameter`` disc's area when that is given. A pair is two of
   them of similar size (area ratio <= 2.5) and colour (within ``colour_tolerance``), their
   distance within ``spacing_tolerance`` of ``marker_spacing`` (times the scale) when given.
   First choice: a pair that has moved together as one rigid body along its own line for
   ACQUIRE_FRAMES frames or more (each candidate followed from frame to frame, nearest within
   ``gate``; spacing constant within 1.5 px + 1 %, at least 4 px travelled, within 25 deg of
   the line): the robot. While no candidate moves, and only with the slope known and before
   anything was seen moving, the old rule: the cheapest pair on the track's line (within
   ``max_pitch``) when no other comes within 0.25 of its cost. Such a static pair is dropped
   (with what was learned of it) as soon as another pair moves as the robot does, and its
   frames are then not the robot's (``switched_at``); while it is held, a warning says so.
   Otherwise the frame is ``ambiguous`` (or 'both lost' with fewer than two marker-like blobs).

``Acquisition`` is a part of ``tracker.Tracker`` (it reads and sets the tracker's state: what
was learned of the pair, the candidates' recent motion); it reads on its own here.
"""
from __future__ import annotations

from collections import deque
import math
from typing import Deque, List, Optional, Tuple

import numpy as np

from saw_ros.vision.association import _Track
from saw_ros.vision.markers import Candidate
from saw_ros.vision.measurement import TrackerState

SIZE_RATIO = 2.5          # largest area ratio of the two markers (or of a marker to its size)
CLEAR_MARGIN = 0.25       # acquisition: the best pair's cost must beat the next by this much
MOTION_FRAMES = 30        # acquisition: frames over which candidates' motion counts
ACQUIRE_FRAMES = 6        # ... a moving pair must have been seen together this many frames
MIN_MOTION = 4.0          # px along the marker line to count as moving
RIGID_PX = 1.5            # ... and keep its spacing within this (plus 1 %) meanwhile
MOTION_ANGLE = math.radians(25.0)   # ... moving along its own line within this
ROUND_MIN = 0.6           # acquisition: least roundness (smaller / larger second moment)


class Acquisition(TrackerState):
    """The tracker's acquisition: taking the pair, confirming or dropping a static one."""

    def _expected_spacing(self) -> Optional[float]:
        if self.config.marker_spacing is not None:
            return self.config.marker_spacing * self.camera.scale
        return self._spacing

    def _motions(self, cands: List[Candidate]) -> List[Deque[complex]]:
        """
        Each candidate's recent positions (scene frame), up to MOTION_FRAMES frames back.

        Candidates are chained to the nearest of the previous frame's.
        """
        free = list(range(len(self._chains)))
        chains, hists = [], []
        for c in cands:
            best, best_d = None, self.config.gate
            for k in free:
                d = abs(c.q - self._chains[k][0])
                if d < best_d:
                    best, best_d = k, d
            if best is None:
                hist: Deque[complex] = deque(maxlen=MOTION_FRAMES + 1)
            else:
                free.remove(best)
                hist = self._chains[best][1]
            hist.append(c.q)
            chains.append((c.q, hist))
            hists.append(hist)
        self._chains = chains
        return hists

    def _marker_like(self, c: Candidate) -> float:
        """Return the candidate's cost as a marker alone (> 1: not a marker)."""
        if not c.colour >= self.config.colour_min or c.roundness < ROUND_MIN:
            return math.inf
        if self._given_area is None:
            return 0.0
        return (math.log(max(c.area, 1.0) / self._given_area) / math.log(SIZE_RATIO)) ** 2

    def _pair_cost(self, ca: Candidate, cb: Candidate, d: float, spacing) -> Optional[float]:
        """Return the cost of two candidates as the two markers (None: they are not)."""
        size = math.log(max(ca.area, 1.0) / max(cb.area, 1.0)) / math.log(SIZE_RATIO)
        colour = (ca.colour - cb.colour) / self.config.colour_tolerance
        if abs(size) > 1.0 or not abs(colour) <= 1.0 or d < 2.0 * self.config.merge_distance:
            return None
        cost = size ** 2 + colour ** 2
        if spacing is not None:
            dev = (d - spacing) / (self.config.spacing_tolerance * spacing)
            if abs(dev) > 1.0:
                return None
            cost += dev ** 2
        return cost

    def _moving_pairs(self, cands, hists, single) -> List[Tuple[float, int, int]]:
        """
        Return the pairs (cost, front, back) that move together as one rigid body.

        Along their own line, for ACQUIRE_FRAMES frames or more: the robot. The front is the
        marker ahead along the track when its slope is known, else along the motion.
        """
        # (A spacing learned on a pair that never moved may be the wrong pair's.)
        spacing = self._expected_spacing() if self._confirmed or \
            self.config.marker_spacing is not None else None
        out = []
        track = complex(math.cos(self.camera.slope), -math.sin(self.camera.slope))
        if self.camera.mirror:
            track = -track.conjugate()
        for a in range(len(cands)):
            if single[a] > 1.0 or len(hists[a]) < ACQUIRE_FRAMES:
                continue
            for b in range(a + 1, len(cands)):
                if single[b] > 1.0 or len(hists[b]) < ACQUIRE_FRAMES:
                    continue
                n = min(len(hists[a]), len(hists[b]))
                pa = np.array(hists[a])[-n:]
                pb = np.array(hists[b])[-n:]
                dist = np.abs(pa - pb)
                if dist.max() - dist.min() > RIGID_PX + 0.01 * dist.mean():
                    continue
                move = 0.5 * (pa[-1] + pb[-1] - pa[0] - pb[0])
                line = pa[-1] - pb[-1]
                along = (move * line.conjugate()).real / abs(line)
                if abs(along) < MIN_MOTION or abs(along) < math.cos(MOTION_ANGLE) * abs(move):
                    continue
                cost = self._pair_cost(cands[a], cands[b], float(dist[-1]), spacing)
                if cost is None:
                    continue
                ahead = (line * track.conjugate()).real if self.slope_known else along
                front, back = (a, b) if ahead > 0 else (b, a)
                out.append((cost + single[a] + single[b], front, back))
        out.sort()
        return out

    def _static_pair(self, cands, single):
        """Return the old rule: the clearly cheapest pair on the track's line, or None."""
        cfg = self.config
        q = np.array([c.q for c in cands])
        surface = self.camera.to_surface(q) * complex(math.cos(cfg.marker_line_angle),
                                                      -math.sin(cfg.marker_line_angle))
        spacing = self._expected_spacing()
        pairs = []
        for a, ca in enumerate(cands):
            if single[a] > 1.0:
                continue
            for b, cb in enumerate(cands):
                if a == b or single[b] > 1.0:
                    continue
                line = surface[a] - surface[b]
                angle = math.atan2(line.imag, line.real) / cfg.max_pitch
                if abs(angle) > 1.0:        # also refuses the pair in the wrong order
                    continue
                cost = self._pair_cost(ca, cb, abs(q[a] - q[b]), spacing)
                if cost is not None:
                    pairs.append((cost + angle ** 2 + single[a] + single[b], a, b))
        if not pairs:
            return None, False
        pairs.sort()
        close = [p for p in pairs if p[0] < pairs[0][0] + CLEAR_MARGIN]
        return (close[0] if len(close) == 1 else None), len(close) > 1

    def _acquire(self, cands: List[Candidate], hists):
        """
        {'front': Candidate or None, 'back': ...} and whether it was ambiguous.

        A pair moving rigidly along its line is taken first; a static pair (the clearly cheapest
        on the track's line) only while no candidate moves, with the slope known, and before any
        pair was seen moving (once the robot moved, something static is not the robot).
        """
        none = {'front': None, 'back': None}
        if len(cands) < 2:
            return none, False
        single = [self._marker_like(c) for c in cands]
        moving = self._moving_pairs(cands, hists, single)
        if moving:
            close = [p for p in moving if p[0] < moving[0][0] + CLEAR_MARGIN]
            if len(close) > 1:
                return none, True
            _, a, b = moving[0]
            self._confirmed = self._seen_moving = True
        else:
            still = all(abs(h[-1] - h[0]) < MIN_MOTION for h in hists)
            if not (self.slope_known and still and not self._seen_moving):
                # Something pink moves (or the track's direction is unknown): wait for a pair
                # that moves as the robot does.
                return none, sum(cost <= 1.0 for cost in single) >= 2
            pair, ambiguous = self._static_pair(cands, single)
            if pair is None:
                return none, ambiguous
            _, a, b = pair
        self.counters.acquisitions += 1
        self._locked_at = (cands[a].q, cands[b].q)
        return {'front': cands[a], 'back': cands[b]}, False

    def _check_lock(self, cands, hists, found) -> Optional[dict]:
        """
        Confirm a pair locked while static once it moves, or drop it for a moving pair.

        Returns the moving pair to take instead, or None.
        """
        f, b = found['front'], found['back']
        if f is not None and b is not None and self._locked_at is not None and \
                min(abs(f.q - self._locked_at[0]), abs(b.q - self._locked_at[1])) >= MIN_MOTION:
            self._confirmed = self._seen_moving = True
            self._chains = []
            return None
        single = [self._marker_like(c) for c in cands]
        moving = [p for p in self._moving_pairs(cands, hists, single)
                  if cands[p[1]] is not f and cands[p[2]] is not b]
        if len(moving) != 1 and not (moving and moving[1][0] >= moving[0][0] + CLEAR_MARGIN):
            return None
        _, a, bb = moving[0]
        self._switches += 1
        self.switched_at = self._last_t
        self._forget()
        self._history.clear()
        self._tracks = {'front': _Track(), 'back': _Track()}
        self._confirmed = self._seen_moving = True
        self.counters.acquisitions += 1
        return {'front': cands[a], 'back': cands[bb]}
