"""The reconstructed worm (saw_ros/core/worm.py): closed form and contact-law version."""
import math

import pytest

from saw_ros.core import Scenario
from saw_ros.core import worm as W


def scen(kt=1082.0, mu=1.0, slope_deg=0.0):
    return Scenario().with_values({'surface.tangential_stiffness': kt,
                                   'surface.friction_coefficient': mu,
                                   'conditions.slope': math.radians(slope_deg)})


def test_calibration_reproduces_the_papers_worm_numbers():
    # docs/worm-model.md: fitting 0.40 (0 deg) and 0.29 (90 deg) at COF 1 gives k ~ 532 N/m and
    # mu F_m ~ 16.8 N; those are the calibrated constants, so the numbers come back exactly.
    assert W.FIGURE21_STIFFNESS == pytest.approx(532, abs=1)
    assert W.CALIBRATED_MOVING_FRICTION == pytest.approx(16.8, abs=0.1)
    k = W.FIGURE21_STIFFNESS
    assert W.closed_form(scen(k, 1.0, 0)).advance_ratio == pytest.approx(0.40, abs=1e-9)
    assert W.closed_form(scen(k, 1.0, 90)).advance_ratio == pytest.approx(0.29, abs=1e-9)


def test_no_advance_below_about_300_n_per_m_on_the_level():
    k0 = W.zero_advance_stiffness(scen())
    assert 300 <= k0 <= 340                       # the model predicts 319 N/m
    for kt in (100, 200, 300, 315):
        assert W.closed_form(scen(kt)).advance_ratio == 0.0
    assert W.closed_form(scen(350)).advance_ratio > 0.0
    for r in W.contact_law([scen(kt) for kt in (100, 200, 300)]):
        assert r.advance_ratio == 0.0


@pytest.mark.parametrize('model', ['closed', 'contact'])
def test_ar_falls_as_cof_rises(model):
    mus = (0.2, 0.5, 1.0, 1.5)
    if model == 'closed':
        ars = [W.closed_form(scen(1082, mu)).advance_ratio for mu in mus]
    else:
        ars = [r.advance_ratio for r in W.contact_law([scen(1082, mu) for mu in mus])]
    assert all(a > b for a, b in zip(ars, ars[1:])), ars


def test_slipping_anchors_give_no_progress():
    weak = W.WormParams(anchor_normal_force=1.0)    # mu (N-1) F_a = 3 N < P = 16.75 N
    r = W.closed_form(scen(), weak)
    assert r.anchors_slip and r.advance_ratio == 0.0
    r = W.contact_law(scen(), weak)[0]
    assert r.anchors_slip and r.advance_ratio == 0.0
    # and slipping on a vertical climb: the weight alone exceeds the anchors' grip
    r = W.contact_law(scen(slope_deg=90), W.WormParams(anchor_normal_force=0.5,
                                                       moving_normal_force=0.0))[0]
    assert r.anchors_slip and r.advance_ratio == 0.0


def test_contact_law_worm_agrees_with_a_rigid_surface_and_no_load():
    # No friction on the moving cell and no slope: nothing loads the anchors, full stroke.
    free = W.WormParams(moving_normal_force=0.0)
    assert W.contact_law(scen(300), free)[0].advance_ratio == pytest.approx(1.0, abs=1e-6)
    # Very stiff surface: both models approach the full stroke.
    assert W.contact_law(scen(1e6))[0].advance_ratio > 0.99
    assert W.closed_form(scen(1e6)).advance_ratio > 0.99


def test_contact_law_worm_is_converged_in_cycles_and_increments():
    s = [scen(800, 1.0, 0), scen(1082, 0.5, 90)]
    a = [r.advance_ratio for r in W.contact_law(s)]
    b = [r.advance_ratio for r in W.contact_law(s, cycles=6, increments=60)]
    assert a == pytest.approx(b, abs=2e-3)


def test_anchor_force_from_the_gap():
    # A 57 mm cell in a 45 mm gap: 6 mm per side, 15 500 * 0.006^1.5 = 7.2 N per side.
    fa = W.anchor_normal_force(W.WormParams(), scen())
    assert fa == pytest.approx(2 * 7.2 + 0.313 * 9.81 / 4, rel=0.01)
