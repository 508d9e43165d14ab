"""Boundary conditions: which DOFs are removed from the system (Sect. 2.7)."""
from __future__ import annotations

import numpy as np

from drill_twin.config.schema import Boundary
from drill_twin.fem import dofs

_LATERAL = {'clamped': (dofs.V, dofs.W, dofs.THETA_Y, dofs.THETA_Z),
            'pinned': (dofs.V, dofs.W),
            'free': ()}


def constrained_dofs(boundary: Boundary, n_nodes: int) -> np.ndarray:
    """
    Sorted global indices of the DOFs held at zero.

    The top rotation is held when ``top_torsion`` is ``driven``: the imposed rotation is
    then carried by a separate rigid-rotation shape, not by the free DOFs.
    """
    top, bit = 0, n_nodes - 1
    held = []
    if boundary.top_axial == 'fixed':
        held.append(dofs.node_dof(top, dofs.U))
    if boundary.top_torsion == 'driven':
        held.append(dofs.node_dof(top, dofs.THETA_X))
    held += [dofs.node_dof(top, d) for d in _LATERAL[boundary.top_lateral]]
    if boundary.bit_axial == 'fixed':
        held.append(dofs.node_dof(bit, dofs.U))
    if boundary.bit_torsion == 'fixed':
        held.append(dofs.node_dof(bit, dofs.THETA_X))
    held += [dofs.node_dof(bit, d) for d in _LATERAL[boundary.bit_lateral]]
    return np.array(sorted(set(int(h) for h in held)), dtype=int)


def free_dofs(constrained: np.ndarray, n_dofs: int) -> np.ndarray:
    """Return the DOFs that are not constrained, sorted."""
    mask = np.ones(n_dofs, dtype=bool)
    mask[constrained] = False
    return np.flatnonzero(mask)


def expected_rigid_modes(boundary: Boundary) -> dict[str, int]:
    """Zero-frequency modes the eigenproblem must have, by type."""
    axial = int(boundary.top_axial == 'free' and boundary.bit_axial == 'free')
    torsional = int(boundary.top_torsion == 'free' and boundary.bit_torsion == 'free')
    lateral = 0
    if boundary.top_lateral == 'free' and boundary.bit_lateral == 'free':
        lateral = 4
    elif 'free' in (boundary.top_lateral, boundary.bit_lateral):
        other = boundary.bit_lateral if boundary.top_lateral == 'free' else boundary.top_lateral
        lateral = 2 if other == 'pinned' else 0
    return {'axial': axial, 'torsional': torsional, 'lateral': lateral}
