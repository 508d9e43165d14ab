"""The assembled finite-element model of the string (paper Sect. 2.1-2.9, Eq. 30)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from drill_twin.config.schema import DrillStringConfig
from drill_twin.fem import dofs
from drill_twin.fem import shape_functions as sf
from drill_twin.fem import strain_energy as se
from drill_twin.fem.assembly import assemble_matrix, assemble_vector, point_matrix
from drill_twin.fem.boundary import constrained_dofs, free_dofs
from drill_twin.fem.element_matrices import mass_matrices, stiffness_from_tangent
from drill_twin.fem.fluid import (FlowField, flow_field, fluid_axial_loads,
                                  fluid_damping_matrices, fluid_mass_matrices,
                                  fluid_stiffness_matrices)
from drill_twin.fem.mesh import Mesh, build_mesh
from drill_twin.fem.prestress import Prestress, solve_prestress
from drill_twin.fem.quadrature import ElementQuadrature, build_quadrature


@dataclass(frozen=True)
class FiniteElementModel:
    """
    All matrices of Eq. 30 on the full DOF set (n_dofs = 6 n_nodes), SI units.

    Fields:
        mass: [M] (with the lumped bit), fluid_mass: [M_f];
        stiffness: [K] (with stabilizer springs), fluid_stiffness: [K_f],
        geometric_stiffness: [K_g(u_S)], the complete tangent of the strain energy at the
            prestress minus [K];
        fluid_damping: [C_f];
        prestress: the static state (Eq. 29);
        constrained, free: DOF indices removed / kept by the boundary conditions;
        driven_rotation: the rigid rotation shape (theta_x = 1 at every node) that carries
            the imposed top rotation, shape (n_dofs,).
        section: section constants of each element; prestress_strain: generalized strains
            of u_S at the Gauss points, shape (n_el, n_points, 8).
    """

    config: DrillStringConfig
    mesh: Mesh
    quadrature: ElementQuadrature
    section: se.SectionStiffness
    flow: FlowField | None
    mass: sp.csr_matrix
    fluid_mass: sp.csr_matrix
    stiffness: sp.csr_matrix
    fluid_stiffness: sp.csr_matrix
    geometric_stiffness: sp.csr_matrix
    fluid_damping: sp.csr_matrix
    prestress: Prestress
    prestress_strain: np.ndarray
    constrained: np.ndarray
    free: np.ndarray
    driven_rotation: np.ndarray

    @property
    def n_dofs(self) -> int:
        return self.mesh.n_dofs

    @property
    def total_mass(self) -> sp.csr_matrix:
        """[M] + [M_f]."""
        return (self.mass + self.fluid_mass).tocsr()

    @property
    def total_stiffness(self) -> sp.csr_matrix:
        """[K] + [K_f] + [K_g(u_S)]."""
        return (self.stiffness + self.fluid_stiffness + self.geometric_stiffness).tocsr()

    def damping(self) -> sp.csr_matrix:
        """[C] + [C_f] with Rayleigh [C] = alpha (M + M_f) + beta (K + K_f + K_g)."""
        d = self.config.damping
        return (d.mass_coefficient_per_s * self.total_mass
                + d.stiffness_coefficient_s * self.total_stiffness
                + self.fluid_damping).tocsr()


def build_model(config: DrillStringConfig) -> FiniteElementModel:
    """Assemble every matrix and the prestress of ``config``."""
    physics = config.physics
    mesh = build_mesh(config)
    quad = build_quadrature(mesh)
    n = mesh.n_dofs
    edofs = mesh.element_dofs
    gravity = config.gravity_m_per_s2 if physics.gravity else 0.0
    section = se.SectionStiffness.from_mesh(mesh)
    zero_strain = np.zeros(quad.strain_rows.shape[:2] + (se.N_STRAINS,))
    linear_tangent = se.tangent_stiffness(zero_strain, section)

    mass = assemble_matrix(mass_matrices(mesh, quad), edofs, n) + _bit_mass(config, mesh)
    stiffness = assemble_matrix(stiffness_from_tangent(linear_tangent, quad), edofs, n)
    if physics.stabilizers:
        stiffness = stiffness + _stabilizer_springs(config, mesh)

    zero = sp.csr_matrix((n, n))
    flow = None
    fluid_mass = fluid_stiffness = fluid_damping = zero
    load = np.zeros(n)
    if physics.fluid:
        flow = flow_field(config, mesh, quad, gravity)
        fluid_mass = assemble_matrix(fluid_mass_matrices(config, flow, quad), edofs, n)
        fluid_stiffness = assemble_matrix(fluid_stiffness_matrices(config, flow, quad),
                                          edofs, n)
        fluid_damping = assemble_matrix(fluid_damping_matrices(config, flow, quad), edofs, n)
        load += assemble_vector(fluid_axial_loads(config, flow, quad, gravity), edofs, n)
    if gravity > 0.0:
        load += _gravity_load(config, mesh, quad, gravity)

    if physics.prestress:
        bit_u = dofs.node_dof(mesh.bit_node, dofs.U)
        f_c = config.bit_rock.static_weight_on_bit_n
        load[bit_u] += f_c
        prestress = solve_prestress(mesh, stiffness, load,
                                    bit_axially_fixed=config.boundary.bit_axial == 'fixed',
                                    static_weight_on_bit_n=f_c)
        u_elements = prestress.displacement_m[edofs]
        prestress_strain = np.einsum('epki,ei->epk', quad.strain_rows, u_elements)
        tangent = se.tangent_stiffness(prestress_strain, section)
        geometric = assemble_matrix(stiffness_from_tangent(tangent - linear_tangent, quad),
                                    edofs, n)
    else:
        prestress = Prestress.none(n, mesh.n_elements)
        prestress_strain = zero_strain
        geometric = zero

    held = constrained_dofs(config.boundary, mesh.n_nodes)
    driven = np.zeros(n)
    driven[dofs.node_dof(np.arange(mesh.n_nodes), dofs.THETA_X)] = 1.0
    return FiniteElementModel(
        config=config, mesh=mesh, quadrature=quad, section=section, flow=flow,
        mass=mass.tocsr(), fluid_mass=fluid_mass.tocsr(), stiffness=stiffness.tocsr(),
        fluid_stiffness=fluid_stiffness.tocsr(), geometric_stiffness=geometric.tocsr(),
        fluid_damping=fluid_damping.tocsr(), prestress=prestress,
        prestress_strain=prestress_strain, constrained=held, free=free_dofs(held, n),
        driven_rotation=driven)


def _gravity_load(config, mesh, quad, gravity):
    per_length = mesh.density_kg_per_m3 * mesh.area_m2 * gravity
    rows = quad.rows.value[:, :, sf.FIELD_U]
    element = np.einsum('ep,epi->ei', per_length[:, None] * quad.weight_m, rows)
    load = assemble_vector(element, mesh.element_dofs, mesh.n_dofs)
    load[dofs.node_dof(mesh.bit_node, dofs.U)] += config.bit.mass_kg * gravity
    return load


def _bit_mass(config, mesh) -> sp.csr_matrix:
    n = mesh.n_dofs
    diagonal = np.zeros(n)
    bit = mesh.bit_node
    for local in (dofs.U, dofs.V, dofs.W):
        diagonal[dofs.node_dof(bit, local)] = config.bit.mass_kg
    diagonal[dofs.node_dof(bit, dofs.THETA_X)] = config.bit.polar_inertia_kg_m2
    return sp.diags(diagonal).tocsr()


def _stabilizer_springs(config, mesh) -> sp.csr_matrix:
    """k_stab (v, w) at each stabilizer (Eq. 28), interpolated where it is not at a node."""
    n = mesh.n_dofs
    total = sp.csr_matrix((n, n))
    for stabilizer in config.stabilizers:
        element, xi = mesh.locate(stabilizer.position_m)
        rows = sf.field_rows(np.array([xi]), mesh.length_m[element:element + 1],
                             mesh.timoshenko_phi()[element:element + 1]).value[0, 0]
        lateral = rows[[sf.FIELD_V, sf.FIELD_W]]
        total = total + point_matrix(lateral, mesh.element_dofs[element],
                                     stabilizer.stiffness_n_per_m, n)
    return total
