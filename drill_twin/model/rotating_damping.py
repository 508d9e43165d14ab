"""
Rayleigh's stiffness-proportional damping read as internal (rotating) damping.

The paper's damping [C] = alpha (M + M_f) + beta K_t (K_t = K + K_f + K_g) acts on u', the
velocities in the fixed frame. Read as material damping, the beta term acts on the strain
rates of the spinning string, the velocities seen in a frame that turns with it:
u' - Omega J u, J the quarter turn of the lateral DOFs about x (fem/whirl_stability.py). With
``lateral_readings.stiffness_damping: rotating_frame`` the time loop keeps the fixed-frame
[C] u' and adds the circulatory force

    f_i = sum_j beta (K_t J)_ij (Omega_i + Omega_j) / 2 u_j      (lateral rows i, j)

with Omega the local spin (the top drive's speed plus the elastic twist rate, rad/s) at the
nodes of i and j: at a uniform spin it is beta Omega K_t J u exactly, the linearised term of
fem/whirl_stability.py, whose growth rates (forward whirl above Omega* = 2 sqrt(alpha / beta))
test/model/test_rotating_damping.py checks the time loop against; with the spin varying along
the string (stick-slip) every element turns at the mean spin of its nodes. The force is a
compiled kernel called from forces.string_forces, the one sum of the string's forces. What
this reading does at the paper's point: docs/LATERAL.md, "What feeds the lateral modes".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from drill_twin.numerics.compiled import kernel
from drill_twin.fem.whirl_stability import quarter_turn

READINGS = ('fixed_frame', 'rotating_frame')
"""``lateral_readings.stiffness_damping``."""


@dataclass(frozen=True)
class RotatingDampingOperators:
    """
    beta K_t J on the lateral rows of the field-wise DOFs, in CSR, as the kernel takes it.

    on: whether the reading is on (the arrays are empty when off); pointer (rows + 1,),
    column, value: the CSR of rows first_row ... first_row + rows - 1 (v, theta_z, w,
    theta_y, field-wise); n_nodes: the mesh's nodes (a field-wise row's node is row % n_nodes).
    """

    on: bool
    pointer: np.ndarray
    column: np.ndarray
    value: np.ndarray
    first_row: int
    n_nodes: int

    @classmethod
    def of(cls, system) -> 'RotatingDampingOperators':
        model = system.model
        nodes = system.n_nodes
        on = model.config.lateral_readings.stiffness_damping == 'rotating_frame'
        if not on:
            return cls(False, np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64),
                       np.zeros(0), 2 * nodes, nodes)
        beta = model.config.damping.stiffness_coefficient_s
        permutation = system.permutation
        circulatory = (beta * model.total_stiffness @ sp.csr_matrix(quarter_turn(model.n_dofs)))
        lateral = slice(2 * nodes, 6 * nodes)                 # v, theta_z, w, theta_y rows
        matrix = sp.csr_matrix(circulatory)[permutation][:, permutation][lateral]
        matrix.eliminate_zeros()
        matrix.sort_indices()
        return cls(True, matrix.indptr.astype(np.int64), matrix.indices.astype(np.int64),
                   matrix.data.astype(float), 2 * nodes, nodes)

    def arguments(self) -> tuple:
        """Return the kernel's operands, in its order (``on`` first)."""
        return (self.on, self.pointer, self.column, self.value, self.first_row, self.n_nodes)


@kernel
def accumulate_rotating_damping(arguments, displacement_t, theta_x_rate_t, force_t):
    """
    force_t += the circulatory force of the module docstring, members last.

    arguments: :meth:`RotatingDampingOperators.arguments`; displacement_t, force_t
    (n_dofs, m); theta_x_rate_t: the local spin, (n_nodes, m) (rad/s).
    """
    _, pointer, column, value, first_row, n_nodes = arguments
    members = displacement_t.shape[1]
    for r in range(pointer.shape[0] - 1):
        row = first_row + r
        a = row % n_nodes
        for j in range(pointer[r], pointer[r + 1]):
            c = column[j]
            b = c % n_nodes
            half = 0.5 * value[j]
            for i in range(members):
                force_t[row, i] += (half * (theta_x_rate_t[a, i] + theta_x_rate_t[b, i])
                                    * displacement_t[c, i])


def rotating_damping_force(system, displacement: np.ndarray, theta_x_rate: np.ndarray,
                           operators: RotatingDampingOperators | None = None) -> np.ndarray:
    """
    Return the circulatory force on the field-wise DOFs, (m, n_dofs) (zero when off).

    displacement: u (m, n_dofs); theta_x_rate: the local spin (m, n_nodes) (rad/s).
    """
    operators = operators or RotatingDampingOperators.of(system)
    displacement_t = np.ascontiguousarray(np.asarray(displacement, dtype=float).T)
    force_t = np.zeros_like(displacement_t)
    if operators.on:
        accumulate_rotating_damping(operators.arguments(), displacement_t,
                                    np.ascontiguousarray(np.asarray(theta_x_rate,
                                                                    dtype=float).T), force_t)
    return np.ascontiguousarray(force_t.T)
