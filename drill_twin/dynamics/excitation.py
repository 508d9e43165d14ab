"""Lateral excitation that real drill strings have and the paper leaves out (issue 12, Sect. 2).

Mass imbalance / bent-collar eccentricity. A mass m (already counted in the string's mass)
has its centre at e from the axis of the node it sits on, in a direction fixed to the
section: at the local spin angle theta = theta_x of the node (the top-drive angle plus the
elastic twist) from the y axis. Its position in the (y, z) plane is
(v + e cos theta, w + e sin theta), so its kinetic energy exceeds that of the same mass on
the axis by

    T_e = m e theta' (w' cos theta - v' sin theta) + m e^2 theta'^2 / 2.

Lagrange's equations give the generalised forces (moved to the right-hand side):

    on v:       m e (theta'^2 cos theta + theta'' sin theta)
    on w:       m e (theta'^2 sin theta - theta'' cos theta)
    on theta_x: m e (v'' sin theta - w'' cos theta) - m e^2 theta''

the rotating force m e theta'^2 plus its tangential part m e theta'', and the torque that
takes the work they do on the lateral motion from the torsion (so energy balances: the top
drive pays for the whirl). The force turns with the local spin, so it follows the
stick-slip. It depends on accelerations and is evaluated with the other non-linear forces
(fixed point of the Newmark iteration); it is small against the string's inertia.
"""
from __future__ import annotations

import numpy as np

from drill_twin.config.schema import Imbalance


class ImbalanceForce:
    """The generalised force of one eccentric mass, on the field-wise DOFs of a system.

    Attributes: node (index), depth_m (x of that node, m), unbalance_kg_m (m e),
    inertia_kg_m2 (m e^2), and the field-wise rows of theta_x, v and w at the node.
    """

    def __init__(self, system, imbalance: Imbalance):
        mesh = system.model.mesh
        self.node = mesh.nearest_node(imbalance.position_m)
        self.depth_m = float(mesh.node_x_m[self.node])
        self.unbalance_kg_m = float(imbalance.mass_kg * imbalance.eccentricity_m)
        self.inertia_kg_m2 = self.unbalance_kg_m * float(imbalance.eccentricity_m)
        self.theta_x_row = system.field(1).start + self.node
        self.v_row = system.field(2).start + self.node
        self.w_row = system.field(4).start + self.node

    @classmethod
    def of(cls, system) -> 'ImbalanceForce | None':
        """The imbalance of ``system``'s configuration, or None when it is disabled."""
        imbalance = system.model.config.excitation.imbalance
        if not imbalance.enabled or imbalance.mass_kg * imbalance.eccentricity_m == 0.0:
            return None
        return cls(system, imbalance)

    def angle_rad(self, fields) -> np.ndarray:
        """Local spin angle theta_x of the node (top-drive angle + twist), (m,) (rad)."""
        return fields.top_angle_rad + fields.displacement[:, self.theta_x_row]

    def components(self, fields) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(F_v, F_w, T_x) of a batch, each (m,) (N, N, N m); ``fields`` a Kinematics."""
        node = self.node
        angle = self.angle_rad(fields)
        cos, sin = np.cos(angle), np.sin(angle)
        rate = fields.theta_x_rate[:, node]
        acceleration = fields.theta_x_acceleration[:, node]
        v_acceleration = fields.bending_y_acceleration[:, node]
        w_acceleration = fields.bending_z_acceleration[:, node]
        me = self.unbalance_kg_m
        centripetal = me * rate * rate
        tangential = me * acceleration
        force_v = centripetal * cos + tangential * sin
        force_w = centripetal * sin - tangential * cos
        torque = me * (v_acceleration * sin - w_acceleration * cos) \
            - self.inertia_kg_m2 * acceleration
        return force_v, force_w, torque

    def accumulate(self, fields, force_t: np.ndarray) -> None:
        """force_t += the imbalance's force; force_t field-wise, members last (n_dofs, m)."""
        force_v, force_w, torque = self.components(fields)
        force_t[self.v_row] += force_v
        force_t[self.w_row] += force_w
        force_t[self.theta_x_row] += torque

    def force(self, system, fields) -> np.ndarray:
        """The force on the field-wise DOFs, (m, n_dofs)."""
        force_t = np.zeros((system.n_dofs, fields.displacement.shape[0]))
        self.accumulate(fields, force_t)
        return force_t.T
