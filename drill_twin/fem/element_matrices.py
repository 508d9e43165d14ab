"""Structural element matrices, computed for all elements at once, shape (n_el, 12, 12)."""
from __future__ import annotations

import numpy as np

from drill_twin.fem import shape_functions as sf
from drill_twin.fem.mesh import Mesh
from drill_twin.fem.quadrature import ElementQuadrature


def weighted_gram(rows_a: np.ndarray, rows_b: np.ndarray, coefficient: np.ndarray,
                  weight_m: np.ndarray) -> np.ndarray:
    """
    Sum over points of coefficient * weight * a^T b.

    rows_a, rows_b: (n_el, n_points, 12); coefficient, weight_m: (n_el, n_points) or
    broadcastable. Returns (n_el, 12, 12).
    """
    scale = np.broadcast_to(coefficient * weight_m, weight_m.shape)
    return np.einsum('ep,epi,epj->eij', scale, rows_a, rows_b)


def mass_matrices(mesh: Mesh, quad: ElementQuadrature) -> np.ndarray:
    """Consistent mass of Eq. 10: rho A (u, v, w), rho I (theta_y, theta_z), rho I_p theta_x."""
    value = quad.rows.value
    rho = mesh.density_kg_per_m3[:, None]
    rho_a = rho * mesh.area_m2[:, None]
    rho_i = rho * mesh.inertia_m4[:, None]
    rho_ip = rho * mesh.polar_inertia_m4[:, None]
    w = quad.weight_m
    mass = np.zeros((mesh.n_elements, 12, 12))
    for field, coefficient in ((sf.FIELD_U, rho_a), (sf.FIELD_V, rho_a), (sf.FIELD_W, rho_a),
                               (sf.FIELD_THETA_Y, rho_i), (sf.FIELD_THETA_Z, rho_i),
                               (sf.FIELD_THETA_X, rho_ip)):
        rows = value[:, :, field]
        mass += weighted_gram(rows, rows, coefficient, w)
    return mass


def stiffness_from_tangent(tangent: np.ndarray, quad: ElementQuadrature) -> np.ndarray:
    """K_e = sum_p w_p B_p^T D_p B_p for a section tangent D of shape (n_el, n_pts, 8, 8)."""
    b = quad.strain_rows
    return np.einsum('ep,epki,epkl,eplj->eij', quad.weight_m, b, tangent, b)
