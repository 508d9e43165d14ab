"""Gauss points of every element with their shape-function and strain rows."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.fem import shape_functions as sf
from drill_twin.fem import strain_energy as se
from drill_twin.fem.mesh import Mesh


@dataclass(frozen=True)
class ElementQuadrature:
    """
    Quadrature data of all elements.

    Fields:
        xi: local coordinates of the points, shape (n_points,).
        weight_m: quadrature weight times element length, shape (n_el, n_points) (m).
        x_m: position of each point along the string, shape (n_el, n_points) (m).
        rows: field rows at the points (see :class:`~drill_twin.fem.shape_functions.FieldRows`).
        strain_rows: generalized-strain rows B, shape (n_el, n_points, 8, 12): g = B u_e.
    """

    xi: np.ndarray
    weight_m: np.ndarray
    x_m: np.ndarray
    rows: sf.FieldRows
    strain_rows: np.ndarray


def strain_rows(rows: sf.FieldRows) -> np.ndarray:
    """B such that g = B u_e, g = (u', v', w', theta_y', theta_z', theta_x', theta_y, theta_z)."""
    n_el, n_pt = rows.value.shape[:2]
    b = np.empty((n_el, n_pt, se.N_STRAINS, 12))
    b[:, :, se.E_AXIAL] = rows.slope[:, :, sf.FIELD_U]
    b[:, :, se.A_SLOPE_V] = rows.slope[:, :, sf.FIELD_V]
    b[:, :, se.B_SLOPE_W] = rows.slope[:, :, sf.FIELD_W]
    b[:, :, se.KAPPA_Y] = rows.slope[:, :, sf.FIELD_THETA_Y]
    b[:, :, se.KAPPA_Z] = rows.slope[:, :, sf.FIELD_THETA_Z]
    b[:, :, se.TAU] = rows.slope[:, :, sf.FIELD_THETA_X]
    b[:, :, se.THETA_Y] = rows.value[:, :, sf.FIELD_THETA_Y]
    b[:, :, se.THETA_Z] = rows.value[:, :, sf.FIELD_THETA_Z]
    return b


def build_quadrature(mesh: Mesh, n_points: int = sf.GAUSS_POINTS) -> ElementQuadrature:
    """Gauss-Legendre quadrature of every element of ``mesh``."""
    xi, weights = sf.gauss_legendre_unit(n_points)
    rows = sf.field_rows(xi, mesh.length_m, mesh.timoshenko_phi())
    return ElementQuadrature(
        xi=xi,
        weight_m=weights[None, :] * mesh.length_m[:, None],
        x_m=mesh.node_x_m[:-1, None] + xi[None, :] * mesh.length_m[:, None],
        rows=rows,
        strain_rows=strain_rows(rows),
    )
