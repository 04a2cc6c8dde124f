"""
The paper's claims (``docs/model.md`` section 10, ``docs/worm-model.md``) held against ours.

Each claim has the paper's value, ours, the tolerance and a verdict. Tolerances come from the
paper's own wording, not from our numbers:
- numbers the paper quotes in whole degrees: +-1 deg;
- simulated AR values: +-10 % relative (the paper's own simulation matched its experiments to a
  mean 11.37 %; nothing tighter can be asked of a model whose r, b, I, e and kn interpretation
  the paper does not give);
- "hardly depends on / only marginally decreases with slope": a 0-90 deg drop of at most 15 % of
  the level AR, the drop of the paper's own default case (0.72 -> 0.61) which it calls marginal;
  "degrades badly": more than that;
- convergence times: +0.1 s (our CCI samples every 1 ms, the paper's plot is read by eye);
- every ordinal claim ("higher", "falls", "wins") is checked as an ordering, no margin.
A claim that is not held keeps its verdict; ``why`` says what we believe causes it.
"""
from __future__ import annotations

from dataclasses import dataclass
import functools
import math
from typing import List, Optional

import numpy as np

from saw_ros.analysis.figures import sweeps
from saw_ros.analysis.figures.sweeps import (COFS, Data, DEFAULT_GAP_MM, DEFAULT_KT, DEFAULT_MU,
                                             FIG10_SLOPES, FIG21_KT, GAPS_MM)
from saw_ros.core import worm as worm_model
from saw_ros.core.statics import minimal_normal_forces, top_surface_needed_above

AR_REL_TOL = 0.10
MARGINAL_DROP = (0.72 - 0.61) / 0.72      # 15.3 %: the paper's own "marginal" decrease


@dataclass
class Claim:
    id: str  # noqa: A003
    source: str         # where the paper says it
    statement: str
    paper: str
    ours: str
    tolerance: str
    held: Optional[bool]        # None: not computed (figure not requested)
    why: str = ''               # shown when not held
    note: str = ''              # shown always (e.g. "calibrated")

    def __post_init__(self):
        if self.held is not None:
            self.held = bool(self.held)      # numpy bools print and compare oddly


def _f(x, d=3):
    # Said in words: a bare nan in the report would not tell the reader what happened.
    return ('not computed (a run diverged or never settled)' if x is None or not math.isfinite(x)
            else f'{x:.{d}f}')


def _drop(values):
    return values[0] - values[-1]


def _needed_above_deg(external_force: float, mu: float) -> float:
    """Return the slope (deg) above which the top surface must press; inf if never to 90 deg."""
    a = top_surface_needed_above(external_force, mu)
    return math.inf if a is None else math.degrees(a)


def statics_claims() -> List[Claim]:
    out = []
    a = _needed_above_deg(0.0, 0.4)
    out.append(Claim('S1', 'Sec. 3, Fig. 4 A', 'case A (F_ext 0, mu 0.4): the top surface is '
                     'needed above 22 deg', '22 deg', f'{a:.2f} deg', '+-1 deg', abs(a - 22) <= 1))
    b, t, tot = minimal_normal_forces(math.pi / 2, 0.0, 0.4)
    ok = bool(abs(tot - 2.5) < 1e-9 and abs(b - 1.25) < 1e-9 and abs(t - 1.25) < 1e-9)
    out.append(Claim('S2', 'Sec. 3, Fig. 4 A', 'case A at 90 deg: total 2.5 m g, 1.25 m g each '
                     'side', '2.5 / 1.25 / 1.25 m g', f'{tot:.3f} / {b:.3f} / {t:.3f} m g',
                     'exact (1e-9)', ok))
    thr = _needed_above_deg(0.5, 0.4)
    out.append(Claim('S3', 'Sec. 3, Fig. 4 B', 'case B (F_ext 0.5 m g, mu 0.4): the top surface '
                     'is needed at every slope', 'from 0 deg', f'from {thr:.2f} deg',
                     'exact', thr == 0.0))
    b, t, _ = minimal_normal_forces(math.pi / 2, 0.5, 0.4)
    out.append(Claim('S4', 'Sec. 3, Fig. 4 B', 'case B at 90 deg: bottom and top forces equal, '
                     '1.875 m g each', '1.875 / 1.875 m g', f'{b:.3f} / {t:.3f} m g',
                     'exact (1e-9)', bool(abs(b - 1.875) < 1e-9 and abs(t - 1.875) < 1e-9)))
    c = _needed_above_deg(0.5, 0.8)
    out.append(Claim('S5', 'Sec. 3, Fig. 4 C', 'case C (F_ext 0.5 m g, mu 0.8): no top surface '
                     'needed up to 15 deg', '15 deg', f'{c:.2f} deg', '+-1 deg', abs(c - 15) <= 1,
                     note='the paper truncates 15.68 deg to "15"'))
    return out


def convergence_claims(data: Data) -> List[Claim]:
    ts = data.timeseries
    if ts is None:
        return []
    m = ts['metrics']
    vx = ts['settle']['vx']
    out = [Claim('C1', 'Sec. 5, Fig. 7', 'from rest at 1 Hz the velocities settle within the '
                 'first 2.5 s', '< 2.5 s', f'{_f(m.steady_from, 2)} s (CCI of vx < 2 %)',
                 'within 2.5 s', m.steady_from is not None and m.steady_from <= 2.5)]
    t2 = m.cci_2pct_after
    out.append(Claim(
        'C2', 'Sec. 5, Fig. 8', "every velocity's CCI under 2 % after 0.4 s", '0.4 s',
        f'{_f(t2, 2)} s (vx alone: {_f(vx[0.02], 2)} s)', '+0.1 s',
        t2 is not None and t2 <= 0.5,
        why='Our robot starts centred in the gap, at rest, at wave phase 0 (the paper does not '
            'give its initial state) and drops onto the squeezed tips; the normal and pitch '
            'velocities ring down through the contact hysteresis (restitution e = 0.9, made '
            'continuous below 10 mm/s, contact.py), neither of which the paper quantifies. The '
            'paper also does not define the CCI of the normal and pitch velocities, whose mean '
            'is near zero; we scale them by their steady RMS (metrics.py). The forward velocity '
            'alone settles at the time given in brackets.'))
    t02 = m.cci_02pct_after
    out.append(Claim('C3', 'Sec. 5, Fig. 8', "every velocity's CCI under 0.2 % after 1.2 s",
                     '1.2 s', f'{_f(t02, 2)} s (vx alone: {_f(vx[0.002], 2)} s)', '+0.1 s',
                     t02 is not None and t02 <= 1.3,
                     why='See C2: initial state and hysteresis are not given by the paper.'))
    return out


def _rel(ours, paper):
    return abs(ours - paper) / paper


def ar_claims(data: Data) -> List[Claim]:
    if '11' not in data.figures:
        return []
    level, vertical = data.ar(slope=0), data.ar(slope=90)
    at532 = ''
    if '21' in data.figures:
        at532 = (f' (at {FIG21_KT:.0f} N/m: {_f(data.ar(slope=0, kt=FIG21_KT))} / '
                 f'{_f(data.ar(slope=90, kt=FIG21_KT))})')
    why_v = ("Our robot climbs better than the paper's: its 0-90 deg drop is "
             f"{_f(_drop([level, vertical]))} against the paper's 0.11. How much the climb "
             'costs depends on how hard the tips are squeezed and how stiff the contact is in '
             'shear: the squeeze follows from the robot\'s height 2 (A + r), whose A ("3.7 cm") '
             'and r the paper does not give consistently (docs/model.md section 8), and from kn, '
             'which the paper gives as "about 1200 N/m" for a 1.5-power law (we use 15 500 '
             'N/m^1.5, matching its 7.2 N at 6 mm). The contact hysteresis (e, not given) also '
             'shapes the slip. At the stiffness the worm calibration implies for Figure 21 '
             f'({FIG21_KT:.0f} N/m) our vertical AR comes closer (see "ours").')
    return [
        Claim('A1', 'Sec. 8, Fig. 21', f'wave AR on the level (defaults: {DEFAULT_GAP_MM:g} mm, '
              f'{DEFAULT_KT:g} N/m, COF {DEFAULT_MU:g})',
              '0.72', _f(level) + at532, '+-10 % rel.', _rel(level, 0.72) <= AR_REL_TOL,
              why='See A2.'),
        Claim('A2', 'Sec. 8, Fig. 21', 'wave AR climbing vertically (defaults)', '0.61',
              _f(vertical) + at532, '+-10 % rel.', _rel(vertical, 0.61) <= AR_REL_TOL,
              why=why_v),
    ]


def gap_claims(data: Data) -> List[Claim]:
    if '9' not in data.figures:
        return []
    slopes = data.grid.slopes
    ar = {g: np.array([data.ar(slope=s, gap=g) for s in slopes]) for g in GAPS_MM}
    drop = {g: _drop(ar[g]) for g in GAPS_MM}
    low = [s for s in slopes if s <= 30]
    lower_30 = all(data.ar(slope=s, gap=40.0) < min(data.ar(slope=s, gap=45.0),
                                                    data.ar(slope=s, gap=50.0)) for s in low)
    worst = {g: ar[g].min() for g in GAPS_MM}
    mean = {g: ar[g].mean() for g in GAPS_MM}
    squeeze = ("The squeeze at each gap follows from the robot's height 2 (A + r) = 57 mm, "
               'inferred (the paper\'s "3.7 cm" amplitude cannot fit its gaps; r is not given): '
               'a taller or softer-squeezed robot would shift all three curves.')
    return [
        Claim('G1', 'Sec. 5.1, Fig. 9', 'at 50 mm the level AR approaches 1', 'about 1',
              _f(ar[50.0][0]), '>= 0.9', ar[50.0][0] >= 0.9,
              why='Our level AR rises with the gap (G2) but reaches ' + _f(ar[50.0][0])
              + ' at 50 mm, where the tips are still squeezed 3.5 mm per side. '
              + squeeze + " We have not isolated what sets the remaining level loss; the paper's "
              'Sec. 5.3 attributes such losses to contacts moving at different speeds.'),
        Claim('G2', 'Sec. 5.1, Fig. 9', 'a larger gap gives a higher level AR', '50 > 45 > 40',
              ' > '.join(_f(ar[g][0]) for g in (50.0, 45.0, 40.0)), 'ordering',
              ar[50.0][0] > ar[45.0][0] > ar[40.0][0]),
        Claim('G3', 'Sec. 5.1, Fig. 9', 'at 50 mm AR falls strongly with slope (the largest '
              '0-90 deg drop of the three gaps)', 'largest drop',
              'drops ' + ', '.join(f'{g:.0f} mm {_f(drop[g])}' for g in GAPS_MM),
              'ordering', drop[50.0] > max(drop[45.0], drop[40.0])),
        Claim('G4', 'Sec. 5.1, Fig. 9', 'at 40 mm AR hardly changes with slope', 'small drop',
              f'drop {_f(drop[40.0])} ({100 * drop[40.0] / ar[40.0][0]:.1f} %)',
              f'<= {100 * MARGINAL_DROP:.1f} % of level AR, the smallest drop',
              drop[40.0] / ar[40.0][0] <= MARGINAL_DROP and drop[40.0] == min(drop.values())),
        Claim('G5', 'Sec. 5.1, Fig. 9', 'at 40 mm AR is lower than at 45 and 50 mm up to about '
              '30 deg', 'lower at 0-30 deg',
              'lower at ' + ', '.join(f'{s:.0f}' for s in low if data.ar(slope=s, gap=40.0)
                                      < min(data.ar(slope=s, gap=45.0),
                                            data.ar(slope=s, gap=50.0))) + ' deg',
              'ordering at every slope <= 30 deg', lower_30),
        Claim('G6', 'Sec. 5.1, Fig. 9', 'a smaller gap climbs better at large angles (40 mm above '
              '50 mm at 90 deg)', '40 mm > 50 mm at steep slopes',
              f'40 mm {_f(ar[40.0][-1])}, 50 mm {_f(ar[50.0][-1])} at 90 deg', 'ordering',
              ar[40.0][-1] > ar[50.0][-1],
              why='In our model the 40 mm curve stays below the 50 mm one at every slope: the '
              'tighter squeeze costs more on the level than it gains on the climb, though the '
              '50 mm curve loses most with slope (G3) and the curves converge at 75-90 deg. '
              + squeeze),
        Claim('G7', 'Sec. 5.1, Fig. 9', '45 mm is the best compromise (read as: the highest '
              'worst-case AR over 0-90 deg)', '45 mm',
              'worst case ' + ', '.join(f'{g:.0f} mm {_f(worst[g])}' for g in GAPS_MM)
              + '; mean ' + ', '.join(f'{g:.0f} mm {_f(mean[g])}' for g in GAPS_MM),
              'ordering', worst[45.0] > max(worst[40.0], worst[50.0]),
              note='by the mean over slopes 50 mm is marginally ahead'),
    ]


def stiffness_claims(data: Data) -> List[Claim]:
    if '10' not in data.figures:
        return []
    ks = np.array(data.grid.stiffness)
    ar = {s: np.array([data.ar(slope=s, kt=k) for k in ks]) for s in FIG10_SLOPES}
    inclined = [s for s in FIG10_SLOPES if s > 0]

    def rises(s):
        a = ar[s]
        return a[-1] - a[0] > 0.01 and np.all(np.diff(a) > -0.005)

    def gain(s, lo, hi):
        sel = (ks >= lo) & (ks <= hi)
        return (ar[s][sel][-1] - ar[s][sel][0]) / (ks[sel][-1] - ks[sel][0])

    spread = np.array([max(ar[s][i] for s in FIG10_SLOPES) - min(ar[s][i] for s in FIG10_SLOPES)
                       for i in range(len(ks))])
    return [
        Claim('K1', 'Sec. 5.2, Fig. 10', 'AR rises with stiffness (100-1000 N/m) at 30, 60 and '
              '90 deg', 'rises', ', '.join(f'{s:.0f} deg {_f(ar[s][0])} -> {_f(ar[s][-1])}'
                                           for s in inclined),
              'rise > 0.01, no fall > 0.005 between grid points', all(rises(s) for s in inclined)),
        Claim('K2', 'Sec. 5.2, Fig. 10', 'AR rises with stiffness on the level too', 'rises',
              f'0 deg {_f(ar[0.0][0])} -> {_f(ar[0.0][-1])}',
              'rise > 0.01, no fall > 0.005', rises(0.0),
              why='Our level AR does not depend on the tangential stiffness (within 0.005): '
              "with no slope and no tether the mean thrust needed is zero, the tips' shear "
              'springs only trade forces between one another and the robot never leans on the '
              "surface's compliance. The paper's text does not single out the level "
              "curve, and its figure's values are not in the text we have; any level rise "
              'there must come from details of its contact implementation that it does not '
              'give (e.g. how its anchors are reset).'),
        Claim('K3', 'Sec. 5.2, Fig. 10', 'strong effect below 600 N/m, weak above (30, 60, 90 '
              'deg)', 'steeper below 600 N/m',
              ', '.join(f'{s:.0f} deg {1000 * gain(s, 100, 600):.2f} vs '
                        f'{1000 * gain(s, 600, 1000):.2f} per 1000 N/m' for s in inclined),
              'ordering', all(gain(s, 100, 600) > gain(s, 600, 1000) for s in inclined)),
        Claim('K4', 'Sec. 5.2, Fig. 10', 'the spread between slopes 0-90 deg shrinks as the '
              'surface stiffens', 'shrinks',
              f'{_f(spread[0])} at {ks[0]:.0f} N/m -> {_f(spread[-1])} at {ks[-1]:.0f} N/m',
              'spread at 1000 < at 100 and non-increasing (+0.005)',
              spread[-1] < spread[0] and bool(np.all(np.diff(spread) < 0.005))),
        Claim('K5', 'Sec. 8, Fig. 20', 'below 300 N/m the wave still climbs 90 deg',
              'advances', ', '.join(f'{k:.0f} N/m {_f(a)}' for k, a in zip(ks, ar[90.0])
                                    if k < 300), 'AR > 0 at every k < 300 N/m',
              all(a > 0 for k, a in zip(ks, ar[90.0]) if k < 300)),
    ]


def cof_claims(data: Data) -> List[Claim]:
    if '11' not in data.figures:
        return []
    slopes = data.grid.slopes
    ar = {mu: np.array([data.ar(slope=s, mu=mu) for s in slopes]) for mu in COFS}
    rel = {mu: _drop(ar[mu]) / ar[mu][0] for mu in COFS}
    mean = {mu: ar[mu].mean() for mu in COFS}
    return [
        Claim('F1', 'Sec. 5.3, Fig. 11', 'on the level a lower COF is slightly better',
              '0.2 >= 0.5 >= 1.0, slightly', ' >= '.join(_f(ar[mu][0]) for mu in COFS),
              'ordering, spread < 0.05', ar[0.2][0] >= ar[0.5][0] >= ar[1.0][0]
              and ar[0.2][0] - ar[1.0][0] < 0.05),
        Claim('F2', 'Sec. 5.3, Fig. 11', 'COF 0.2 degrades badly with slope',
              'large drop', f'drop {100 * rel[0.2]:.1f} % ({_f(ar[0.2][0])} -> '
              f'{_f(ar[0.2][-1])})', f'> {100 * MARGINAL_DROP:.1f} % and the largest',
              rel[0.2] > MARGINAL_DROP and rel[0.2] == max(rel.values()),
              note='our COF 0.2 robot still climbs 90 deg at AR ' + _f(ar[0.2][-1])),
        Claim('F3', 'Sec. 5.3, Fig. 11', 'COF 0.5 and 1.0 hardly depend on slope', 'small drop',
              f'drops {100 * rel[0.5]:.1f} % and {100 * rel[1.0]:.1f} %',
              f'<= {100 * MARGINAL_DROP:.1f} %', rel[0.5] <= MARGINAL_DROP
              and rel[1.0] <= MARGINAL_DROP),
        Claim('F4', 'Sec. 5.3, Fig. 11', 'COF 0.5 is the best overall (read as: highest mean AR '
              'over 0-90 deg)', '0.5', 'mean ' + ', '.join(f'{mu:g}: {_f(mean[mu])}'
                                                           for mu in COFS),
              'ordering', mean[0.5] > max(mean[0.2], mean[1.0]),
              why='In our model COF 0.5 and 1.0 are within about 0.01 of each other at every '
              'slope: 0.5 is ahead on shallow slopes, 1.0 on steep ones, and the means differ '
              'by less than the 1 % our AR sweeps resolve. Which one wins depends on the share '
              'of tips that slip, which is set by the normal forces (the squeeze, kn and the '
              'robot height the paper does not give) more than by mu once mu >= 0.5.'),
    ]


def worm_claims(data: Data) -> List[Claim]:
    out = []
    lvl = sweeps.worm_ar(0.0, FIG21_KT, 1.0)
    vert = sweeps.worm_ar(90.0, FIG21_KT, 1.0)
    cal = (f'calibrated: mu F_m = {worm_model.CALIBRATED_MOVING_FRICTION:.2f} N and the Figure 21 '
           f'stiffness {FIG21_KT:.0f} N/m are solved from these two numbers (worm.py)')
    out.append(Claim('W1', 'Sec. 8, Fig. 21', 'worm AR on the level, COF 1', '0.40',
                     _f(lvl.advance_ratio), '+-10 % rel.',
                     _rel(lvl.advance_ratio, 0.40) <= AR_REL_TOL, note=cal))
    out.append(Claim('W2', 'Sec. 8, Fig. 21', 'worm AR climbing vertically, COF 1', '0.29',
                     _f(vert.advance_ratio), '+-10 % rel.',
                     _rel(vert.advance_ratio, 0.29) <= AR_REL_TOL, note=cal))
    k0 = worm_model.zero_advance_stiffness(sweeps.scenario_of(sweeps.point(0.0)))
    k0_cl = _contact_law_zero_stiffness()
    out.append(Claim('W3', 'Sec. 7-8, Fig. 20', 'below about 300 N/m the worm does not advance, '
                     'even on the level', 'about 300 N/m', f'{k0:.0f} N/m (contact-law worm: '
                     f'{k0_cl:.0f} N/m)', '250-350 N/m', 250 <= k0 <= 350,
                     note='a prediction of the calibrated closed form, not an input'))
    mus = (0.2, 0.5, 1.0, 1.5)
    ars = [sweeps.worm_ar(0.0, DEFAULT_KT, mu).advance_ratio for mu in mus]
    out.append(Claim('W4', 'Sec. 7, Fig. 21', 'worm AR falls as the COF rises', 'falls',
                     ', '.join(f'{mu:g}: {_f(a)}' for mu, a in zip(mus, ars))
                     + f' (level, {DEFAULT_KT:.0f} N/m)', 'strictly falling',
                     bool(np.all(np.diff(ars) < 0))))
    if '20' in data.figures:
        ks = data.grid.stiffness
        beats, narrows, worst = True, True, []
        for s in FIG10_SLOPES:
            margin = np.array([data.ar(slope=s, kt=k) - sweeps.worm_ar(s, k, 1.0).advance_ratio
                               for k in ks])
            beats &= bool(np.all(margin > 0))
            narrows &= bool(margin[-1] == margin.min())
            worst.append(f'{s:.0f} deg min {_f(margin.min())}, at {ks[-1]:.0f} N/m '
                         f'{_f(margin[-1])}')
        out.append(Claim('W5', 'Sec. 7, Fig. 20', 'the wave beats the worm at every stiffness '
                         '100-1000 N/m for 0, 30, 60, 90 deg (COF 1)', 'wave > worm',
                         'margin ' + '; '.join(worst), 'wave AR > worm AR at every point',
                         beats))
        out.append(Claim('W6', 'Sec. 7, Fig. 20', "the wave's advantage narrows as the surface "
                         'stiffens', 'narrows', 'the margin is smallest at the stiffest point'
                         + (' for every slope' if narrows else ' not for every slope'),
                         'smallest margin at 1000 N/m', narrows))
    if '21' in data.figures:
        slopes = data.grid.slopes
        res = {}
        for mu in COFS:
            res[mu] = [data.ar(slope=s, kt=FIG21_KT, mu=mu)
                       - sweeps.worm_ar(s, FIG21_KT, mu).advance_ratio for s in slopes]
        txt = lambda mu: f'wave - worm {_f(min(res[mu]))} to {_f(max(res[mu]))}'  # noqa: E731
        out.append(Claim('W7', 'Sec. 7, Fig. 21', 'the worm beats the wave at COF 0.2 (0-90 deg)',
                         'worm > wave', txt(0.2) + f' (at {FIG21_KT:.0f} N/m)',
                         'worm AR > wave AR at every slope', max(res[0.2]) < 0))
        out.append(Claim('W8', 'Sec. 7, Fig. 21', 'the wave beats the worm at COF 0.5 and 1.0 '
                         '(0-90 deg)', 'wave > worm', f'COF 0.5: {txt(0.5)}; COF 1.0: '
                         f'{txt(1.0)} (at {FIG21_KT:.0f} N/m)', 'wave AR > worm AR at every slope',
                         min(res[0.5]) > 0 and min(res[1.0]) > 0,
                         why='At COF 0.5 the reconstructed worm (P = mu F_m + m g sin a) keeps '
                         'most of its stroke, and our wave does not beat it at every slope. The '
                         "worm's friction term mu F_m is calibrated at COF 1 only; the paper's "
                         "reference [24] may scale the moving cell's drag with mu differently."))
    return out


@functools.lru_cache(maxsize=1)
def _contact_law_zero_stiffness() -> float:
    """Smallest stiffness (10 N/m resolution) at which the contact-law worm advances, level."""
    ks = np.arange(100.0, 2001.0, 10.0)
    res = worm_model.contact_law([sweeps.scenario_of(sweeps.point(0.0, kt=k)) for k in ks])
    moving = [k for k, r in zip(ks, res) if r.advance_ratio > 0]
    return float(moving[0]) if moving else float('nan')


def evaluate(data: Data) -> List[Claim]:
    claims = []
    if '4' in data.figures:
        claims += statics_claims()
    claims += convergence_claims(data)
    claims += ar_claims(data)
    claims += gap_claims(data)
    claims += stiffness_claims(data)
    claims += cof_claims(data)
    if {'20', '21'} & set(data.figures):
        claims += worm_claims(data)
    return claims
