"""
Degree-of-freedom numbering: 6 per node, ordered as in the paper (Eq. 5).

Node n owns global DOFs 6 n + (u, v, theta_z, w, theta_y, theta_x). Element e joins nodes
e and e + 1; its 12 local DOFs are those of node e followed by those of node e + 1.
"""
from __future__ import annotations

import numpy as np

DOFS_PER_NODE = 6
U, V, THETA_Z, W, THETA_Y, THETA_X = range(DOFS_PER_NODE)

AXIAL_DOFS = (U,)
TORSIONAL_DOFS = (THETA_X,)
LATERAL_DOFS = (V, THETA_Z, W, THETA_Y)


def node_dof(node: int | np.ndarray, local: int) -> int | np.ndarray:
    """Global index of DOF ``local`` of ``node``."""
    return DOFS_PER_NODE * node + local


def element_dof_map(n_elements: int) -> np.ndarray:
    """Global DOF indices of every element, shape (n_elements, 12)."""
    first = DOFS_PER_NODE * np.arange(n_elements)[:, None]
    return first + np.arange(2 * DOFS_PER_NODE)[None, :]


def dof_kind(n_nodes: int) -> np.ndarray:
    """Per global DOF: 0 axial, 1 torsional, 2 lateral. Shape (6 n_nodes,)."""
    kind = np.full(DOFS_PER_NODE, 2)
    kind[U] = 0
    kind[THETA_X] = 1
    return np.tile(kind, n_nodes)
