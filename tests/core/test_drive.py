"""The drive from outside the model (issue 22): commands, a profile over the turn, the PI."""
import math

import numpy as np
import pytest

from saw_ros.core.drive import PhaseProfile, SpeedPI, VOLTAGE_LIMIT
from saw_ros.core.dynamics import Simulator
from saw_ros.core.params import ParameterError, Scenario

MOTOR = Scenario().with_values({'motor.voltage': 6.0})


def run(sim, steps):
    for _ in range(steps):
        sim.step()
    return sim


def test_a_command_equal_to_the_parameter_changes_nothing_bit_for_bit():
    plain = run(Simulator(MOTOR), 800)
    commanded = Simulator(MOTOR)
    commanded.command_voltage(6.0)
    run(commanded, 800)
    profiled = Simulator(MOTOR)
    profiled.set_profile(PhaseProfile.constant(6.0))
    run(profiled, 800)
    assert np.array_equal(plain.q, commanded.q) and np.array_equal(plain.q, profiled.q)
    assert np.array_equal(plain.omega, profiled.omega)


def test_a_voltage_command_acts_on_the_next_step():
    a, b = run(Simulator(MOTOR), 500), run(Simulator(MOTOR), 500)
    b.command_voltage(12.0)
    a.step()
    b.step()
    assert b.omega[0] > a.omega[0]            # the very next step turns the helix faster
    # The implicit motor step with twice the voltage: the rise is (dV k / R) dt / (J + k^2 dt / R)
    motor = MOTOR.motor
    k, r, j, dt = motor.torque_constant, motor.resistance, motor.inertia, MOTOR.integration.dt
    expected = 6.0 * k / r * dt / (j + k * k * dt / r)
    assert b.omega[0] - a.omega[0] == pytest.approx(expected, rel=1e-9)


def test_clearing_the_command_returns_to_the_parameter():
    sim = run(Simulator(MOTOR), 200)
    sim.command_voltage(3.0)
    assert sim.motor.voltage[0] == 3.0
    sim.command_voltage(None)
    assert sim.motor.voltage[0] == 6.0 and sim.commanded_voltage is None


def test_a_command_survives_a_parameter_change():
    sim = run(Simulator(MOTOR), 100)
    sim.command_voltage(4.0)
    sim.set_scenarios([MOTOR.with_values({'conditions.slope': 0.2})])
    assert sim.motor.voltage[0] == 4.0


@pytest.mark.parametrize('bad', [float('nan'), -0.1, VOLTAGE_LIMIT + 0.1, float('inf')])
def test_bad_voltage_commands_are_refused_and_never_applied(bad):
    sim = Simulator(MOTOR)
    with pytest.raises(ParameterError):
        sim.command_voltage(bad)
    assert sim.motor.voltage[0] == 6.0 and sim.commanded_voltage is None


@pytest.mark.parametrize('edge', [0.0, VOLTAGE_LIMIT])
def test_voltage_commands_at_both_ends_of_the_range_run(edge):
    sim = Simulator(MOTOR)
    sim.command_voltage(edge)
    run(sim, 300)
    assert np.isfinite(sim.q).all()


def test_without_a_motor_the_command_is_a_frequency():
    sim = Simulator(Scenario())
    with pytest.raises(ParameterError, match='frequency'):
        sim.command_voltage(6.0)
    sim.command_frequency(2.0)
    before = sim.phase.copy()
    sim.step()
    assert sim.phase[0] - before[0] == pytest.approx(2.0 * math.pi * 2.0 * sim.dt)
    with pytest.raises(ParameterError):
        sim.command_frequency(-1.0)
    sim.command_frequency(None)
    before = sim.phase.copy()
    sim.step()
    assert sim.phase[0] - before[0] == pytest.approx(2.0 * math.pi * 1.0 * sim.dt)


def test_profile_follows_its_fourier_series_and_clips_at_zero():
    profile = PhaseProfile([6.0, 2.0], [1, 9], [[0.1, 0.0, 0.0, 0.2], [0.0, 0.0, 0.0, -0.9]])
    phase = np.array([0.3, 0.3])
    v = profile.voltage(phase)
    assert v[0] == pytest.approx(6.0 * (1 + 0.1 * math.cos(0.3) + 0.2 * math.sin(9 * 0.3)))
    low = profile.voltage(np.array([math.pi / 18, math.pi / 18]))   # sin(9 phi) = 1
    assert low[1] == pytest.approx(2.0 * 0.1)
    turn = profile.over_turn(720)
    assert turn.min() >= 0.0
    assert turn[0].mean() == pytest.approx(6.0, rel=1e-9)    # harmonics average to nothing
    assert (turn <= profile.peak[:, None] + 1e-12).all()


def test_profile_refuses_bad_input():
    with pytest.raises(ParameterError):
        PhaseProfile([float('nan')], [1], [[0.0, 0.0]])
    with pytest.raises(ParameterError):
        PhaseProfile([6.0], [0], [[0.0, 0.0]])
    with pytest.raises(ParameterError):
        Simulator(Scenario()).set_profile(PhaseProfile.constant(6.0))


def test_pi_holds_a_first_order_plant_at_its_target_without_windup():
    # Plant: speed' = (gain u - speed) / tau; its steady speed at u is gain u.
    gain, tau, dt = 0.01, 0.3, 1.0 / 60.0
    pi = SpeedPI(kp=40.0, ki=60.0, u_min=0.0, u_max=12.0, u_ff=5.0)
    speed = 0.0
    for _ in range(int(30.0 / dt)):
        u = pi.update(0.05, speed, dt)
        speed += (gain * u - speed) / tau * dt
    assert speed == pytest.approx(0.05, rel=1e-3)
    # An unreachable target saturates the output; the integrator holds from then on, so the
    # output leaves the limit as soon as the target comes back within reach.
    held = None
    for _ in range(int(5.0 / dt)):
        u = pi.update(1.0, speed, dt)
        speed += (gain * u - speed) / tau * dt
        if u == 12.0 and held is None:
            held = pi.integral
    assert u == 12.0 and pi.integral == held
    assert pi.update(0.05, speed, dt) < 12.0
