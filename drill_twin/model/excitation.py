"""
Lateral excitation that real drill strings have and the paper leaves out (docs/LATERAL.md).

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
stick-slip. It is evaluated with the other non-linear forces; being linear in the node's
accelerations, -A (v'', w'', theta_x''), its inertia A also enters the Newmark step's Newton
matrix (Woodbury, :mod:`~drill_twin.integrator.woodbury`): as a fixed point alone
it would cost three iterations a step (20 % of the collars' local polar inertia for 1000 kg at
5 cm).

One implementation: the compiled :func:`accumulate_imbalance`, called from
``forces.string_forces`` (the one sum of the string's forces, used by
``NonlinearForces.evaluate`` and by the compiled Newmark step). Its operands are one tuple,
:meth:`ImbalanceForce.arguments` (the same types whether the imbalance is on or off, so the
kernels are compiled once; off, nothing is evaluated). The top-drive angle changes every step:
it is a one-element state array of that tuple, written by whoever evaluates the forces
(``ImbalanceForce.set_top_angle``). In the Newmark step the node's w'' is not among the
kinematics the other forces read; :func:`imbalance_node_acceleration` computes that one row
from the reduced accelerations, only when the imbalance is on.
"""
from __future__ import annotations

import numpy as np

from drill_twin.config.schema import Imbalance
from drill_twin.numerics.compiled import inline, kernel

NODE, THETA_X_ROW, V_ROW, W_ROW = range(4)
"""Positions in the index array of the operands: the node, its theta_x, v and w DOF rows."""


@kernel
def accumulate_imbalance(imbalance, displacement_t, theta_x_rate_t, theta_x_acceleration_t,
                         bending_y_acceleration_t, bending_z_acceleration_t, force_t):
    """
    force_t += the imbalance's (F_v, F_w, T_x) at its node, members last.

    imbalance: :meth:`ImbalanceForce.arguments`; displacement_t, force_t: field-wise DOFs
    (n_dofs, m) (displacement without the driven angle); theta_x rates and accelerations
    (n_nodes, m) (with the driven rotation); bending accelerations: (v, theta_z) and
    (w, theta_y), (2 n_nodes, m) (only the node's v and w rows are read).
    """
    indices, constants, top_angle = imbalance[1], imbalance[2], imbalance[3]
    node = indices[NODE]
    x_row, v_row, w_row = indices[THETA_X_ROW], indices[V_ROW], indices[W_ROW]
    me, inertia = constants[0], constants[1]
    for i in range(displacement_t.shape[1]):
        angle = top_angle[0] + displacement_t[x_row, i]
        cos, sin = np.cos(angle), np.sin(angle)
        rate = theta_x_rate_t[node, i]
        acceleration = theta_x_acceleration_t[node, i]
        centripetal = me * rate * rate
        tangential = me * acceleration
        force_t[v_row, i] += centripetal * cos + tangential * sin
        force_t[w_row, i] += centripetal * sin - tangential * cos
        force_t[x_row, i] += (me * (bending_y_acceleration_t[node, i] * sin
                                    - bending_z_acceleration_t[node, i] * cos)
                              - inertia * acceleration)


@inline
def imbalance_node_acceleration(imbalance, a, bending_z_acceleration_t):
    """
    Set bending_z_acceleration_t[node] = w'' of the imbalance's node.

    w'' is computed from the reduced accelerations a (n, m), members last (the other rows are
    left as they are).
    """
    node, w_shape, first = imbalance[1][NODE], imbalance[4], imbalance[5]
    for i in range(a.shape[1]):
        total = 0.0
        for j in range(w_shape.shape[0]):
            total += w_shape[j] * a[first + j, i]
        bending_z_acceleration_t[node, i] = total


class ImbalanceForce:
    """
    The generalised force of one eccentric mass, on the field-wise DOFs of a system.

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
        self._arguments = _arguments(True, system, self.node,
                                     (self.theta_x_row, self.v_row, self.w_row),
                                     (self.unbalance_kg_m, self.inertia_kg_m2))

    @classmethod
    def of(cls, system) -> 'ImbalanceForce | None':
        """Return the imbalance of ``system``'s configuration, or None when it is disabled."""
        imbalance = system.model.config.excitation.imbalance
        if not imbalance.enabled or imbalance.mass_kg * imbalance.eccentricity_m == 0.0:
            return None
        return cls(system, imbalance)

    @staticmethod
    def arguments_of(force: 'ImbalanceForce | None', system) -> tuple:
        """
        Return the kernels' operand tuple of ``force``, or an inert one.

        The inert one (same types, flag off) is returned when there is no imbalance.
        """
        if force is not None:
            return force.arguments()
        return _arguments(False, system, 0, (0, 0, 0), (0.0, 0.0))

    def arguments(self) -> tuple:
        """
        Return what :func:`accumulate_imbalance` and :func:`imbalance_node_acceleration` take.

        (on, indices (node, theta_x, v, w rows) int64 (4,), (m e, m e^2) (2,), top-drive
        angle (1,) (rad, a state array), Phi_z row of the node's w (n_z,), first bending-z
        column).
        """
        return self._arguments

    def set_top_angle(self, angle_rad: float) -> None:
        """Set the top-drive angle (rad) the next evaluation adds to the node's twist."""
        self._arguments[3][0] = angle_rad

    def angle_rad(self, fields) -> np.ndarray:
        """Local spin angle theta_x of the node (top-drive angle + twist), (m,) (rad)."""
        return fields.top_angle_rad + fields.displacement[:, self.theta_x_row]

    def force(self, system, fields) -> np.ndarray:
        """
        Return the force on the field-wise DOFs, (m, n_dofs).

        ``fields`` a forces.Kinematics (with bending_z_acceleration and top_angle_rad).
        """
        if fields.bending_z_acceleration is None:
            raise ValueError('the imbalance needs the kinematics\' bending_z_acceleration')
        self.set_top_angle(fields.top_angle_rad)
        displacement_t = _members_last(fields.displacement)
        force_t = np.zeros_like(displacement_t)
        accumulate_imbalance(self._arguments, displacement_t,
                             _members_last(fields.theta_x_rate),
                             _members_last(fields.theta_x_acceleration),
                             _members_last(fields.bending_y_acceleration),
                             _members_last(fields.bending_z_acceleration), force_t)
        return np.ascontiguousarray(force_t.T)


def _arguments(on: bool, system, node: int, rows, constants) -> tuple:
    block = system.blocks['bending_z']
    w_shape = np.ascontiguousarray(block.shapes[node], dtype=float)
    return (bool(on), np.array((node, *rows), dtype=np.int64),
            np.array(constants, dtype=float), np.zeros(1), w_shape,
            int(block.columns.start))


def _members_last(array) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(array, dtype=float).T)
