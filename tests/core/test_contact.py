"""The contact law one term at a time, on a single tip driven by hand (Eqs. 6-8)."""
import numpy as np
import pytest

from saw_ros.core.contact import contact_step, ContactLaw, ContactState, hysteresis_factor

KN, KT, MU, E, V0, DT = 15500.0, 1082.0, 0.8, 0.9, 0.01, 1e-3


def drive(penetrations, xs, e=E):
    law = ContactLaw.from_values(KN, KT, MU, 1.5, e, V0, DT)
    state = ContactState(1, 1)
    out = []
    for d, x in zip(penetrations, xs):
        fn, ft = contact_step(state, np.array([[d]]), np.array([[x]]), law)
        out.append((fn[0, 0], ft[0, 0], bool(state.slipping[0, 0])))
    return np.array(out)


def test_stick_then_slip_at_exactly_mu_fn():
    n = 400
    depth = 0.005
    # Touch, then hold the depth and drag the tip forward at 50 mm/s (faster than v0).
    xs = np.concatenate([[0.0], 0.05 * DT * np.arange(1, n)])
    out = drive(np.full(n, depth), xs)
    fn, ft, slipping = out[1:, 0], out[1:, 1], out[1:, 2].astype(bool)
    expected_fn = KN * depth ** 1.5 * (1 + E) / 2     # constant depth: rate 0, factor (1+e)/2
    np.testing.assert_allclose(fn, expected_fn)
    cap = MU * expected_fn
    spring = KT * xs[1:]
    stick = spring < cap
    assert stick[0] and not stick[-1]
    # While sticking the spring pulls back with kt x (the stretch grows: loading branch)...
    np.testing.assert_allclose(ft[stick], -spring[stick], rtol=1e-12)
    assert not slipping[stick].any()
    # ...then the tip slips with exactly mu Fn and the anchor follows it.
    np.testing.assert_allclose(ft[~stick], -cap, rtol=1e-12)
    assert slipping[~stick].all()


def test_first_touch_anchors_the_spring_and_losing_contact_forgets_it():
    out = drive([0.004, 0.004, -0.001, 0.004, 0.004], [0.0, 0.001, 0.002, 0.010, 0.0105])
    assert out[0, 1] == 0.0                    # anchored where it touched
    assert out[1, 1] == pytest.approx(-KT * 0.001)
    assert out[2, 0] == 0.0 and out[2, 1] == 0.0
    assert out[3, 1] == 0.0                    # re-anchored at x = 0.010
    assert out[4, 1] == pytest.approx(-KT * 0.0005)


def test_loading_unloading_cycle_returns_e_of_the_energy():
    rate = 0.05                                # m/s, well above v0
    up = np.arange(1, 121) * rate * DT        # to 6 mm
    path = np.concatenate([up, up[::-1][1:], [0.0]])
    fn = drive(path, np.zeros_like(path))[:, 0]
    d = np.concatenate([[0.0], path])
    work = 0.5 * (fn + np.concatenate([[0.0], fn[:-1]])) * np.diff(d)   # trapezoid, J
    stored = work[work > 0].sum()
    returned = -work[work < 0].sum()
    assert stored == pytest.approx(KN * 0.006 ** 2.5 / 2.5, rel=0.02)
    assert returned / stored == pytest.approx(E, abs=0.01)


def test_slow_deformation_is_a_smooth_damper_not_a_switch():
    rates = np.array([-1.0, -V0, -V0 / 2, 0.0, V0 / 2, V0, 1.0])
    factor = hysteresis_factor(rates, E, V0)
    np.testing.assert_allclose(factor, [E, E, (3 * E + 1) / 4, (1 + E) / 2, (E + 3) / 4, 1, 1])


def test_a_spring_with_no_stiffness_left_keeps_its_anchor():
    """
    Restitution e -> 0 (5e-324: 1 - e rounds to 1) leaves an unloading shear spring no gain.

    Ft is then 0 and Ft / gain is 0 / 0; the tip sticks with its anchor where it was, so when
    the stretch grows again the spring pulls from that anchor (kt times the stretch, loading).
    """
    # Touch at x = 0, stretch to 1 mm, relax to 0.5 mm fast (gain 0), stretch again.
    xs = [0.0, 0.001, 0.0005, 0.0006]
    out = drive(np.full(len(xs), 0.004), xs, e=5e-324)
    assert np.isfinite(out[:, :2]).all()
    assert out[2, 1] == 0.0                            # unloading: no stiffness, no force
    assert out[3, 1] == pytest.approx(-KT * 0.0006)    # loading again, from the old anchor
