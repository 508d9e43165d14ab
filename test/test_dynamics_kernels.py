"""The compiled force kernels against a straightforward numpy implementation of the same
formulas, on random batches (kept here, not in the package: the package has one
implementation). The formulas themselves are checked against the energies in
test_dynamics_forces.py."""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.dynamics.contact import contact_force
from drill_twin.dynamics.finite_strain import finite_strain_force
from drill_twin.dynamics.forces import Kinematics, NonlinearForces
from drill_twin.dynamics.kinetic_coupling import kinetic_coupling_force
from drill_twin.dynamics.reduced_system import build_reduced_system
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
    """A batch with large random modal amplitudes, spinning, laterally deflected by up to
    ``lateral_m`` (some nodes beyond the clearance), random accelerations."""
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
    """NonlinearForces sums the kernels and the bit law, projects on the basis, and its
    results are not overwritten by the next evaluation of the same batch size."""
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
