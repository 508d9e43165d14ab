"""The finite-element mesh of the string and per-element section properties."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.config.schema import DrillStringConfig
from drill_twin.fem.dofs import DOFS_PER_NODE, element_dof_map


@dataclass(frozen=True)
class Mesh:
    """
    Nodes, elements and cross-section properties; arrays are per element unless stated.

    Fields:
        node_x_m: node positions along the axis, down from the top, shape (n_nodes,).
        length_m: element lengths l_e.
        section_index: index into ``config.sections`` of each element.
        young_modulus_pa, shear_modulus_pa, shear_correction, density_kg_per_m3: material.
        area_m2: steel area A; inertia_m4: I (about y or z); polar_inertia_m4: I_p = 2 I;
        fourth_moment_m6: R4 = integral of y^2 z^2 over the section (m^6), the only
            higher moment the finite-strain energy needs (int y^4 = 3 R4).
        outer_radius_m, inner_radius_m: R_o, R_i.
        node_outer_radius_m: per node, the largest R_o of the elements touching it.
        element_dofs: global DOFs of each element, shape (n_elements, 12).
    """

    node_x_m: np.ndarray
    length_m: np.ndarray
    section_index: np.ndarray
    young_modulus_pa: np.ndarray
    shear_modulus_pa: np.ndarray
    shear_correction: np.ndarray
    density_kg_per_m3: np.ndarray
    area_m2: np.ndarray
    inertia_m4: np.ndarray
    polar_inertia_m4: np.ndarray
    fourth_moment_m6: np.ndarray
    outer_radius_m: np.ndarray
    inner_radius_m: np.ndarray
    node_outer_radius_m: np.ndarray
    element_dofs: np.ndarray

    @property
    def n_nodes(self) -> int:
        return self.node_x_m.size

    @property
    def n_elements(self) -> int:
        return self.length_m.size

    @property
    def n_dofs(self) -> int:
        return DOFS_PER_NODE * self.n_nodes

    @property
    def total_length_m(self) -> float:
        return float(self.node_x_m[-1])

    @property
    def bit_node(self) -> int:
        return self.n_nodes - 1

    def timoshenko_phi(self) -> np.ndarray:
        """Return phi = 12 E I / (k_s G A l_e^2) of each element (Appendix A)."""
        return (12.0 * self.young_modulus_pa * self.inertia_m4
                / (self.shear_correction * self.shear_modulus_pa * self.area_m2
                   * self.length_m ** 2))

    def locate(self, x_m: float) -> tuple[int, float]:
        """Element index and local coordinate xi in [0, 1] of the point x (m)."""
        if not 0.0 <= x_m <= self.total_length_m * (1 + 1e-12):
            raise ValueError(f'x = {x_m} m is outside the string [0, {self.total_length_m}] m')
        element = int(np.clip(np.searchsorted(self.node_x_m, x_m, side='right') - 1,
                              0, self.n_elements - 1))
        xi = (x_m - self.node_x_m[element]) / self.length_m[element]
        return element, float(np.clip(xi, 0.0, 1.0))

    def nearest_node(self, x_m: float) -> int:
        """Index of the node closest to x (m)."""
        return int(np.argmin(np.abs(self.node_x_m - x_m)))


def build_mesh(config: DrillStringConfig) -> Mesh:
    """Split every section into its equal elements, top to bottom."""
    lengths, index = [], []
    for number, section in enumerate(config.sections):
        lengths.append(np.full(section.elements, section.length_m / section.elements))
        index.append(np.full(section.elements, number))
    length = np.concatenate(lengths)
    section_index = np.concatenate(index)
    node_x = np.concatenate([[0.0], np.cumsum(length)])

    def per_element(getter):
        return np.array([getter(config.sections[i]) for i in section_index], dtype=float)

    outer_r = per_element(lambda s: s.outer_diameter_m / 2.0)
    inner_r = per_element(lambda s: s.inner_diameter_m / 2.0)
    area = np.pi * (outer_r ** 2 - inner_r ** 2)
    inertia = np.pi * (outer_r ** 4 - inner_r ** 4) / 4.0
    fourth = np.pi * (outer_r ** 6 - inner_r ** 6) / 24.0
    node_outer = np.zeros(node_x.size)
    node_outer[:-1] = outer_r
    node_outer[1:] = np.maximum(node_outer[1:], outer_r)
    return Mesh(
        node_x_m=node_x,
        length_m=length,
        section_index=section_index,
        young_modulus_pa=per_element(lambda s: s.young_modulus_pa),
        shear_modulus_pa=per_element(lambda s: s.shear_modulus_pa),
        shear_correction=per_element(lambda s: s.shear_correction_factor),
        density_kg_per_m3=per_element(lambda s: s.density_kg_per_m3),
        area_m2=area,
        inertia_m4=inertia,
        polar_inertia_m4=2.0 * inertia,
        fourth_moment_m6=fourth,
        outer_radius_m=outer_r,
        inner_radius_m=inner_r,
        node_outer_radius_m=node_outer,
        element_dofs=element_dof_map(length.size),
    )
