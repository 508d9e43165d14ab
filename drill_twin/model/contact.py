"""
Impact and rubbing between the string and the borehole wall (Eq. 17-18).

At every node, with r = sqrt(v^2 + w^2) and the clearance c = R_ch - R_o (the paper's
(r - R_ch - R_o) read as r - (R_ch - R_o)), a penetration r > c gives the radial force
F_r = -k_ip (r - c) along (v, w) / r and the rubbing torque T_x = -mu_ip |F_r| R_o sign(theta_x'),
with sign regularised as z / sqrt(z^2 + eps^2). k_ip is applied as a concentrated nodal
stiffness (N/m), as the paper's Sect. 2.4 says ("concentrated forces and torques").

The paper's friction is that torque alone: it brakes the spin but never pushes the string
sideways, so it cannot drive backward whirl. With ``borehole.tangential_friction`` (off by
default) the friction is a force at the contact point instead, as rotordynamics models rub:
F_t = -mu |F_r| sign(s) t on (v, w), with t = (-w, v) / r and s = (v', w') . t + R_o theta_x'
the slip velocity of the pipe's surface on the wall, and its moment T_x = -mu |F_r| R_o
sign(s) (sign regularised with eps R_o). Its power, F_t . (v', w') + T_x theta_x' =
-mu |F_r| s sign(s), is never positive; rolling without slip (s = 0) is the backward whirl
(v', w') . t = -R_o theta_x'.

The kernel runs node by node with the members of the batch as the inner axis; the wall is
touched at a few nodes at most, so its cost is one radius per node and member.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.numerics.compiled import kernel


@dataclass(frozen=True)
class ContactForces:
    """Radial contact force magnitude (N) and contact flags at every node, shape (m, n_nodes)."""

    radial_force_n: np.ndarray
    in_contact: np.ndarray


@kernel
def accumulate_contact(displacement_t, theta_x_rate_t, bending_y_rate_t, bending_z_rate_t,
                       n_nodes, clearance_m, outer_radius_m, stiffness_n_per_m, friction,
                       regularization_rad_per_s, tangential, force_t, radial_force_n,
                       in_contact, tangent):
    """
    force_t += f_ip; returns the number of (member, node) pairs in contact.

    displacement_t, force_t: field-wise DOFs, members last (n_dofs, m); theta_x_rate_t:
    (n_nodes, m); bending_y_rate_t, bending_z_rate_t: the (v, theta_z) and (w, theta_y) rates
    (2 n_nodes, m) (read with ``tangential`` only). Outputs, members first: radial_force_n
    (m, n_nodes) (N), in_contact
    (m, n_nodes), tangent (m, n_nodes, 2, 2): d(-F)/d(v, w), zero off contact.
    """
    members = displacement_t.shape[1]
    v_row, w_row, x_row = 2 * n_nodes, 4 * n_nodes, n_nodes
    eps2 = regularization_rad_per_s ** 2
    touching = 0
    for node in range(n_nodes):
        clearance = clearance_m[node]
        lever = outer_radius_m[node]
        for i in range(members):
            v = displacement_t[v_row + node, i]
            w = displacement_t[w_row + node, i]
            radius = np.sqrt(v * v + w * w)
            penetration = radius - clearance
            if penetration > 0.0:
                touching += 1
                magnitude = stiffness_n_per_m * penetration
                nv, nw = v / radius, w / radius
                force_t[v_row + node, i] += -magnitude * nv
                force_t[w_row + node, i] += -magnitude * nw
                spin = theta_x_rate_t[node, i]
                if tangential:
                    slip = (-nw * bending_y_rate_t[node, i] + nv * bending_z_rate_t[node, i]
                            + lever * spin)
                    smooth_sign = slip / np.sqrt(slip * slip + eps2 * lever * lever)
                    rub = friction * magnitude * smooth_sign
                    force_t[v_row + node, i] += rub * nw
                    force_t[w_row + node, i] += -rub * nv
                else:
                    smooth_sign = spin / np.sqrt(spin * spin + eps2)
                force_t[x_row + node, i] += -friction * magnitude * lever * smooth_sign
                # d(-F)/d(v, w) = k [n n^T + (penetration / r) (I - n n^T)].
                ratio = penetration / radius
                k = stiffness_n_per_m
                radial_force_n[i, node] = magnitude
                in_contact[i, node] = True
                tangent[i, node, 0, 0] = k * (nv * nv + ratio * (1 - nv * nv))
                tangent[i, node, 1, 1] = k * (nw * nw + ratio * (1 - nw * nw))
                tangent[i, node, 0, 1] = k * (1 - ratio) * nv * nw
                tangent[i, node, 1, 0] = tangent[i, node, 0, 1]
            else:
                radial_force_n[i, node] = 0.0
                in_contact[i, node] = False
                for a in range(2):
                    for b in range(2):
                        tangent[i, node, a, b] = 0.0
    return touching


def contact_force(system, stiffness_n_per_m: float, friction: float,
                  regularization_rad_per_s: float, fields, tangential: bool = False):
    """
    (f_ip on the field-wise DOFs (m, n_dofs), ContactForces, tangent).

    tangent: (m, n_nodes, 2, 2) stiffness d(-F)/d(v, w) of every node (zero off contact),
    used by the Newton iteration; None when no node of any member touches the wall.
    """
    displacement_t = np.ascontiguousarray(np.asarray(fields.displacement, dtype=float).T)
    members, nodes = displacement_t.shape[1], system.n_nodes
    force_t = np.zeros_like(displacement_t)
    radial = np.empty((members, nodes))
    flags = np.empty((members, nodes), dtype=bool)
    tangent = np.empty((members, nodes, 2, 2))
    rates = [getattr(fields, name, None) for name in ('bending_y_rate', 'bending_z_rate')]
    rates = [np.zeros((2 * nodes, members)) if r is None
             else np.ascontiguousarray(np.asarray(r, dtype=float).T) for r in rates]
    touching = accumulate_contact(
        displacement_t, np.ascontiguousarray(np.asarray(fields.theta_x_rate, dtype=float).T),
        rates[0], rates[1], nodes,
        system.clearance_m, system.node_outer_radius_m, float(stiffness_n_per_m),
        float(friction), float(regularization_rad_per_s), bool(tangential), force_t, radial,
        flags, tangent)
    return (np.ascontiguousarray(force_t.T), ContactForces(radial, flags),
            tangent if touching else None)
