"""Figure 4 of the paper, exactly (closed form, Eqs. 1-5)."""
import math

import numpy as np
import pytest

from saw_ros.core.statics import FIGURE4_CASES, minimal_normal_forces, top_surface_needed_above

CASES = {c.name: c for c in FIGURE4_CASES}


def test_case_a_needs_top_surface_above_21_80_deg_and_2_5_mg_at_vertical():
    a = CASES['A']
    assert math.degrees(top_surface_needed_above(a.external_force, a.mu)) == pytest.approx(
        21.80, abs=0.005)
    bottom, top, total = minimal_normal_forces(math.pi / 2, a.external_force, a.mu)
    assert (bottom, top, total) == pytest.approx((1.25, 1.25, 2.5))


def test_case_b_needs_top_surface_at_every_angle():
    b = CASES['B']
    assert top_surface_needed_above(b.external_force, b.mu) == 0.0
    slopes = np.radians(np.linspace(0, 90, 91))
    _, top, _ = minimal_normal_forces(slopes, b.external_force, b.mu)
    assert np.all(top > 0)
    assert minimal_normal_forces(math.pi / 2, b.external_force, b.mu)[0] == pytest.approx(1.875)


def test_case_c_needs_top_surface_above_15_68_deg():
    c = CASES['C']
    angle = math.degrees(top_surface_needed_above(c.external_force, c.mu))
    assert angle == pytest.approx(15.68, abs=0.005)
    _, top, _ = minimal_normal_forces(np.radians([angle - 0.1, angle + 0.1]), c.external_force,
                                      c.mu)
    assert top[0] < 0 < top[1]


def test_equation_1_balance_bottom_minus_top_is_weight_component():
    slopes = np.radians(np.linspace(-90, 90, 37))
    bottom, top, total = minimal_normal_forces(slopes, 0.3, 0.6)
    np.testing.assert_allclose(bottom - top, np.cos(slopes), atol=1e-12)
    np.testing.assert_allclose(total, (0.3 + np.sin(slopes)) / 0.6)
