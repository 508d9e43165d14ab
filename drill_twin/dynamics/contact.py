"""Impact and rubbing between the string and the borehole wall (Eq. 17-18).

At every node, with r = sqrt(v^2 + w^2) and the clearance c = R_ch - R_o (the paper's
(r - R_ch - R_o) read as r - (R_ch - R_o)), a penetration r > c gives the radial force
F_r = -k_ip (r - c) along (v, w) / r and the rubbing torque T_x = -mu_ip |F_r| R_o sign(theta_x'),
with sign regularised as z / sqrt(z^2 + eps^2). k_ip is applied as a concentrated nodal
stiffness (N/m), as the paper's Sect. 2.4 says ("concentrated forces and torques").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ContactForces:
    """Radial contact force magnitude (N) and contact flags at every node, shape (m, n_nodes)."""

    radial_force_n: np.ndarray
    in_contact: np.ndarray


def contact_force(system, stiffness_n_per_m: float, friction: float,
                  regularization_rad_per_s: float, fields):
    """(f_ip on the field-wise DOFs (m, n_dofs), ContactForces, tangent).

    tangent: (m, n_nodes, 2, 2) stiffness d(-F)/d(v, w) of every node (zero off contact),
    used by the Newton iteration.
    """
    u = fields.displacement
    v_slice, w_slice = system.field(2), system.field(4)
    v, w = u[:, v_slice], u[:, w_slice]
    radius = np.sqrt(v * v + w * w)
    penetration = radius - system.clearance_m
    in_contact = penetration > 0.0
    force = np.zeros_like(u)
    tangent = None
    if not in_contact.any():
        return force, ContactForces(np.zeros_like(radius), in_contact), tangent
    safe_radius = np.where(in_contact, radius, 1.0)
    magnitude = np.where(in_contact, stiffness_n_per_m * penetration, 0.0)
    nv, nw = v / safe_radius, w / safe_radius
    force[:, v_slice] = -magnitude * nv
    force[:, w_slice] = -magnitude * nw
    spin = fields.theta_x_rate
    smooth_sign = spin / np.sqrt(spin * spin + regularization_rad_per_s ** 2)
    force[:, system.field(1)] = (-friction * magnitude * system.node_outer_radius_m
                                 * smooth_sign)
    # d(-F)/d(v, w) = k [n n^T + (penetration / r) (I - n n^T)] on contact.
    ratio = np.where(in_contact, penetration / safe_radius, 0.0)
    k = np.where(in_contact, stiffness_n_per_m, 0.0)
    tangent = np.empty(radius.shape + (2, 2))
    tangent[..., 0, 0] = k * (nv * nv + ratio * (1 - nv * nv))
    tangent[..., 1, 1] = k * (nw * nw + ratio * (1 - nw * nw))
    tangent[..., 0, 1] = tangent[..., 1, 0] = k * (1 - ratio) * nv * nw
    return force, ContactForces(magnitude, in_contact), tangent
