"""
The mass imbalance of the BHA against Lagrange and the closed form.

The imbalance is checked against Lagrange's equations and the closed-form steady forced whirl
of the linearised, prestressed string.

Closed form (drill_twin/analysis/harmonic.py): an imbalance m e spinning at a constant Omega loads
its node with m e Omega^2 (cos, sin)(Omega t + phi); once the transient has died out the
linear string answers with u = Re(U e^(i Omega t)), (K + K_f + K_g - Omega^2 (M + M_f)
+ i Omega (C + C_f)) U = F, solved on the full finite-element model. The time integration
(reduced basis, Newmark, the force turning with the node's own spin angle) must land on it.
"""
from __future__ import annotations

import numpy as np
import pytest
from conftest import config_with, default_raw
from imbalanced_string import ECCENTRICITY_M, imbalanced_string as _config, MASS_KG, POSITION_M

from drill_twin.config import ConfigError
from drill_twin.model.excitation import ImbalanceForce
from drill_twin.model.forces import Kinematics
from drill_twin.integrator.newmark import NewmarkIntegrator
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import Simulator
from drill_twin.fem import dofs
from drill_twin.analysis.harmonic import forced_whirl
from drill_twin.modal.reduced_basis import modal_analysis

STEP = 1e-30


def test_imbalance_is_off_by_default_and_validated(default_config):
    assert not default_config.excitation.imbalance.enabled
    assert default_config.excitation.imbalance.unbalance_kg_m == 0.0
    with pytest.raises(ConfigError, match='excitation.imbalance.position_m'):
        config_with({'excitation': {'imbalance': {'enabled': True, 'position_m': 1700.0}}})
    with pytest.raises(ConfigError, match='excitation.imbalance.eccentricity_m'):
        config_with({'excitation': {'imbalance': {'eccentricity_m': -0.01}}})


def _eccentric_energy(me, mee, v_rate, w_rate, angle, spin):
    """T_e: the kinetic energy of the eccentric mass minus that of the same mass on the axis."""
    return me * spin * (w_rate * np.cos(angle) - v_rate * np.sin(angle)) + 0.5 * mee * spin ** 2


def test_imbalance_force_follows_from_lagranges_equations():
    """
    Return (F_v, F_w, T_x) = -(d/dt dT_e/dq' - dT_e/dq) for q = (v, w, theta_x) of the node.

    The derivatives are taken numerically from T_e alone (complex step, central differences).
    """
    model, _, basis = modal_analysis(_config())
    system = build_reduced_system(model, basis)
    force = ImbalanceForce.of(system)
    node = force.node
    assert force.depth_m == pytest.approx(POSITION_M)
    me, mee = MASS_KG * ECCENTRICITY_M, MASS_KG * ECCENTRICITY_M ** 2
    rng = np.random.default_rng(7)
    for _ in range(5):
        q0 = rng.normal(size=3) * (0.05, 0.05, 3.0)           # v, w, theta_x at t = 0
        q1 = rng.normal(size=3) * (0.1, 0.1, 2.0) + (0, 0, 5.0)
        q2 = rng.normal(size=3) * (0.3, 0.3, 4.0)
        top_angle = 1.7

        def state(t):
            return q0 + t * q1 + 0.5 * t * t * q2, q1 + t * q2

        def energy(position, velocity):
            return _eccentric_energy(me, mee, velocity[0], velocity[1],
                                     top_angle + position[2], velocity[2])

        expected = []
        h = 1e-4
        for k in range(3):
            unit = np.eye(3)[k]

            def momentum(t):
                p, r = state(t)
                return energy(p, r + 1j * STEP * unit).imag / STEP

            rate_of_momentum = (momentum(h) - momentum(-h)) / (2 * h)
            gradient = energy(q0 + 1j * STEP * unit, q1).imag / STEP
            expected.append(-(rate_of_momentum - gradient))

        n, n_dofs = system.n_nodes, system.n_dofs
        displacement = np.zeros((1, n_dofs))
        displacement[0, system.field(1).start + node] = q0[2]
        displacement[0, system.field(2).start + node] = q0[0]
        displacement[0, system.field(4).start + node] = q0[1]
        rate_x, acc_x = np.zeros((1, n)), np.zeros((1, n))
        rate_x[0, node], acc_x[0, node] = q1[2], q2[2]
        acc_y, acc_z = np.zeros((1, 2 * n)), np.zeros((1, 2 * n))
        acc_y[0, node], acc_z[0, node] = q2[0], q2[1]
        zeros = np.zeros((1, 2 * n))
        fields = Kinematics(displacement=displacement, theta_x_rate=rate_x,
                            theta_x_acceleration=acc_x, bending_y_rate=zeros,
                            bending_y_acceleration=acc_y, bending_z_rate=zeros,
                            bit_axial_rate=np.zeros(1), bending_z_acceleration=acc_z,
                            top_angle_rad=top_angle)
        full = force.force(system, fields)[0]
        got = [full[system.field(2).start + node], full[system.field(4).start + node],
               full[system.field(1).start + node]]
        np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-9 * np.abs(expected).max())
        assert np.count_nonzero(full) == 3                     # only the node's three DOFs


def _steady_orbit(spin_rad_per_s, duration_s, window_s=2.0):
    """
    Run from rest and return the orbit statistics over the last ``window_s``.

    Run from rest (no lateral deflection) and return (mean radius, mean lag, radius
    spread, the model and the node) over the last ``window_s``. The lag is the local spin
    angle of the node minus the angle of its displacement.
    """
    simulator = Simulator(_config(spin_rad_per_s))
    system, force = simulator.system, simulator.forces.imbalance
    steps = int(round(duration_s / simulator.dt))
    radius, lag = [], []
    for k in range(steps):
        simulator.step()
        if k >= steps - int(round(window_s / simulator.dt)):
            u = system.physical(simulator.state.q)[0]
            v = u[system.field(2).start + force.node]
            w = u[system.field(4).start + force.node]
            spin_angle = simulator.state.top_angle_rad + u[system.field(1).start + force.node]
            radius.append(np.hypot(v, w))
            lag.append(np.angle(np.exp(1j * (spin_angle - np.arctan2(w, v)))))
    radius, lag = np.array(radius), np.unwrap(np.array(lag))
    return radius.mean(), lag.mean(), np.ptp(radius), system.model, force


@pytest.fixture(scope='module')
def resonance_rad_per_s():
    """
    Return the lateral mode in 3-6 rad/s that moves the imbalance's node most.

    Found by modal analysis.
    """
    model, modes, _ = modal_analysis(_config())
    node = model.mesh.nearest_node(POSITION_M)
    lateral = np.flatnonzero((modes.kind == 'lateral') & ~modes.rigid)
    omega = 2 * np.pi * modes.frequency_hz[lateral]
    band = lateral[(omega > 3.0) & (omega < 6.0)]
    v_row = dofs.node_dof(node, dofs.V)
    w_row = dofs.node_dof(node, dofs.W)
    weight = modes.shapes[v_row, band] ** 2 + modes.shapes[w_row, band] ** 2
    return float(2 * np.pi * modes.frequency_hz[band[np.argmax(weight)]])


@pytest.mark.parametrize('where', ['below', 'at', 'above'])
def test_steady_forced_whirl_matches_the_harmonic_response(where, resonance_rad_per_s):
    """
    The unbalanced BHA settles on the closed form's orbit across a lateral resonance.

    Started from rest, the unbalanced BHA settles on the closed form's orbit (radius within
    2 %, lag within 0.02 rad) below, at and above a lateral resonance, and the closed form
    peaks there (2.5 times its response 1.5 rad/s below). Damping alpha = 0.5 /s (zeta about
    0.06 at the resonance) lets the transient die out (e^-6) in 26 s.
    """
    spin = {'below': resonance_rad_per_s - 1.5, 'at': resonance_rad_per_s,
            'above': resonance_rad_per_s + 1.5}[where]
    radius, lag, spread, model, force = _steady_orbit(spin, 26.0)
    closed = forced_whirl(model, force.node, force.unbalance_kg_m, spin)
    assert abs(abs(closed.v) - abs(closed.w)) < 1e-9 * closed.radius_m     # a circle
    assert radius == pytest.approx(closed.radius_m, rel=0.02)
    assert spread < 0.02 * radius                                          # steady
    assert np.angle(np.exp(1j * (lag - closed.lag_rad))) == pytest.approx(0.0, abs=0.02)
    peak = forced_whirl(model, force.node, force.unbalance_kg_m, resonance_rad_per_s)
    below = forced_whirl(model, force.node, force.unbalance_kg_m, resonance_rad_per_s - 1.5)
    assert peak.radius_m > 2.5 * below.radius_m


def test_the_compiled_step_applies_the_imbalance_at_the_nodes_spin_angle():
    """
    The Newmark step's imbalance forces match Lagrange's forces written out in numpy.

    The Newmark step (compiled) and NonlinearForces.evaluate sum the imbalance in the same
    kernel; the step's wiring (the top-drive angle at the end of the step, the node's w''
    computed in the step) is checked against Lagrange's forces written out in numpy. A step
    limited to one iteration returns the forces of its first iterate, whose kinematics are
    known: d = q + dt q' + dt^2 a / 2, v = q' + dt a, a the last accelerations, with the new
    top speed, acceleration and angle. Only the imbalance acts on the string (f_se, f_ke,
    wall, bit off), so that f_NL is the imbalance's. A stale top angle (it advances by
    0.05 rad per step) or a missing w'' (the reaction torque) fails.
    """
    simulator = Simulator(_config(5.2))
    system, force = simulator.system, simulator.forces.imbalance
    me, mee = force.unbalance_kg_m, force.inertia_kg_m2
    for _ in range(150):
        simulator.step()
    state, dt = simulator.state, simulator.dt
    one_iteration = NewmarkIntegrator(simulator.forces, dt, 1e-6, 1)
    speed = state.top_speed_rad_per_s + 0.05
    after, result = one_iteration.step(state, speed, state.hook_load_n)
    full = result.forces.full[0]
    u = system.physical(state.q + dt * state.q_rate + 0.5 * dt * dt * state.q_acceleration)[0]
    rate = system.physical(state.q_rate + dt * state.q_acceleration)[0]
    acceleration = system.physical(state.q_acceleration)[0]
    x_row, v_row, w_row = force.theta_x_row, force.v_row, force.w_row
    angle = after.top_angle_rad + u[x_row]
    spin = rate[x_row] + speed
    spin_rate = acceleration[x_row] + after.top_acceleration_rad_per_s2
    assert after.top_acceleration_rad_per_s2 == pytest.approx(5.0)
    expected = np.array([
        me * (spin ** 2 * np.cos(angle) + spin_rate * np.sin(angle)),
        me * (spin ** 2 * np.sin(angle) - spin_rate * np.cos(angle)),
        me * (acceleration[v_row] * np.sin(angle) - acceleration[w_row] * np.cos(angle))
        - mee * spin_rate])
    reaction = me * abs(acceleration[w_row] * np.cos(angle))
    assert reaction > 1e-4 * np.abs(expected).max()          # w'' counts at this tolerance
    got = full[[v_row, w_row, x_row]]
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    assert np.all(np.delete(full, [v_row, w_row, x_row]) == 0.0)
    # The end-of-step state through evaluate (the Python path) against the same formula.
    simulator.step()
    state = simulator.state
    u, rate, acceleration = (system.physical(x)[0] for x in (state.q, state.q_rate,
                                                             state.q_acceleration))
    angle = state.top_angle_rad + u[x_row]
    spin = rate[x_row] + state.top_speed_rad_per_s
    spin_rate = acceleration[x_row] + state.top_acceleration_rad_per_s2
    again = simulator.integrator.evaluate(state).full[0]
    np.testing.assert_allclose(
        again[[v_row, w_row]],
        me * np.array([spin ** 2 * np.cos(angle) + spin_rate * np.sin(angle),
                       spin ** 2 * np.sin(angle) - spin_rate * np.cos(angle)]), rtol=1e-9)


def test_the_newton_step_takes_the_imbalances_inertia_whole():
    """
    The imbalance's force, linear in the node's accelerations, is in the Newton matrix.

    Its inertia A on the node's (v, w, theta_x) (20 % of the collars' local polar inertia for
    1000 kg at 5 cm) enters S by the Woodbury identity, so one iteration lands where the
    converged step is, up to the fixed point of its velocity and angle terms: the first
    iterate's accelerations are within 3e-4 of the change over the step (6.7e-5 measured;
    with the inertia left to the fixed point they are 1.7e-3 off, and the paper-length lateral
    profile takes three iterations on 75 % of its steps, against one on 96 % with it). Only
    the imbalance acts (f_se, f_ke, wall and bit off).
    """
    simulator = Simulator(_config(5.2))
    for _ in range(150):
        simulator.step()
    state, dt = simulator.state, simulator.dt
    speed = state.top_speed_rad_per_s + 0.05
    first, _ = NewmarkIntegrator(simulator.forces, dt, 1e-6, 1).step(state, speed,
                                                                     state.hook_load_n)
    converged, result = NewmarkIntegrator(simulator.forces, dt, 1e-13, 60).step(
        state, speed, state.hook_load_n)
    assert result.success and result.iterations <= 3
    change = np.linalg.norm(converged.q_acceleration - state.q_acceleration)
    assert np.linalg.norm(first.q_acceleration - converged.q_acceleration) < 3e-4 * change


def test_without_imbalance_its_operands_are_inert():
    """
    Off, the kernels get an operand tuple of the same types with its switch off.

    No force anywhere, nothing evaluated.
    """
    simulator = Simulator(config_with({'physics': dict(default_raw()['physics'],
                                                       finite_strain=False,
                                                       kinetic_coupling=False)}))
    forces = simulator.forces
    assert forces.imbalance is None and forces.imbalance_arguments[0] is False
    on = ImbalanceForce.arguments_of(Simulator(_config()).forces.imbalance,
                                     simulator.system)
    assert [type(a) for a in on] == [type(a) for a in forces.imbalance_arguments]
