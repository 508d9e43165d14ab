"""
Drilling-fluid forces (Eq. 19-23): added mass, stiffness, damping and axial force.

Inside the string the flow is inviscid; in the annulus it is viscous. The volume flow
Q = u_in A_i(top) goes down the string and up the annulus; pressures vary linearly in x
within each section, continuous along the string, with p_o(0) = 0 (Eq. 20-22).

Two readings are taken here (docs/MODEL-CHOICES.md):
- p_cte makes the inside pressure at the bit exceed the annulus pressure by the head
  loss of Eq. 23, rho_f (U_i - U_o)^2 / 2 (about 5 kPa with the paper's data).
- The Coriolis term is the gyroscopic form of a pipe conveying fluid (Paidoussis),
  c int N^T N' dx with c = 2 M_f U_i - 2 chi rho_f A_o U_o, unless ``coriolis: paper``
  asks for Eq. 19 as printed (the same coefficient with the opposite sign on N_theta^T N_theta).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.config.schema import DrillStringConfig
from drill_twin.fem import shape_functions as sf
from drill_twin.fem.element_matrices import weighted_gram
from drill_twin.fem.mesh import Mesh
from drill_twin.fem.quadrature import ElementQuadrature


@dataclass(frozen=True)
class FlowField:
    """
    Flow quantities; arrays are per element unless stated (SI units).

    inner_area_m2 A_i, outer_area_m2 A_o, outer_diameter_m D_o, annulus_area_m2,
    inner_speed_m_per_s U_i, annulus_speed_m_per_s U_o, chi, inner_fluid_mass_kg_per_m M_f,
    inner_pressure_gradient_pa_per_m, outer_pressure_gradient_pa_per_m,
    inner_pressure_pa and outer_pressure_pa at the Gauss points (n_el, n_points),
    pressure_constant_pa p_cte, flow_rate_m3_per_s Q.
    """

    inner_area_m2: np.ndarray
    outer_area_m2: np.ndarray
    outer_diameter_m: np.ndarray
    annulus_area_m2: np.ndarray
    inner_speed_m_per_s: np.ndarray
    annulus_speed_m_per_s: np.ndarray
    chi: np.ndarray
    inner_fluid_mass_kg_per_m: np.ndarray
    inner_pressure_gradient_pa_per_m: np.ndarray
    outer_pressure_gradient_pa_per_m: np.ndarray
    inner_pressure_pa: np.ndarray
    outer_pressure_pa: np.ndarray
    pressure_constant_pa: float
    flow_rate_m3_per_s: float


def flow_field(config: DrillStringConfig, mesh: Mesh, quad: ElementQuadrature,
               gravity_m_per_s2: float) -> FlowField:
    """Speeds and pressures of Eq. 20-23 for the mesh (g = 0 when gravity is off)."""
    fluid = config.fluid
    rho_f = fluid.density_kg_per_m3
    d_ch = config.borehole.diameter_m
    d_o = 2.0 * mesh.outer_radius_m
    a_i = np.pi * mesh.inner_radius_m ** 2
    a_o = np.pi * mesh.outer_radius_m ** 2
    annulus = np.pi * (d_ch ** 2 - d_o ** 2) / 4.0
    flow = fluid.inlet_speed_m_per_s * a_i[0]
    u_i = np.divide(flow, a_i, out=np.zeros_like(a_i), where=a_i > 0)
    u_o = flow / annulus
    ratio2 = (d_ch / d_o) ** 2
    chi = (ratio2 + 1.0) / (ratio2 - 1.0)
    hydraulic_diameter = d_ch - d_o                       # 4 A_ch / S_tot
    friction = 0.5 * fluid.drag_coefficient * rho_f * d_o ** 2 * u_o ** 2 / hydraulic_diameter
    grad_i = np.full(mesh.n_elements, rho_f * gravity_m_per_s2)
    grad_o = rho_f * gravity_m_per_s2 + friction / a_o
    # p_o is continuous, piecewise linear, p_o(0) = 0.
    p_o_nodes = np.concatenate([[0.0], np.cumsum(grad_o * mesh.length_m)])
    local = quad.x_m - mesh.node_x_m[:-1, None]
    p_o = p_o_nodes[:-1, None] + grad_o[:, None] * local
    head_loss_pa = 0.5 * rho_f * (u_i[-1] - u_o[-1]) ** 2
    length = mesh.total_length_m
    p_cte = p_o_nodes[-1] - rho_f * gravity_m_per_s2 * length + head_loss_pa
    p_i = rho_f * gravity_m_per_s2 * quad.x_m + p_cte
    return FlowField(
        inner_area_m2=a_i, outer_area_m2=a_o, outer_diameter_m=d_o, annulus_area_m2=annulus,
        inner_speed_m_per_s=u_i, annulus_speed_m_per_s=u_o, chi=chi,
        inner_fluid_mass_kg_per_m=rho_f * a_i,
        inner_pressure_gradient_pa_per_m=grad_i, outer_pressure_gradient_pa_per_m=grad_o,
        inner_pressure_pa=p_i, outer_pressure_pa=p_o,
        pressure_constant_pa=float(p_cte), flow_rate_m3_per_s=float(flow))


def _lateral_gram(rows_v, rows_w, coefficient, weight_m):
    return (weighted_gram(rows_v, rows_v, coefficient, weight_m)
            + weighted_gram(rows_w, rows_w, coefficient, weight_m))


def fluid_mass_matrices(config: DrillStringConfig, flow: FlowField,
                        quad: ElementQuadrature) -> np.ndarray:
    """[M_f]^e: (M_f + chi rho_f A_o) on the lateral displacements."""
    coefficient = (flow.inner_fluid_mass_kg_per_m
                   + flow.chi * config.fluid.density_kg_per_m3 * flow.outer_area_m2)[:, None]
    value = quad.rows.value
    return _lateral_gram(value[:, :, sf.FIELD_V], value[:, :, sf.FIELD_W], coefficient,
                         quad.weight_m)


def fluid_stiffness_matrices(config: DrillStringConfig, flow: FlowField,
                             quad: ElementQuadrature) -> np.ndarray:
    """[K_f]^e of Eq. 19 as written (MODEL.md, Table 1 reading, point 5)."""
    rho_f = config.fluid.density_kg_per_m3
    m_f = flow.inner_fluid_mass_kg_per_m[:, None]
    a_i = flow.inner_area_m2[:, None]
    a_o = flow.outer_area_m2[:, None]
    tension_like = (-m_f * flow.inner_speed_m_per_s[:, None] ** 2
                    - a_i * flow.inner_pressure_pa + a_o * flow.outer_pressure_pa
                    - flow.chi[:, None] * rho_f * a_o * flow.annulus_speed_m_per_s[:, None] ** 2)
    rotation_like = (-a_i * flow.inner_pressure_gradient_pa_per_m[:, None]
                     + a_o * flow.outer_pressure_gradient_pa_per_m[:, None])
    slope, value = quad.rows.slope, quad.rows.value
    return (_lateral_gram(slope[:, :, sf.FIELD_V], slope[:, :, sf.FIELD_W], tension_like,
                          quad.weight_m)
            + _lateral_gram(value[:, :, sf.FIELD_THETA_Y], value[:, :, sf.FIELD_THETA_Z],
                            rotation_like, quad.weight_m))


def fluid_viscous_damping_matrices(config: DrillStringConfig, flow: FlowField,
                                   quad: ElementQuadrature) -> np.ndarray:
    """Viscous part of [C_f]^e: (C_f rho_f D_o U_o / 2 + k) on the lateral displacements."""
    fluid = config.fluid
    value = quad.rows.value
    viscous = (0.5 * fluid.drag_coefficient * fluid.density_kg_per_m3 * flow.outer_diameter_m
               * flow.annulus_speed_m_per_s + fluid.viscous_damping_n_s_per_m2)[:, None]
    return _lateral_gram(value[:, :, sf.FIELD_V], value[:, :, sf.FIELD_W], viscous,
                         quad.weight_m)


def coriolis_coefficient(config: DrillStringConfig, flow: FlowField) -> np.ndarray:
    """Return c = 2 M_f U_i - 2 chi rho_f A_o U_o of each element (kg/s)."""
    return (2.0 * flow.inner_fluid_mass_kg_per_m * flow.inner_speed_m_per_s
            - 2.0 * flow.chi * config.fluid.density_kg_per_m3 * flow.outer_area_m2
            * flow.annulus_speed_m_per_s)


def fluid_coriolis_matrices(config: DrillStringConfig, flow: FlowField,
                            quad: ElementQuadrature) -> np.ndarray:
    """Coriolis part of [C_f]^e (see the module docstring for the two forms)."""
    value, slope = quad.rows.value, quad.rows.slope
    c = coriolis_coefficient(config, flow)[:, None]
    if config.fluid.coriolis == 'gyroscopic':
        return sum(weighted_gram(value[:, :, f], slope[:, :, f], c, quad.weight_m)
                   for f in (sf.FIELD_V, sf.FIELD_W))
    return _lateral_gram(value[:, :, sf.FIELD_THETA_Y], value[:, :, sf.FIELD_THETA_Z], -c,
                         quad.weight_m)


def fluid_damping_matrices(config: DrillStringConfig, flow: FlowField,
                           quad: ElementQuadrature) -> np.ndarray:
    """[C_f]^e: viscous lateral damping plus the Coriolis term."""
    return (fluid_viscous_damping_matrices(config, flow, quad)
            + fluid_coriolis_matrices(config, flow, quad))


def fluid_axial_loads(config: DrillStringConfig, flow: FlowField, quad: ElementQuadrature,
                      gravity_m_per_s2: float) -> np.ndarray:
    """f_f^e of Eq. 19 (axial only), shape (n_el, 12), N."""
    rho_f = config.fluid.density_kg_per_m3
    per_length = (flow.inner_fluid_mass_kg_per_m * gravity_m_per_s2
                  - flow.inner_area_m2 * flow.inner_pressure_gradient_pa_per_m
                  - 0.5 * config.fluid.drag_coefficient * rho_f * flow.outer_diameter_m
                  * flow.annulus_speed_m_per_s ** 2)
    rows = quad.rows.value[:, :, sf.FIELD_U]
    return np.einsum('ep,epi->ei', per_length[:, None] * quad.weight_m, rows)
