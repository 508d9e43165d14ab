"""Element and global matrices: closed forms, symmetry, definiteness, rigid motions, statics."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as la
from conftest import config_with, physics_off

from drill_twin.fem import dofs
from drill_twin.fem import shape_functions as sf
from drill_twin.fem.element_matrices import stiffness_from_tangent
from drill_twin.fem.model import build_model
from drill_twin.fem.quadrature import build_quadrature
from drill_twin.fem.strain_energy import SectionStiffness, tangent_stiffness


def test_shape_functions_interpolate_nodal_values():
    rows = sf.field_rows(np.array([0.0, 1.0]), np.array([7.0]), np.array([0.3]))
    own = {sf.FIELD_U: dofs.U, sf.FIELD_V: dofs.V, sf.FIELD_W: dofs.W,
           sf.FIELD_THETA_X: dofs.THETA_X, sf.FIELD_THETA_Y: dofs.THETA_Y,
           sf.FIELD_THETA_Z: dofs.THETA_Z}
    for field, local in own.items():
        for point, node_offset in ((0, 0), (1, 6)):
            expected = np.zeros(12)
            expected[local + node_offset] = 1.0
            np.testing.assert_allclose(rows.value[0, point, field], expected, atol=1e-14)


def test_euler_bernoulli_limit_rotation_is_the_slope():
    """With phi = 0: theta_z = dv/dx and theta_y = -dw/dx everywhere."""
    xi = np.linspace(0, 1, 7)
    rows = sf.field_rows(xi, np.array([5.0]), np.array([0.0]))
    np.testing.assert_allclose(rows.value[0, :, sf.FIELD_THETA_Z], rows.slope[0, :, sf.FIELD_V],
                               atol=1e-13)
    np.testing.assert_allclose(rows.value[0, :, sf.FIELD_THETA_Y], -rows.slope[0, :, sf.FIELD_W],
                               atol=1e-13)


def test_timoshenko_shear_strain_is_constant_along_the_element():
    xi = np.linspace(0, 1, 9)
    rows = sf.field_rows(xi, np.array([3.0]), np.array([0.8]))
    shear = rows.slope[0, :, sf.FIELD_V] - rows.value[0, :, sf.FIELD_THETA_Z]
    np.testing.assert_allclose(shear, np.broadcast_to(shear[0], shear.shape), atol=1e-13)


def test_bending_stiffness_is_the_closed_form_timoshenko_element(default_analysis):
    """Przemieniecki's Timoshenko beam element, v-plane DOFs (v1, theta_z1, v2, theta_z2)."""
    model = default_analysis[0]
    mesh, quad = model.mesh, model.quadrature
    linear = tangent_stiffness(np.zeros(quad.strain_rows.shape[:2] + (8,)), model.section)
    k_e = stiffness_from_tangent(linear, quad)
    plane = [dofs.V, dofs.THETA_Z, 6 + dofs.V, 6 + dofs.THETA_Z]
    for e in (0, mesh.n_elements - 1):
        length, phi = mesh.length_m[e], mesh.timoshenko_phi()[e]
        ei = mesh.young_modulus_pa[e] * mesh.inertia_m4[e]
        l2 = length ** 2
        expected = ei / ((1 + phi) * length ** 3) * np.array([
            [12, 6 * length, -12, 6 * length],
            [6 * length, (4 + phi) * l2, -6 * length, (2 - phi) * l2],
            [-12, -6 * length, 12, -6 * length],
            [6 * length, (2 - phi) * l2, -6 * length, (4 + phi) * l2]])
        np.testing.assert_allclose(k_e[e][np.ix_(plane, plane)], expected, rtol=1e-10)


def _free_free_model():
    boundary = {'top_axial': 'free', 'top_torsion': 'free', 'top_lateral': 'free',
                'bit_axial': 'free', 'bit_torsion': 'free', 'bit_lateral': 'free'}
    return build_model(config_with({'physics': physics_off(), 'boundary': boundary}))


def test_rigid_motions_cost_no_strain_energy():
    model = _free_free_model()
    x = model.mesh.node_x_m
    k = model.stiffness
    motions = []
    for local in (dofs.U, dofs.V, dofs.W, dofs.THETA_X):
        m = np.zeros(model.n_dofs)
        m[dofs.node_dof(np.arange(x.size), local)] = 1.0
        motions.append(m)
    tilt_v = np.zeros(model.n_dofs)          # rotation about z: v = x, theta_z = 1
    tilt_v[dofs.node_dof(np.arange(x.size), dofs.V)] = x
    tilt_v[dofs.node_dof(np.arange(x.size), dofs.THETA_Z)] = 1.0
    tilt_w = np.zeros(model.n_dofs)          # rotation about y: w = -x, theta_y = 1
    tilt_w[dofs.node_dof(np.arange(x.size), dofs.W)] = -x
    tilt_w[dofs.node_dof(np.arange(x.size), dofs.THETA_Y)] = 1.0
    scale = abs(k).max()
    for motion in motions + [tilt_v, tilt_w]:
        assert np.abs(k @ motion).max() < 1e-9 * scale * max(1.0, np.abs(motion).max())


def test_mass_is_the_string_mass_and_definite(default_analysis, default_config):
    model = default_analysis[0]
    mesh = model.mesh
    steel = np.sum(mesh.density_kg_per_m3 * mesh.area_m2 * mesh.length_m)
    analytic = sum(s.density_kg_per_m3 * np.pi / 4 * (s.outer_diameter_m ** 2
                                                      - s.inner_diameter_m ** 2) * s.length_m
                   for s in default_config.sections)
    assert steel == pytest.approx(analytic, rel=1e-12)
    for local in (dofs.U, dofs.V, dofs.W):
        r = np.zeros(model.n_dofs)
        r[dofs.node_dof(np.arange(mesh.n_nodes), local)] = 1.0
        assert r @ (model.mass @ r) == pytest.approx(steel, rel=1e-12)
    spin = model.driven_rotation
    polar = np.sum(mesh.density_kg_per_m3 * mesh.polar_inertia_m4 * mesh.length_m)
    assert spin @ (model.mass @ spin) == pytest.approx(polar, rel=1e-12)
    free = model.free
    m = model.total_mass[free][:, free].toarray()
    np.testing.assert_allclose(m, m.T, rtol=0, atol=1e-13 * np.abs(m).max())
    assert la.eigvalsh(m).min() > 0


def test_fluid_added_mass_per_metre(default_analysis, default_config):
    """Fluid mass: int (M_f + chi rho_f A_o) dx for a rigid lateral translation (Eq. 19)."""
    model = default_analysis[0]
    rho_f = default_config.fluid.density_kg_per_m3
    d_ch = default_config.borehole.diameter_m
    expected = 0.0
    for s in default_config.sections:
        chi = ((d_ch / s.outer_diameter_m) ** 2 + 1) / ((d_ch / s.outer_diameter_m) ** 2 - 1)
        per_m = rho_f * np.pi / 4 * (s.inner_diameter_m ** 2 + chi * s.outer_diameter_m ** 2)
        expected += per_m * s.length_m
    r = np.zeros(model.n_dofs)
    r[dofs.node_dof(np.arange(model.mesh.n_nodes), dofs.V)] = 1.0
    assert r @ (model.fluid_mass @ r) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize('name', ['stiffness', 'geometric_stiffness', 'fluid_stiffness',
                                  'fluid_mass', 'mass'])
def test_matrices_are_symmetric(default_analysis, name):
    matrix = getattr(default_analysis[0], name)
    assert abs(matrix - matrix.T).max() <= 1e-12 * abs(matrix).max()


def test_stiffness_is_semidefinite_and_tangent_definite(default_analysis):
    model = default_analysis[0]
    free = model.free
    k = model.stiffness[free][:, free].toarray()
    eigenvalues = la.eigvalsh(k, model.total_mass[free][:, free].toarray())
    # One rigid (axial) mode at zero; the next, a slack bending mode, is at 3e-6 rad^2/s^2.
    assert eigenvalues.min() > -1e-9
    assert np.sum(eigenvalues < 1e-8) == 1
    tangent = model.total_stiffness[free][:, free].toarray()
    tangent = 0.5 * (tangent + tangent.T)
    eigenvalues = la.eigvalsh(tangent, model.total_mass[free][:, free].toarray())
    assert eigenvalues.min() > -1e-9                               # prestressed, not buckled
    assert np.sum(eigenvalues < 1e-8) == 1


def test_fluid_coriolis_is_skew_but_for_jumps_of_its_coefficient(default_analysis):
    """
    The gyroscopic term c int N^T N' dx does no work, except the point terms.

    The point terms (c_left - c_right) / 2 where c changes (section junction) or ends (top,
    bit).
    """
    from drill_twin.fem.assembly import assemble_matrix
    from drill_twin.fem.fluid import coriolis_coefficient, fluid_coriolis_matrices
    model = default_analysis[0]
    mesh = model.mesh
    c = assemble_matrix(fluid_coriolis_matrices(model.config, model.flow, model.quadrature),
                        mesh.element_dofs, mesh.n_dofs).toarray()
    coefficient = coriolis_coefficient(model.config, model.flow)
    left = np.concatenate([[0.0], coefficient])
    right = np.concatenate([coefficient, [0.0]])
    expected = np.zeros_like(c)
    for node in range(mesh.n_nodes):
        for local in (dofs.V, dofs.W):
            d = dofs.node_dof(node, local)
            expected[d, d] = 0.5 * (left[node] - right[node])
    np.testing.assert_allclose(0.5 * (c + c.T), expected, atol=1e-9 * np.abs(c).max())
    assert np.abs(c - c.T).max() > 1.0
    no_flow = build_model(config_with({'fluid': {'inlet_speed_m_per_s': 0.0}}))
    assert abs(no_flow.fluid_damping).max() == 0.0


def test_prestress_equilibrium_and_hook_load(default_analysis, default_config):
    """N(x) = f_c + (weight and fluid load below x), Eq. 29; hook load = total load."""
    model = default_analysis[0]
    mesh, prestress = model.mesh, model.prestress
    g = default_config.gravity_m_per_s2
    f_c = default_config.bit_rock.static_weight_on_bit_n
    flow = model.flow
    per_length = (mesh.density_kg_per_m3 * mesh.area_m2 * g
                  - 0.5 * default_config.fluid.drag_coefficient
                  * default_config.fluid.density_kg_per_m3 * flow.outer_diameter_m
                  * flow.annulus_speed_m_per_s ** 2)
    below = np.cumsum((per_length * mesh.length_m)[::-1])[::-1]
    midpoint_load_below = below - 0.5 * per_length * mesh.length_m
    # Equilibrium of the string below x: N(x) = f_c + load below x (tension > 0).
    np.testing.assert_allclose(prestress.axial_force_n, f_c + midpoint_load_below, rtol=1e-9,
                               atol=1e-6 * abs(f_c))
    assert prestress.hook_load_n == pytest.approx(below[0] + f_c, rel=1e-10)
    collar = default_config.sections[-1]
    collar_weight = collar.density_kg_per_m3 * np.pi / 4 * (
        collar.outer_diameter_m ** 2 - collar.inner_diameter_m ** 2) * g
    assert prestress.neutral_point_above_bit_m == pytest.approx(-f_c / collar_weight, rel=2e-3)


def test_stabilizer_spring_between_nodes_is_interpolated():
    base = config_with({'physics': physics_off()})
    x = 1400.0 - 0.37 * 43.75
    moved = config_with({'physics': dict(physics_off(), stabilizers=True),
                         'stabilizers': [{'name': 's', 'position_m': x,
                                          'stiffness_n_per_m': 1e6}]})
    k = build_model(moved).stiffness - build_model(base).stiffness
    mesh = build_model(base).mesh
    # A rigid lateral translation stretches the spring by 1 m: energy k / 2.
    r = np.zeros(mesh.n_dofs)
    r[dofs.node_dof(np.arange(mesh.n_nodes), dofs.V)] = 1.0
    assert r @ (k @ r) == pytest.approx(1e6, rel=1e-12)


def test_quadrature_integrates_the_mass_exactly():
    """Four Gauss points integrate the degree-6 Timoshenko mass exactly: six points agree."""
    from drill_twin.fem.element_matrices import mass_matrices
    from drill_twin.fem.mesh import build_mesh
    mesh = build_mesh(config_with({}))
    np.testing.assert_allclose(mass_matrices(mesh, build_quadrature(mesh, 4)),
                               mass_matrices(mesh, build_quadrature(mesh, 6)), rtol=1e-12,
                               atol=1e-12)


def test_section_constants():
    from drill_twin.fem.mesh import build_mesh
    mesh = build_mesh(config_with({}))
    s = SectionStiffness.from_mesh(mesh)
    r_o, r_i = 0.0635, 0.0475
    assert mesh.polar_inertia_m4[0] == pytest.approx(np.pi / 2 * (r_o ** 4 - r_i ** 4))
    assert float(s.ER4[0, 0]) == pytest.approx(210e9 * np.pi / 24 * (r_o ** 6 - r_i ** 6))
