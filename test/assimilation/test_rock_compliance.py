"""
The rock under the bit as a spring (``bit_rock.contact_stiffness_n_per_m``).

On a rigid rock the bit that lands is stopped within one time step: the landing's WOB is its
momentum over dt and grows without bound as the step is refined (measured: 4.2, 5.8, 6.6 MN at
5, 2.5, 1.25 ms). With the rock a spring k the landing is a spring-mass impact that lasts many
steps: its peak converges with the step. Steady drilling does not touch the spring's branch of
the law's graph: the paper's point is the rigid rock's to the last digit, the bit pressing the
rock by WOB / k (docs/MODEL-CHOICES.md, "The bit on and off bottom, and a bit equation that
cannot fail", row "Landing"; docs/ENVELOPE.md, "Landings").
"""
from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from drill_twin.config import load_config
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig

CHEAP = ['initial_conditions.steady_twist=true', 'initial_conditions.lateral_deflection_m=0',
         'reduced_basis.lateral_modes=2', 'physics.contact=false',
         'physics.finite_strain=false', 'physics.kinetic_coupling=false']


def _collar_impedance(config) -> float:
    """Z = A sqrt(E rho) of the bottom section, the drill collars (N s/m)."""
    collar = config.sections[-1]
    area = np.pi / 4 * (collar.outer_diameter_m ** 2 - collar.inner_diameter_m ** 2)
    return area * np.sqrt(collar.young_modulus_pa * collar.density_kg_per_m3)


def _landing_peak(stiffness: str, dt: float, landing_speeds: list | None = None):
    """
    Largest WOB (N) and lift-offs after the hook load is raised by 200 kN at once.

    The string drills at 5.2 rad/s with 250 kN on the bit; with 50 kN left it springs up, the
    bit lifts off and lands again. ``landing_speeds`` collects the bit's axial speed (m/s) on
    the step before each landing.
    """
    config = load_config(None, CHEAP + [f'integration.time_step_s={dt}',
                                        f'bit_rock.contact_stiffness_n_per_m={stiffness}'])
    with threadpool_limits(limits=1, user_api='blas'):
        simulator = Simulator(config)
        rig = Rig(simulator)
        weight = rig.hook_load_command_n - config.bit_rock.static_weight_on_bit_n
        rig.set_top_drive_speed(5.2)
        rig.set_hook_load(weight - 250e3)
        for _ in range(int(round(10.0 / dt))):
            rig.step()
        rig.set_hook_load(weight - 50e3)
        largest, before = 0.0, simulator.observe(detailed=0)
        for _ in range(int(round(4.0 / dt))):
            rig.step()
            largest = max(largest, -float(simulator.last.weight_on_bit_n[0]))
            now = simulator.observe(detailed=0)
            if landing_speeds is not None and now.on_bottom[0] and not before.on_bottom[0]:
                landing_speeds.append(float(before.bit_axial_velocity_m_per_s[0]))
            before = now
    return largest, int(simulator.lift_off_count[0])


def test_a_landing_on_the_rock_spring_converges_with_the_time_step():
    """
    The landing's peak WOB is the model's, not the step's.

    Compliant rock (1e8 N/m): 0.747 and 0.764 MN at 5 and 2.5 ms (measured; 0.770 at 1.25 ms),
    a bit landing at 0.375 m/s on a spring carrying an apparent mass of about 42 t
    (v sqrt(k m)); the BHA's wave impedance would give Z v = 0.56 MN. Rigid rock: the peak grows
    by 39 % when the step is halved.
    """
    speeds = []
    coarse, lifts = _landing_peak('1.0e8', 0.005, speeds)
    fine, _ = _landing_peak('1.0e8', 0.0025)
    assert lifts >= 2                                     # it does bounce
    assert 0.5e6 < coarse < 1.0e6
    # Against the continuum: a rod landing at v on a stiffer rock carries Z v; the spring on
    # the reduced model's apparent mass gives the same order, not the one-step stop's 10 Z v.
    wave = _collar_impedance(load_config(None, CHEAP)) * max(speeds)
    assert wave < coarse < 2.0 * wave
    assert abs(coarse - fine) < 0.05 * fine
    rigid_coarse, _ = _landing_peak('null', 0.005)
    rigid_fine, _ = _landing_peak('null', 0.0025)
    assert rigid_coarse > 3 * coarse and rigid_fine > 1.25 * rigid_coarse


def test_the_paper_point_is_the_rigid_rocks_with_the_bit_pressing_the_rock():
    """
    At the paper's point (stick-slip, WOB within 0.3 % of 100 kN) the spring never acts.

    Bit speed, WOB and TOB equal the rigid rock's to 1e-12 relative over 20 s; the bit is
    WOB / k below the hole's bottom (1.0 mm) instead of on it.
    """
    runs = {}
    for stiffness in ('null', '1.0e8'):
        config = load_config(None, ['integration.time_step_s=0.005',
                                    f'bit_rock.contact_stiffness_n_per_m={stiffness}'])
        with threadpool_limits(limits=1, user_api='blas'):
            simulator = Simulator(config)
            rows = []
            for _ in range(4000):
                simulator.step()
                o = simulator.observe(detailed=0)
                rows.append((o.speed_rad_per_s[0], o.weight_on_bit_n[0], o.torque_on_bit_nm[0],
                             o.bit_depth_m[0], o.hole_depth_m[0]))
        runs[stiffness] = np.array(rows)
    rigid, compliant = runs['null'], runs['1.0e8']
    assert np.ptp(rigid[:, 0]) > 2.0                      # the bit's speed does stick-slip
    np.testing.assert_allclose(compliant[:, :4], rigid[:, :4], rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(rigid[:, 3], rigid[:, 4])       # on a rigid rock: on it
    pressed = compliant[:, 3] - compliant[:, 4]
    np.testing.assert_allclose(pressed, -compliant[:, 1] / 1.0e8, atol=1e-9)
    assert pressed.mean() == pytest.approx(1.0e-3, rel=0.01)


@pytest.mark.parametrize('stiffness', ['1.0e8', 'null'])
def test_the_rock_never_drives_the_bit(stiffness):
    """
    The rock's torque opposes the bit's rotation at every step: T omega <= 0.

    The hook load jumps to the string's weight for 40 ms and then 300 kN below it, as the
    envelope sweep's driller did: on the spring the bit rises for a few steps while it still
    presses the rock. Eq. 26 read at that negative ROP gives t = -Z (a4 ROP / root + a5) > 0,
    a rock that drives the bit (+3 kN m here, +2.2 MN m at a member's rebound in the sweep);
    there the bit does not cut and the law's graph is its resting branch. Also through
    bounces off the bottom (the weight + 50 kN, then 250 kN below it).
    """
    config = load_config(None, CHEAP + ['integration.time_step_s=0.005',
                                        f'bit_rock.contact_stiffness_n_per_m={stiffness}'])
    with threadpool_limits(limits=1, user_api='blas'):
        simulator = Simulator(config)
        rig = Rig(simulator)
        weight = rig.hook_load_command_n - config.bit_rock.static_weight_on_bit_n
        power, pressing = [], 0
        for seconds, hook in ((1.0, None), (0.04, weight), (2.0, weight - 3e5),
                              (1.0, weight + 5e4), (3.0, weight - 2.5e5)):
            if hook is not None:
                rig.set_hook_load(hook)
            for _ in range(int(round(seconds / simulator.dt))):
                rig.step()
                last = simulator.last
                power.append(float(last.torque_on_bit_nm[0] * last.bit_speed_rad_per_s[0]))
                pressing += int(last.weight_on_bit_n[0] < 0 and last.rop_m_per_s[0] < 0)
    if stiffness != 'null':
        assert pressing > 0                 # the case: the bit rising while it presses
    assert max(power) <= 0.0


@pytest.mark.parametrize('germ', [None, [[1.05, 0.02], [0.02, 0.95]]])
def test_an_evaluated_state_of_a_rising_bit_has_the_resting_torque(germ):
    """
    A state whose bit rises on bottom (ROP -1.5 mm/s) evaluates to a torque opposing the spin.

    The state evaluation (after a reset or an analysis: what is published until the next
    step) reads the law at the state's velocities; at that ROP Eq. 25 still presses (about
    -17 kN) and Eq. 26 gives t = -Z (a4 ROP / root + a5), about +1 kN m at 5.2 rad/s: the
    rock would drive the bit. It is the resting branch's torque at the force the rock bears
    instead, as in the step's solve (for the mean law the closed form torque_of_force).
    """
    config = load_config(None, CHEAP + ['integration.time_step_s=0.005'])
    with threadpool_limits(limits=1, user_api='blas'):
        germs = None if germ is None else np.array([germ], dtype=float)
        simulator = Simulator(config, germs=germs)
        for _ in range(40):
            simulator.step()
        integrator = simulator.integrator
        state = simulator.state.copy()
        row = integrator.bit_axial_row
        state.q_rate[0] += (-1.5e-3 - state.q_rate[0] @ row) * row / (row @ row)
        evaluation = integrator.evaluate(state)
    rop, omega = evaluation.rop_m_per_s[0], evaluation.bit_speed_rad_per_s[0]
    force, torque = evaluation.weight_on_bit_n[0], evaluation.torque_on_bit_nm[0]
    assert rop == pytest.approx(-1.5e-3, rel=1e-9) and omega > 1.0 and force < -1e4
    law = simulator.law
    assert law.forces(np.array([rop]), np.array([omega]), germs)[1][0] > 500.0  # Eq. 26's
    if germ is None:
        assert torque == pytest.approx(law.torque_of_force(force, omega), rel=1e-12)
    assert torque == pytest.approx(law.bearing_torque(np.array([force]), np.array([omega]),
                                                      germs)[0], rel=1e-12)
    assert torque * omega <= 0.0


def test_a_stepped_state_evaluates_to_the_steps_own_bit_force_and_torque():
    """
    What the rock bears is in the state: its evaluation is the step's bit force and torque.

    Eight members of germs at delta 0.2 stepped 2 s: some cut, some rest on the rock's spring
    (moving faster than their law cuts at that force: the law at their velocities gives more
    than twice the force). The state evaluation, which an analysis's write-back and a reset
    use for the accelerations, has the step's WOB and TOB on both branches (the law read at
    the velocities would give 252 against 99 kN on the paper's string; docs/MODEL-CHOICES.md,
    row "Landing"), so writing a state back unchanged leaves its accelerations and its drilling
    as they were.
    """
    from drill_twin.assimilation.state import MemberState
    from drill_twin.uncertainty.germ import germs_for_realizations
    config = load_config(None, CHEAP)
    with threadpool_limits(limits=1, user_api='blas'):
        simulator = Simulator(config, 8, germs=germs_for_realizations(0.2, 0, range(8)))
        for _ in range(int(round(2.0 / simulator.dt))):
            simulator.step()
        integrator, state = simulator.integrator, simulator.state
        assert np.all(simulator.on_bottom())
        at_velocities = integrator.evaluate(state, bearing=False).weight_on_bit_n
        evaluation = integrator.evaluate(state)
        step = simulator.last
        resting = np.abs(at_velocities / step.weight_on_bit_n - 1.0) > 0.1
        assert 0 < resting.sum() < 8                       # both branches are in the batch
        np.testing.assert_allclose(evaluation.weight_on_bit_n, step.weight_on_bit_n, rtol=1e-9)
        np.testing.assert_allclose(evaluation.torque_on_bit_nm, step.torque_on_bit_nm,
                                   rtol=1e-9)
        accelerations, hole = state.q_acceleration.copy(), simulator.hole_u().copy()
        members = MemberState(simulator, 8, ['axial', 'torsional'])
        members.write(members.extract())
        largest = np.abs(accelerations).max()
        np.testing.assert_allclose(simulator.state.q_acceleration, accelerations, rtol=0,
                                   atol=1e-9 * largest)
        np.testing.assert_array_equal(simulator.hole_u(), hole)
