"""
The compiled force kernels against a straightforward numpy implementation.

The numpy implementation of the same formulas, on random batches, is kept here, not in the
package (the package has one implementation). The formulas themselves are checked against the
energies in test_dynamics_forces.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.model.contact import contact_force
from drill_twin.model.finite_strain import finite_strain_force
from drill_twin.model.forces import Kinematics, NonlinearForces
from drill_twin.model.kinetic_coupling import kinetic_coupling_force
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.fem import strain_energy as se


@pytest.fixture(scope='module')
def system(default_analysis):
    model, _, basis = default_analysis
    return build_reduced_system(model, basis)


# -- the numpy reference (the implementation the kernels replaced) -------------------------

def reference_finite_strain(system, u):
    m = u.shape[0]
    both = (system.strain_and_tangent_operator @ u.T).reshape(2, se.N_STRAINS, system.n_gauss, m)
    total = [system.prestress_strain_components[k] + both[0][k] for k in range(se.N_STRAINS)]
    stress = np.array(se.stress_components(total, system.section_columns))
    stress -= system.prestress_stress_components
    stress -= both[1]
    stress *= system.gauss_weight_m[None, :, None]
    return -(system.strain_operator_t @ stress.reshape(-1, m)).T


def reference_kinetic_coupling(system, fields):
    b = system.blocks
    rate_x = fields.theta_x_rate @ system.theta_x_gauss_t
    acc_x = fields.theta_x_acceleration @ system.theta_x_gauss_t
    rate_z = fields.bending_y_rate @ system.theta_z_gauss_t
    acc_z = fields.bending_y_acceleration @ system.theta_z_gauss_t
    theta_y = fields.displacement[:, b['bending_z'].rows] @ system.theta_y_gauss_t
    rate_y = fields.bending_z_rate @ system.theta_y_gauss_t
    scale = system.polar_inertia_density * system.gauss_weight_m
    force = np.zeros_like(fields.displacement)
    force[:, b['torsional'].rows] = (scale * (rate_y * rate_z + theta_y * acc_z)
                                     ) @ system.theta_x_gauss
    force[:, b['bending_z'].rows] = (-scale * rate_x * rate_z) @ system.theta_y_gauss
    force[:, b['bending_y'].rows] = (scale * (acc_x * theta_y + rate_x * rate_y)
                                     ) @ system.theta_z_gauss
    return force


def reference_contact(system, k, mu, eps, fields):
    u = fields.displacement
    v_slice, w_slice = system.field(2), system.field(4)
    v, w = u[:, v_slice], u[:, w_slice]
    radius = np.sqrt(v * v + w * w)
    penetration = radius - system.clearance_m
    touching = penetration > 0.0
    safe = np.where(touching, radius, 1.0)
    magnitude = np.where(touching, k * penetration, 0.0)
    nv, nw = v / safe, w / safe
    force = np.zeros_like(u)
    force[:, v_slice] = -magnitude * nv
    force[:, w_slice] = -magnitude * nw
    spin = fields.theta_x_rate
    force[:, system.field(1)] = (-mu * magnitude * system.node_outer_radius_m
                                 * spin / np.sqrt(spin * spin + eps ** 2))
    ratio = np.where(touching, penetration / safe, 0.0)
    stiffness = np.where(touching, k, 0.0)
    tangent = np.empty(radius.shape + (2, 2))
    tangent[..., 0, 0] = stiffness * (nv * nv + ratio * (1 - nv * nv))
    tangent[..., 1, 1] = stiffness * (nw * nw + ratio * (1 - nw * nw))
    tangent[..., 0, 1] = tangent[..., 1, 0] = stiffness * (1 - ratio) * nv * nw
    return force, magnitude, touching, tangent


# -- random batches ---------------------------------------------------------------------

def _random_fields(system, rng, members, lateral_m):
    """
    Return a batch with large random modal amplitudes, spinning, with random accelerations.

    Laterally deflected by up to ``lateral_m`` (some nodes beyond the clearance).
    """
    n = system.size
    q = rng.normal(size=(members, n)) * rng.uniform(0.5, 20.0, size=(members, 1))
    bending = system.blocks['bending_y'], system.blocks['bending_z']
    for block in bending:
        lateral = q[:, block.columns] @ block.shapes_t[:, :system.n_nodes]
        q[:, block.columns] *= lateral_m / np.abs(lateral).max(axis=1, keepdims=True)
    v = rng.normal(size=(members, n)) * 5.0
    a = rng.normal(size=(members, n)) * 50.0
    return Kinematics.of(system, q, v, a, rng.uniform(-6, 6), rng.normal() * 3)


@pytest.mark.parametrize('members', [1, 3, 16, 37])
def test_kernels_match_the_numpy_reference(system, members):
    rng = np.random.default_rng(members)
    fields = _random_fields(system, rng, members, lateral_m=0.12)
    f_se = finite_strain_force(system, fields.displacement)
    expected = reference_finite_strain(system, fields.displacement)
    assert np.abs(expected).max() > 0
    np.testing.assert_allclose(f_se, expected, rtol=1e-11, atol=1e-12 * np.abs(expected).max())

    f_ke = kinetic_coupling_force(system, fields)
    expected = reference_kinetic_coupling(system, fields)
    assert np.abs(expected).max() > 0
    np.testing.assert_allclose(f_ke, expected, rtol=1e-11, atol=1e-12 * np.abs(expected).max())

    k, mu, eps = 1e8, 0.0005, 0.1
    f_ip, contact, tangent = contact_force(system, k, mu, eps, fields)
    force, magnitude, touching, expected_tangent = reference_contact(system, k, mu, eps, fields)
    assert touching.any() and not touching.all()        # both branches are exercised
    np.testing.assert_array_equal(contact.in_contact, touching)
    np.testing.assert_allclose(contact.radial_force_n, magnitude, rtol=1e-13)
    np.testing.assert_allclose(f_ip, force, rtol=1e-13, atol=1e-13 * np.abs(force).max())
    np.testing.assert_allclose(tangent, expected_tangent, rtol=1e-13, atol=1e-6)


def test_the_assembly_is_the_sum_of_the_kernels_and_reuses_its_work_arrays(system):
    """
    The assembly sums the kernels and the bit law; its results survive the next evaluation.

    NonlinearForces sums the kernels and the bit law, projects on the basis, and its
    results are not overwritten by the next evaluation of the same batch size.
    """
    forces = NonlinearForces(system)
    rng = np.random.default_rng(8)
    first = _random_fields(system, rng, 5, lateral_m=0.12)
    second = _random_fields(system, rng, 5, lateral_m=0.0)
    evaluation = forces.evaluate(first)
    kept = evaluation.full.copy(), evaluation.contact.radial_force_n.copy()
    workspace = forces.workspace(5)
    later = forces.evaluate(second)
    assert forces.workspace(5) is workspace
    assert later.contact_tangent is None and not later.contact.in_contact.any()
    np.testing.assert_array_equal(evaluation.full, kept[0])
    np.testing.assert_array_equal(evaluation.contact.radial_force_n, kept[1])
    wob, tob, _, _ = forces.law.forces_and_jacobian(first.bit_axial_rate,
                                                    first.theta_x_rate[:, system.bit_node])
    expected = (reference_finite_strain(system, first.displacement)
                + reference_kinetic_coupling(system, first)
                + reference_contact(system, system.model.config.borehole.contact_stiffness_n_per_m,
                                    system.model.config.borehole.friction_coefficient,
                                    system.model.config.borehole.friction_regularization_rad_per_s,
                                    first)[0])
    expected[:, forces.bit_axial_index] += wob - forces.static_weight_on_bit_n
    expected[:, forces.bit_torsion_index] += tob
    scale = np.abs(expected).max()
    np.testing.assert_allclose(evaluation.full, expected, rtol=1e-11, atol=1e-12 * scale)
    np.testing.assert_allclose(evaluation.modal, system.project(expected), rtol=1e-10,
                               atol=1e-11 * np.abs(system.project(expected)).max())


def test_a_nan_member_does_not_spoil_the_others(system):
    rng = np.random.default_rng(2)
    fields = _random_fields(system, rng, 4, lateral_m=0.1)
    displacement = fields.displacement.copy()
    displacement[2] = np.nan
    broken = Kinematics(displacement, *(getattr(fields, name) for name in
                                        ('theta_x_rate', 'theta_x_acceleration', 'bending_y_rate',
                                         'bending_y_acceleration', 'bending_z_rate',
                                         'bit_axial_rate')))
    force = NonlinearForces(system).evaluate(broken).full
    assert np.isnan(force[2]).any()
    np.testing.assert_array_equal(np.isfinite(force[[0, 1, 3]]), True)
    np.testing.assert_allclose(force[[0, 1, 3]],
                               NonlinearForces(system).evaluate(fields).full[[0, 1, 3]],
                               rtol=1e-12, atol=1e-9)


# -- the bit-rock law: the numpy implementation the kernel replaced -------------------------

def reference_law(law, rop, omega, germ):
    """(f, t, lifted, J) of Eq. 25-26 and the blended random law, vectorised with numpy."""
    e2 = law.e * law.e
    w = np.where(np.abs(omega) < 1e-9, np.where(omega < 0, -1e-9, 1e-9), omega)
    s = omega * omega + e2
    root = np.sqrt(s)
    slope_ratio = (w * w + e2) / (w * w)
    force = -rop * slope_ratio / law.a2 + law.a3 * root / law.a2 - law.a1 / law.a2
    torque = -law.a4 * rop * omega / s - law.a5 * omega / root
    jacobian = np.empty(rop.shape + (2, 2))
    jacobian[:, 0, 0] = -slope_ratio / law.a2
    jacobian[:, 0, 1] = 2 * rop * e2 / (law.a2 * w ** 3) + law.a3 * omega / (law.a2 * root)
    jacobian[:, 1, 0] = -law.a4 * omega / s
    jacobian[:, 1, 1] = -law.a4 * rop * (e2 - omega * omega) / (s * s) - law.a5 * e2 / (s * root)
    if germ is not None:
        g11, g12, g22 = germ[:, 0, 0], germ[:, 0, 1], germ[:, 1, 1]
        ok = (rop > 0) & (omega > 0) & (force < 0) & (torque < 0)
        r, v = np.where(ok, rop, 1.0), np.where(ok, omega, 1.0)
        p = np.where(ok, force * torque, 1.0)
        dp = jacobian[:, 0, :] * torque[:, None] + force[:, None] * jacobian[:, 1, :]
        q1, q2 = p * v / r, p * r / v
        dq1 = dp * (v / r)[:, None] + np.stack([-p * v / r ** 2, p / r], axis=-1)
        dq2 = dp * (r / v)[:, None] + np.stack([p / v, -p * r / v ** 2], axis=-1)
        r1, r2 = np.sqrt(q1), np.sqrt(q2)
        deviation = np.stack([(g11 - 1) * force - g12 * r1, (g22 - 1) * torque - g12 * r2], -1)
        d_deviation = np.empty_like(jacobian)
        d_deviation[:, 0, :] = (g11 - 1)[:, None] * jacobian[:, 0, :] - g12[:, None] * dq1 / (
            2 * r1[:, None])
        d_deviation[:, 1, :] = (g22 - 1)[:, None] * jacobian[:, 1, :] - g12[:, None] * dq2 / (
            2 * r2[:, None])
        weight = r * r / (r * r + law.rop_scale ** 2)
        d_weight = 2 * r * law.rop_scale ** 2 / (r * r + law.rop_scale ** 2) ** 2
        random_jacobian = jacobian + weight[:, None, None] * d_deviation
        random_jacobian[:, :, 0] += deviation * d_weight[:, None]
        force = np.where(ok, force + weight * deviation[:, 0], force)
        torque = np.where(ok, torque + weight * deviation[:, 1], torque)
        jacobian = np.where(ok[:, None, None], random_jacobian, jacobian)
    lifted = force >= 0
    return (np.where(lifted, 0.0, force), np.where(lifted, 0.0, torque), lifted,
            np.where(lifted[:, None, None], 0.0, jacobian))


@pytest.mark.parametrize('random', [False, True])
def test_the_law_kernel_matches_the_numpy_reference(default_config, random):
    """
    Random points over cutting, lift-off, ROP near and below 0, omega near, at and below 0.

    Omega below 0 meets the floor of 1/omega^2; with and without random germs.
    """
    from drill_twin.model.bit_rock import BitRockLaw
    law = BitRockLaw.from_config(default_config.bit_rock)
    rng = np.random.default_rng(5)
    m = 4000
    rop = rng.normal(2e-3, 3e-3, m)
    omega = rng.normal(3.0, 6.0, m)
    omega[:20] = rng.normal(0, 1e-9, 20)
    omega[20:25] = 0.0
    rop[25:60] = rng.normal(0, 1e-4, 35)
    germ = None
    if random:
        germ = np.eye(2) + 0.1 * rng.normal(size=(m, 2, 2))
        germ = 0.5 * (germ + germ.transpose(0, 2, 1))
    expected = reference_law(law, rop, omega, germ)
    result = law.forces_and_jacobian(rop, omega, germ)
    assert expected[2].any() and not expected[2].all()         # lift-off and cutting occur
    np.testing.assert_array_equal(result[2], expected[2])
    for got, want in zip((result[0], result[1]), expected[:2]):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13 * np.abs(want).max())
    # Entries of J scale very differently (d/dROP ~ 1e9, d/domega ~ 1e4): each on its own.
    for r in range(2):
        for c in range(2):
            want = expected[3][:, r, c]
            np.testing.assert_allclose(result[3][:, r, c], want, rtol=1e-12,
                                       atol=1e-13 * np.abs(want).max())
    force, torque, lifted = law.forces(rop, omega, germ)          # the same kernel
    np.testing.assert_array_equal(force, result[0])
    np.testing.assert_array_equal(lifted, result[2])


# -- the compiled step and the observer -----------------------------------------------------

def test_observe_reads_the_fields_of_the_state(default_config):
    """
    Observation's stations, hook and top torque against the field-wise vectors Phi q.

    Phi q with the driven rotation on theta_x, computed here directly.
    """
    from drill_twin.integrator.simulator import Simulator
    simulator = Simulator(default_config, members=3,
                          germs=np.eye(2) + np.zeros((3, 2, 2)))
    rng = np.random.default_rng(4)
    simulator.state.q = simulator.state.q + 1e-3 * rng.normal(size=simulator.state.q.shape)
    simulator.state.q_rate = rng.normal(size=simulator.state.q.shape)
    simulator.state.q_acceleration = rng.normal(size=simulator.state.q.shape)
    simulator.state.top_acceleration_rad_per_s2 = 0.7
    system, state = simulator.system, simulator.state
    theta_x = system.field(1)
    u = system.physical(state.q)
    rate = system.physical(state.q_rate)
    rate[:, theta_x] += state.top_speed_rad_per_s
    acceleration = system.physical(state.q_acceleration)
    acceleration[:, theta_x] += 0.7
    observation = simulator.observe(detailed=2)
    for k, station in enumerate(system.stations):
        for name, field in (('station_displacement_m', u), ('station_velocity_m_per_s', rate),
                            ('station_acceleration_m_per_s2', acceleration)):
            expected = field[:2] @ station.rows[:3].T
            np.testing.assert_allclose(getattr(observation, name)[:, k], expected,
                                       rtol=1e-10, atol=1e-12 * np.abs(expected).max())
        spin = rate[:2] @ station.rows[3:].T
        np.testing.assert_allclose(observation.station_spin_rate_rad_per_s[:, k], spin,
                                   rtol=1e-10, atol=1e-12 * np.abs(spin).max())
    np.testing.assert_allclose(observation.hook_position_m, u[:2, 0], rtol=1e-12)
    torque = (acceleration[:2] @ system.driven_rows['mass']
              + rate[:2] @ system.driven_rows['damping']
              - simulator.last.full[:2, theta_x].sum(axis=1))
    np.testing.assert_allclose(observation.top_torque_nm, torque, rtol=1e-9,
                               atol=1e-12 * np.abs(torque).max())
    assert observation.weight_on_bit_n.shape == (3,)


def test_observe_derives_the_bit_quantities_by_their_definitions(default_config):
    """
    The bit's depth, angle, ROP, depth of cut, hole depth and on-bottom flag of an observation.

    Against their definitions from the state directly: depth = L + u_bit (Phi's axial row at
    the bit), angle = theta_top + theta_x at the bit, hole depth = L + the hole, on bottom
    within 1 um, ROP = the bit's axial velocity on bottom and moving down (else 0), depth of
    cut = ROP omega / (omega^2 + e^2). One member picked up off bottom, one drilling.
    """
    from drill_twin.integrator.simulator import Simulator
    simulator = Simulator(default_config, members=2,
                          germs=np.eye(2) + np.zeros((2, 2, 2)))
    hook = simulator.state.hook_load_n
    loads = np.array([hook + 400e3, hook])
    for _ in range(100):
        simulator.step(hook_load_n=loads)
    seen = simulator.observe()
    state, integrator = simulator.state, simulator.integrator
    length = simulator.system.model.mesh.total_length_m
    bit_u = state.q @ integrator.bit_axial_row
    np.testing.assert_allclose(seen.depth_m, length + bit_u, rtol=1e-14)
    np.testing.assert_allclose(seen.bit_depth_m, seen.depth_m, rtol=0)
    np.testing.assert_allclose(seen.angle_rad, state.top_angle_rad + state.q
                               @ integrator.bit_rows[1], rtol=1e-12)
    np.testing.assert_allclose(seen.hole_depth_m, length + state.hole_u, rtol=1e-14)
    on_bottom = bit_u >= state.hole_u - 1e-6
    assert seen.on_bottom.tolist() == on_bottom.tolist() == [False, True]
    velocity = simulator.last.rop_m_per_s
    rop = np.where(on_bottom, np.maximum(velocity, 0.0), 0.0)
    np.testing.assert_array_equal(seen.rop_m_per_s, rop)
    assert seen.rop_m_per_s[1] > 0
    omega, e = seen.speed_rad_per_s, simulator.law.e
    np.testing.assert_allclose(seen.depth_of_cut_m_per_rad, rop * omega / (omega ** 2 + e ** 2),
                               rtol=1e-14)


def test_a_step_with_wall_contact_matches_single_member_steps(default_config):
    """
    The compiled step with members pressed on the wall equals each member stepped alone.

    The batch has members pressed on the wall (Woodbury correction of some members only); the
    step also conserves the touch flags.
    """
    from drill_twin.integrator.simulator import Simulator
    members = 3
    germs = np.eye(2) + np.array([0.0, 0.02, -0.03])[:, None, None] * np.array(
        [[1.0, 0.5], [0.5, -1.0]])
    batch = Simulator(default_config, members=members, germs=germs)
    bending = batch.system.blocks['bending_y']
    q, rate = batch.state.q.copy(), batch.state.q_rate.copy()
    q[1:, bending.columns] *= 40.0                # members 1 and 2 on the wall, 0 free
    batch.reset(q, rate)
    for _ in range(4):
        batch.step()
    touched = batch.last.contact.in_contact.any(axis=1)
    assert not touched[0] and touched[1:].all()
    for member in range(members):
        alone = Simulator(default_config, members=1, germs=germs[member:member + 1])
        alone.reset(q[member:member + 1], rate[member:member + 1])
        for _ in range(4):
            alone.step()
        np.testing.assert_allclose(alone.state.q[0], batch.state.q[member], rtol=1e-9,
                                   atol=1e-12 * np.abs(batch.state.q).max())
        np.testing.assert_allclose(alone.last.weight_on_bit_n[0],
                                   batch.last.weight_on_bit_n[member], rtol=1e-9)


def test_a_member_diverging_on_the_wall_fails_its_step_and_spares_the_others(default_config):
    """
    An infinite lateral displacement is 'in contact' with no direction (nan tangent).

    The step's Woodbury correction cannot be made for that member: the step reports it not
    finite (no exception, the caller retries or restarts it) and the member on the wall beside
    it steps exactly as it does alone.
    """
    from drill_twin.integrator.simulator import Simulator
    batch = Simulator(default_config, members=2)
    bending = batch.system.blocks['bending_y']
    q, rate = batch.state.q.copy(), batch.state.q_rate.copy()
    q[:, bending.columns] *= 40.0                  # both members pressed on the wall
    alone = Simulator(default_config, members=1)
    alone.reset(q[:1], rate[:1])
    batch.reset(q, rate)
    batch.state.q[1, bending.columns.start] = np.inf      # diverged since the last step
    integrator = batch.integrator
    state, result = integrator.step(batch.state, batch.state.top_speed_rad_per_s,
                                    batch.state.hook_load_n)
    assert not result.success and 'non-finite' in result.message
    assert result.finite.tolist() == [True, False]
    alone.step()
    assert alone.last.contact.in_contact.any()
    np.testing.assert_allclose(state.q[0], alone.state.q[0], rtol=1e-9,
                               atol=1e-12 * np.abs(alone.state.q).max())


def test_members_verify_on_the_model_clocks_schedule(default_config):
    """
    Second iterations fall on every VERIFY_EVERY-th step of the model's clock, for all at once.

    The first steps verify (no contraction rate yet, or one too slow to accept); a member whose
    history is dropped (``forget``, as after an analysis) verifies alone on its next step and
    then keeps the clock's schedule: it does not fall due alone VERIFY_EVERY steps later, which
    would cost the whole batch a second iteration (the 64-member ensemble ran two iterations on
    8 % of its steps that way, 4 % on the clock's).
    """
    from drill_twin.integrator.newmark_update import VERIFY_EVERY
    from drill_twin.integrator.simulator import Simulator
    germs = np.eye(2) + np.array([0.0, 0.02, -0.03])[:, None, None] * np.array(
        [[1.0, 0.5], [0.5, -1.0]])
    batch = Simulator(default_config, members=3, germs=germs)
    verified = []
    for step in range(1, 2 * VERIFY_EVERY + 11):
        if step == 8:
            batch.integrator.forget([1])
        result = batch.step()
        if result.iterations > 1:
            verified.append(step)
        assert round(batch.time_s / batch.dt) == step
    # Steps 1 and 2: no rate yet, then a rate whose estimated remaining error is too large.
    assert verified[:1] == [1] and verified[1:] in ([8, VERIFY_EVERY, 2 * VERIFY_EVERY],
                                                    [2, 8, VERIFY_EVERY, 2 * VERIFY_EVERY])


def test_a_large_batch_verifies_in_groups_spread_over_the_clock(default_config):
    """
    Members verify in groups of VERIFY_GROUP, VERIFY_SPACING steps apart on the model's clock.

    17 members are three groups: second iterations on the steps n with n + 3 g a multiple of
    25 (g = 0, 1, 2), and on no other step once the start is past (a whole batch verifying at
    once made the longest twin ticks).
    """
    from drill_twin.integrator.newmark_update import VERIFY_EVERY
    from drill_twin.integrator.newmark_update import VERIFY_GROUP, VERIFY_SPACING
    from drill_twin.integrator.simulator import Simulator
    members = 2 * VERIFY_GROUP + 1
    germs = np.eye(2) + 0.01 * np.random.default_rng(4).standard_normal((members, 2, 2))
    batch = Simulator(default_config, members=members, germs=germs)
    verified = [step for step in range(1, 2 * VERIFY_EVERY + 1)
                if batch.step().iterations > 1]
    expected = sorted(n for n in range(3, 2 * VERIFY_EVERY + 1) for g in range(3)
                      if (n + VERIFY_SPACING * g) % VERIFY_EVERY == 0)
    assert expected == [19, 22, 25, 44, 47, 50]
    assert [n for n in verified if n > 2] == expected


def test_groups_beyond_the_cycles_slots_verify_with_the_first_ones(default_config):
    """
    A batch of more than VERIFY_SLOTS groups verifies on the cycle's VERIFY_SLOTS steps only.

    Group g takes slot g mod VERIFY_SLOTS: 73 members are ten groups, the ninth and tenth
    verifying with the first and second, so second iterations fall on 8 steps of 25 (not on
    26 and 51, or 23 and 48, where groups 8 and 9 had slots of their own: a 256-member batch
    then ran two iterations on every step). A member's schedule depends on its index only.
    """
    from drill_twin.integrator.newmark_update import VERIFY_EVERY
    from drill_twin.integrator.newmark_update import VERIFY_GROUP, VERIFY_SLOTS, VERIFY_SPACING
    from drill_twin.integrator.simulator import Simulator
    members = (VERIFY_SLOTS + 1) * VERIFY_GROUP + 1
    germs = np.eye(2) + 0.01 * np.random.default_rng(5).standard_normal((members, 2, 2))
    batch = Simulator(default_config, members=members, germs=germs)
    verified = [step for step in range(1, 2 * VERIFY_EVERY + 2)
                if batch.step().iterations > 1]
    expected = sorted(n for n in range(3, 2 * VERIFY_EVERY + 2) for slot in range(VERIFY_SLOTS)
                      if (n + VERIFY_SPACING * slot) % VERIFY_EVERY == 0)
    assert expected == [4, 7, 10, 13, 16, 19, 22, 25, 29, 32, 35, 38, 41, 44, 47, 50]
    assert [n for n in verified if n > 2] == expected


def test_a_failed_members_flags_are_put_back_without_touching_the_steps_result(default_config):
    """
    The contact and lift-off flags a step keeps for the next one's acceptance are its result's.

    A member whose step fails gets its flags from before the step back; the step's result
    (held by its caller) keeps the flags it was computed with, and the others keep the new ones.
    """
    from drill_twin.integrator.simulator import Simulator
    batch = Simulator(default_config, members=2)
    bending = batch.system.blocks['bending_y']
    q, rate = batch.state.q.copy(), batch.state.q_rate.copy()
    q[0, bending.columns] *= 40.0                  # member 0 pressed on the wall
    batch.reset(q, rate)
    batch.step()
    integrator = batch.integrator
    before = tuple(flags.copy() for flags in integrator._active)
    assert before[0][0].any() and not before[0][1].any()
    batch.state.q[1, bending.columns] *= 40.0      # member 1 goes to the wall ...
    batch.state.q[1, 0] = np.nan                   # ... and diverges there
    state, result = integrator.step(batch.state, batch.state.top_speed_rad_per_s,
                                    batch.state.hook_load_n)
    assert result.finite.tolist() == [True, False]
    computed = result.forces.contact.in_contact, result.forces.lifted
    contact, lifted = integrator._active
    np.testing.assert_array_equal(contact[1], before[0][1])
    np.testing.assert_array_equal(lifted[1], before[1][1])
    np.testing.assert_array_equal(contact[0], computed[0][0])
    np.testing.assert_array_equal(lifted[0], computed[1][0])
    # The result keeps what the step computed: member 1 on the wall (not put back in place).
    assert result.forces.contact.in_contact[1].any()
    assert not np.shares_memory(contact, result.forces.contact.in_contact)


def test_a_steps_wall_tangents_are_its_own(default_config):
    """
    The contact tangents a step hands out stay as they were after the next step.

    The kernel writes them into the batch's work array; the evaluation gets a copy when a node
    touches (and None when none does).
    """
    from drill_twin.integrator.simulator import Simulator
    batch = Simulator(default_config, members=2)
    bending = batch.system.blocks['bending_y']
    q, rate = batch.state.q.copy(), batch.state.q_rate.copy()
    q[0, bending.columns] *= 40.0                  # member 0 pressed on the wall
    batch.reset(q, rate)
    first = batch.step().forces.contact_tangent
    kept = first.copy()
    assert np.any(kept[0] != 0.0) and not np.any(kept[1])
    second = batch.step().forces.contact_tangent
    assert second is not first and np.any(second != kept)
    np.testing.assert_array_equal(first, kept)
