"""
The reduced model of Eq. 35 and every operator the time loop needs, precomputed once.

The displacement from the prestressed state is u = [Phi] q + psi theta_top(t): q holds the
amplitudes of the basis columns (the rigid axial mode, which carries the penetration, and the
elastic modes) and psi is the rigid rotation carried by the top-drive angle theta_top.

Layout. The linearised string does not couple its axial, torsional and two bending motions,
so every basis column lives on one group of DOFs. Inside the time loop the physical DOFs are
stored field by field, [u | theta_x | v | theta_z | w | theta_y] (n_nodes each), and the
reduced coordinates group by group, [axial | torsional | bending in y | bending in z]: each
block of [Phi] is then a small dense matrix on a contiguous slice, four times fewer
operations than the full [Phi]. Non-linear forces are evaluated on these physical fields
with sparse Gauss-point operators and projected back block by block.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from drill_twin.fem import dofs
from drill_twin.fem import shape_functions as sf
from drill_twin.fem import strain_energy as se
from drill_twin.fem.model import FiniteElementModel
from drill_twin.modal.reduced_basis import ReducedBasis, reduce_matrices

FIELD_ORDER = (dofs.U, dofs.THETA_X, dofs.V, dofs.THETA_Z, dofs.W, dofs.THETA_Y)
"""Physical fields in the order of the loop's layout."""
GROUPS = ('axial', 'torsional', 'bending_y', 'bending_z')
"""Column groups: bending_y moves v (in the x-y plane), bending_z moves w."""
_GROUP_FIELDS = {'axial': (0,), 'torsional': (1,), 'bending_y': (2, 3), 'bending_z': (4, 5)}


@dataclass(frozen=True)
class Block:
    """
    A group of reduced coordinates and the fields they move.

    columns: slice of the reduced coordinates; rows: slice of the field-wise DOFs;
    shapes: that block of [Phi], (rows, columns); shapes_t: its transpose.
    """

    columns: slice
    rows: slice
    shapes: np.ndarray
    shapes_t: np.ndarray


@dataclass(frozen=True)
class Station:
    """
    A measurement point at depth x (m).

    Interpolation rows of the six fields (u, v, w, theta_x, theta_y, theta_z) on the field-wise
    DOFs, shape (6, n_dofs).
    """

    x_m: float
    rows: np.ndarray


@dataclass(frozen=True)
class ReducedSystem:
    """
    Precomputed reduced matrices and operators (SI units; see the module docstring).

    Fields:
        model, basis: the finite-element model and the reduced basis.
        basis_columns: for each reduced coordinate, its column in ``basis`` (ranks, types).
        mass, damping, stiffness: [M_r], [C_r], [K_r] in the loop's order, (n, n).
        mass_driven, damping_driven: Phi^T (M + M_f) psi and Phi^T (C + C_f) psi, (n,).
        blocks: the four column groups.
        permutation: field-wise DOF -> model DOF index, (n_dofs,).
        n_nodes: nodes per field; field(k) gives the slice of field k (position in FIELD_ORDER).
        strain_operator: generalized strains at the Gauss points, component first: row
            k * P + p is strain k at point p; sparse (8 P, n_dofs).
        strain_and_tangent_operator: [B; H_S B] stacked, sparse (16 P, n_dofs): the strains
            and their image by the prestress tangent in one product.
        theta_x_gauss, theta_y_gauss, theta_z_gauss: dense rows (P, block size) giving each
            rotation at the P Gauss points from the theta_x block, the bending_z block and the
            bending_y block (dense: small, and a dense product beats a sparse call here);
            the *_t variants are their transposes.
        gauss_weight_m, polar_inertia_density (rho I_p, kg m): per Gauss point, (P,).
        prestress_strain, prestress_stress, prestress_tangent: g_S, dW/dg and d2W/dg2 at the
            Gauss points, (P, 8) and (P, 8, 8); section: constants per Gauss point;
            the *_components and section_columns variants are shaped (8, P, 1) and (P, 1)
            for the component-first loop arrays (8, P, m).
        clearance_m, node_outer_radius_m: per node.
        bit_node, top_axial_row: the axial rows of [Phi] at the top, (n,).
        driven_rows: psi^T (M + M_f) and psi^T (C + C_f) on the field-wise DOFs: the torque
            balance of the whole string gives the top-drive torque (psi^T K = 0), which is
            far more accurate in a truncated basis than the top node's own row.
        stations: output stations.
    """

    model: FiniteElementModel
    basis: ReducedBasis
    basis_columns: np.ndarray
    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    mass_driven: np.ndarray
    damping_driven: np.ndarray
    blocks: dict
    permutation: np.ndarray
    n_nodes: int
    strain_operator: sp.csr_matrix
    strain_operator_t: sp.csr_matrix
    strain_and_tangent_operator: sp.csr_matrix
    theta_x_gauss: np.ndarray
    theta_y_gauss: np.ndarray
    theta_z_gauss: np.ndarray
    theta_x_gauss_t: np.ndarray
    theta_y_gauss_t: np.ndarray
    theta_z_gauss_t: np.ndarray
    gauss_weight_m: np.ndarray
    polar_inertia_density: np.ndarray
    prestress_strain: np.ndarray
    prestress_stress: np.ndarray
    prestress_tangent: np.ndarray
    section: se.SectionStiffness
    prestress_strain_components: np.ndarray
    prestress_stress_components: np.ndarray
    section_columns: se.SectionStiffness
    clearance_m: np.ndarray
    node_outer_radius_m: np.ndarray
    bit_node: int
    top_axial_row: np.ndarray
    driven_rows: dict
    stations: tuple

    @property
    def size(self) -> int:
        """Number of reduced coordinates n."""
        return self.mass.shape[0]

    @property
    def n_dofs(self) -> int:
        return self.permutation.size

    @property
    def n_gauss(self) -> int:
        return self.gauss_weight_m.size

    def field(self, position: int) -> slice:
        """Slice of field ``FIELD_ORDER[position]`` in the field-wise DOFs."""
        return slice(position * self.n_nodes, (position + 1) * self.n_nodes)

    def physical(self, q: np.ndarray) -> np.ndarray:
        """Field-wise u = Phi q for q of shape (m, n) (without the driven rotation)."""
        out = np.zeros(q.shape[:-1] + (self.n_dofs,))
        for block in self.blocks.values():
            out[..., block.rows] = q[..., block.columns] @ block.shapes_t
        return out

    def project(self, force: np.ndarray) -> np.ndarray:
        """Phi^T f for a field-wise force (m, n_dofs) -> (m, n)."""
        out = np.empty(force.shape[:-1] + (self.size,))
        for block in self.blocks.values():
            out[..., block.columns] = force[..., block.rows] @ block.shapes
        return out

    def steady_twist(self, torque_on_bit_nm: float, top_speed_rad_per_s: float) -> np.ndarray:
        """
        Return the torsional coordinates (rad, the torsional block's) of a steady twist.

        In static equilibrium under the torque on bit t_bit (N m) and the drag of the string
        spinning at Omega (rad/s): K_r q = Phi_bit t_bit - Phi^T (C + C_f) psi Omega on the
        torsional block.
        """
        torsion = self.blocks['torsional']
        load = (torsion.shapes[self.bit_node] * torque_on_bit_nm
                - self.damping_driven[torsion.columns] * top_speed_rad_per_s)
        return np.linalg.solve(self.stiffness[torsion.columns, torsion.columns], load)


def _column_groups(model: FiniteElementModel, basis: ReducedBasis) -> dict[str, np.ndarray]:
    shapes = basis.shapes
    energy = {}
    for name, members in (('axial', (dofs.U,)), ('torsional', (dofs.THETA_X,)),
                          ('bending_y', (dofs.V, dofs.THETA_Z)),
                          ('bending_z', (dofs.W, dofs.THETA_Y))):
        rows = np.isin(np.arange(model.n_dofs) % dofs.DOFS_PER_NODE, members)
        energy[name] = np.einsum('im,im->m', shapes[rows], shapes[rows])
    stacked = np.stack([energy[g] for g in GROUPS])
    owner = np.argmax(stacked, axis=0)
    purity = stacked[owner, np.arange(shapes.shape[1])] / stacked.sum(axis=0)
    if np.any(purity < 1 - 1e-9):
        raise ValueError('the reduced basis couples axial, torsional and bending motion; the '
                         'time loop needs modes that each live on one group of DOFs')
    return {name: np.flatnonzero(owner == g) for g, name in enumerate(GROUPS)}


def _field_wise_permutation(n_nodes: int) -> np.ndarray:
    nodes = np.arange(n_nodes)
    return np.concatenate([dofs.node_dof(nodes, local) for local in FIELD_ORDER])


def _gauss_operator(rows: np.ndarray, element_dofs: np.ndarray, n_columns: int) -> sp.csr_matrix:
    """Sparse (n_el * n_pts * k, n_columns) operator from element rows (n_el, n_pts, k, 12)."""
    n_el, n_pt, k, _ = rows.shape
    index = np.arange(n_el * n_pt * k).reshape(n_el, n_pt, k)
    rr = np.broadcast_to(index[..., None], rows.shape)
    cc = np.broadcast_to(element_dofs[:, None, None, :], rows.shape)
    keep = rows != 0.0
    return sp.csr_matrix((rows[keep], (rr[keep], cc[keep])), shape=(n_el * n_pt * k, n_columns))


def build_reduced_system(model: FiniteElementModel, basis: ReducedBasis) -> ReducedSystem:
    """Precompute everything that does not change inside the time loop."""
    mesh, quad = model.mesh, model.quadrature
    n_nodes = mesh.n_nodes
    n_el, n_pt = quad.weight_m.shape
    permutation = _field_wise_permutation(n_nodes)
    inverse = np.empty_like(permutation)
    inverse[permutation] = np.arange(permutation.size)
    element_dofs = inverse[mesh.element_dofs]            # element DOFs in field-wise numbering
    order, blocks = _blocks(model, basis, permutation, n_nodes)

    reduced = reduce_matrices(model, basis)
    pick = np.ix_(order, order)
    strain = _gauss_operator(quad.strain_rows, element_dofs, permutation.size)
    n_points = n_el * n_pt
    component_major = (np.arange(n_points)[None, :] * se.N_STRAINS
                       + np.arange(se.N_STRAINS)[:, None]).ravel()
    strain = strain[component_major].tocsr()              # row k * P + p: component first
    prestress_strain = model.prestress_strain.reshape(n_el * n_pt, se.N_STRAINS)
    section = se.SectionStiffness(
        **{name: np.repeat(getattr(model.section, name)[:, 0], n_pt)
           for name in ('EA', 'EI', 'ER4', 'kGA', 'kGI')})

    def rotation_rows(field, block):
        operator = _gauss_operator(quad.rows.value[:, :, [field]], element_dofs,
                                   permutation.size)
        return np.ascontiguousarray(operator[:, blocks[block].rows].toarray())

    prestress_stress = se.stress_resultants(prestress_strain, section)
    prestress_tangent = se.tangent_stiffness(prestress_strain, section)
    tangent_blocks = sp.bmat([[sp.diags(prestress_tangent[:, k, l])  # noqa: E741
                               for l in range(se.N_STRAINS)]  # noqa: E741
                              for k in range(se.N_STRAINS)]).tocsr()
    theta_x = rotation_rows(sf.FIELD_THETA_X, 'torsional')
    theta_y = rotation_rows(sf.FIELD_THETA_Y, 'bending_z')
    theta_z = rotation_rows(sf.FIELD_THETA_Z, 'bending_y')
    psi = basis.driven_rotation
    driven_rows = {name: np.asarray(matrix.T @ psi).ravel()[permutation]
                   for name, matrix in (('mass', model.total_mass), ('damping', model.damping()))}
    top_axial = dofs.node_dof(0, dofs.U)
    return ReducedSystem(
        model=model, basis=basis, basis_columns=order,
        mass=reduced.mass[pick], damping=reduced.damping[pick],
        stiffness=reduced.stiffness[pick],
        mass_driven=reduced.mass_driven[order], damping_driven=reduced.damping_driven[order],
        blocks=blocks, permutation=permutation, n_nodes=n_nodes,
        strain_operator=strain, strain_operator_t=strain.T.tocsr(),
        strain_and_tangent_operator=sp.vstack([strain, tangent_blocks @ strain]).tocsr(),
        theta_x_gauss=theta_x, theta_y_gauss=theta_y, theta_z_gauss=theta_z,
        theta_x_gauss_t=np.ascontiguousarray(theta_x.T),
        theta_y_gauss_t=np.ascontiguousarray(theta_y.T),
        theta_z_gauss_t=np.ascontiguousarray(theta_z.T),
        gauss_weight_m=quad.weight_m.ravel(),
        polar_inertia_density=np.repeat(mesh.density_kg_per_m3 * mesh.polar_inertia_m4, n_pt),
        prestress_strain=prestress_strain,
        prestress_stress=prestress_stress,
        prestress_tangent=prestress_tangent,
        section=section,
        prestress_strain_components=np.ascontiguousarray(prestress_strain.T)[:, :, None],
        prestress_stress_components=np.ascontiguousarray(prestress_stress.T)[:, :, None],
        section_columns=se.SectionStiffness(**{k: v[:, None] for k, v in
                                               section.__dict__.items()}),
        clearance_m=model.config.borehole.diameter_m / 2.0 - mesh.node_outer_radius_m,
        node_outer_radius_m=mesh.node_outer_radius_m.copy(),
        bit_node=mesh.bit_node,
        top_axial_row=basis.shapes[top_axial, order].copy(),
        driven_rows=driven_rows,
        stations=_stations(model, element_dofs, permutation.size),
    )


def _blocks(model: FiniteElementModel, basis: ReducedBasis, permutation: np.ndarray,
            n_nodes: int) -> tuple[np.ndarray, dict]:
    """
    (order, blocks): the basis columns grouped (GROUPS), and the four :class:`Block`.

    order: for each reduced coordinate its column in ``basis``; a block's shapes are [Phi] on
    its fields' field-wise rows (``permutation``, n_nodes per field).
    """
    groups = _column_groups(model, basis)
    order = np.concatenate([groups[g] for g in GROUPS])
    phi = basis.shapes[permutation][:, order]          # field-wise rows, grouped columns
    blocks, start = {}, 0
    for name in GROUPS:
        count = groups[name].size
        fields = _GROUP_FIELDS[name]
        rows = slice(fields[0] * n_nodes, (fields[-1] + 1) * n_nodes)
        block = np.ascontiguousarray(phi[rows, start:start + count])
        blocks[name] = Block(columns=slice(start, start + count), rows=rows, shapes=block,
                             shapes_t=np.ascontiguousarray(block.T))
        start += count
    return order, blocks


def _stations(model: FiniteElementModel, element_dofs: np.ndarray, n_dofs: int) -> tuple:
    """Return the output stations (:class:`Station`) of the configuration, rows on n_dofs DOFs."""
    mesh = model.mesh
    stations = []
    for x in model.config.output.stations_m:
        element, xi = mesh.locate(x)
        rows = sf.field_rows(np.array([xi]), mesh.length_m[element:element + 1],
                             mesh.timoshenko_phi()[element:element + 1]).value[0, 0]
        full = np.zeros((sf.N_FIELDS, n_dofs))
        full[:, element_dofs[element]] = rows
        stations.append(Station(x_m=float(x), rows=full))
    return tuple(stations)
