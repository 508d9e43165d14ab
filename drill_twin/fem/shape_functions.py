"""
Shape functions of the two-node Timoshenko element (paper Appendix A).

Axial displacement u and torsion theta_x are linear; the lateral fields use the
shear-corrected cubic functions with phi = 12 E I / (k_s G A l_e^2). ``w`` and
``theta_y`` take the sign flips that follow from theta_y = -dw/dx, theta_z = +dv/dx.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.fem import dofs

# Field numbering of the rows returned below.
FIELD_U, FIELD_V, FIELD_W, FIELD_THETA_X, FIELD_THETA_Y, FIELD_THETA_Z = range(6)
N_FIELDS = 6

GAUSS_POINTS = 4
"""Gauss-Legendre points per element: exact for the mass (degree 6) and for K, K_g, K_f."""


def gauss_legendre_unit(n: int = GAUSS_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights of n-point Gauss-Legendre quadrature on [0, 1]."""
    points, weights = np.polynomial.legendre.leggauss(n)
    return 0.5 * (points + 1.0), 0.5 * weights


@dataclass(frozen=True)
class FieldRows:
    """
    Interpolation rows: field f at point p of element e is ``value[e, p, f] @ u_e``.

    value, slope: shape (n_elements, n_points, 6, 12); slope is d/dx (1/m).
    """

    value: np.ndarray
    slope: np.ndarray


def field_rows(xi: np.ndarray, length_m: np.ndarray, phi: np.ndarray) -> FieldRows:
    """
    Rows of the six fields and of their x-derivatives at local coordinates ``xi``.

    :param xi: local coordinates in [0, 1], shape (n_points,).
    :param length_m: element lengths, shape (n_elements,).
    :param phi: Timoshenko shear parameter of each element, shape (n_elements,).
    """
    xi = np.asarray(xi, dtype=float)[None, :]
    le = np.asarray(length_m, dtype=float)[:, None]
    ph = np.asarray(phi, dtype=float)[:, None]
    d = 1.0 + ph
    n_el, n_pt = le.shape[0], xi.shape[1]

    nv1 = (1 - 3 * xi**2 + 2 * xi**3 + ph * (1 - xi)) / d
    nv2 = le * (xi - 2 * xi**2 + xi**3 + ph * (xi - xi**2) / 2) / d
    nv3 = (3 * xi**2 - 2 * xi**3 + ph * xi) / d
    nv4 = le * (-xi**2 + xi**3 + ph * (xi**2 - xi) / 2) / d
    nt1 = (-6 * xi + 6 * xi**2) / (d * le)
    nt2 = (1 - 4 * xi + 3 * xi**2 + ph * (1 - xi)) / d
    nt3 = (6 * xi - 6 * xi**2) / (d * le)
    nt4 = (-2 * xi + 3 * xi**2 + ph * xi) / d
    # d/dxi
    dnv1 = (-6 * xi + 6 * xi**2 - ph) / d
    dnv2 = le * (1 - 4 * xi + 3 * xi**2 + ph * (1 - 2 * xi) / 2) / d
    dnv3 = (6 * xi - 6 * xi**2 + ph) / d
    dnv4 = le * (-2 * xi + 3 * xi**2 + ph * (2 * xi - 1) / 2) / d
    dnt1 = (-6 + 12 * xi) / (d * le)
    dnt2 = (-4 + 6 * xi - ph) / d
    dnt3 = (6 - 12 * xi) / (d * le)
    dnt4 = (-2 + 6 * xi + ph) / d
    lin1 = np.broadcast_to(1 - xi, (n_el, n_pt))
    lin2 = np.broadcast_to(xi, (n_el, n_pt))
    dlin1 = np.broadcast_to(-1.0 + 0 * xi, (n_el, n_pt))
    dlin2 = np.broadcast_to(1.0 + 0 * xi, (n_el, n_pt))

    value = np.zeros((n_el, n_pt, N_FIELDS, 12))
    slope = np.zeros((n_el, n_pt, N_FIELDS, 12))
    node2 = dofs.DOFS_PER_NODE

    def put(target, field, local_dofs, functions):
        for local, function in zip(local_dofs, functions):
            target[:, :, field, local] = function

    ends = (dofs.U, dofs.U + node2)
    put(value, FIELD_U, ends, (lin1, lin2))
    put(slope, FIELD_U, ends, (dlin1, dlin2))
    ends = (dofs.THETA_X, dofs.THETA_X + node2)
    put(value, FIELD_THETA_X, ends, (lin1, lin2))
    put(slope, FIELD_THETA_X, ends, (dlin1, dlin2))
    plane_v = (dofs.V, dofs.THETA_Z, dofs.V + node2, dofs.THETA_Z + node2)
    put(value, FIELD_V, plane_v, (nv1, nv2, nv3, nv4))
    put(slope, FIELD_V, plane_v, (dnv1, dnv2, dnv3, dnv4))
    put(value, FIELD_THETA_Z, plane_v, (nt1, nt2, nt3, nt4))
    put(slope, FIELD_THETA_Z, plane_v, (dnt1, dnt2, dnt3, dnt4))
    plane_w = (dofs.W, dofs.THETA_Y, dofs.W + node2, dofs.THETA_Y + node2)
    put(value, FIELD_W, plane_w, (nv1, -nv2, nv3, -nv4))
    put(slope, FIELD_W, plane_w, (dnv1, -dnv2, dnv3, -dnv4))
    put(value, FIELD_THETA_Y, plane_w, (-nt1, nt2, -nt3, nt4))
    put(slope, FIELD_THETA_Y, plane_w, (-dnt1, dnt2, -dnt3, dnt4))
    slope /= le[:, :, None, None]
    return FieldRows(value=value, slope=slope)
