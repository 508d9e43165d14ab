"""The generalized eigenproblem (Eq. 32) and the classification of its modes."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la

from drill_twin.fem.boundary import expected_rigid_modes
from drill_twin.fem.dofs import dof_kind
from drill_twin.fem.model import FiniteElementModel

MODE_TYPES = ('axial', 'torsional', 'lateral')


@dataclass(frozen=True)
class NormalModes:
    """
    All modes of ([K] + [K_f] + [K_g]) phi = omega^2 ([M] + [M_f]) phi, ascending.

    Fields:
        eigenvalue: omega^2 (rad^2/s^2), shape (n_modes,).
        frequency_hz: omega / 2 pi (0 for rigid and for negative eigenvalues).
        shapes: mass-normalised shapes on the full DOF set, shape (n_dofs, n_modes).
        kind: 'axial', 'torsional' or 'lateral' (where the kinetic energy lies).
        energy_fraction: kinetic-energy fraction per type (columns as MODE_TYPES),
            shape (n_modes, 3).
        rigid: True for the zero-frequency (rigid-body) modes.
    """

    eigenvalue: np.ndarray
    frequency_hz: np.ndarray
    shapes: np.ndarray
    kind: np.ndarray
    energy_fraction: np.ndarray
    rigid: np.ndarray


def _dof_groups(model: FiniteElementModel) -> list[tuple[str, np.ndarray]]:
    """Free DOFs of each uncoupled group: axial, torsion, bending in (x, y), bending in (x, z)."""
    from drill_twin.fem import dofs

    local = np.arange(model.n_dofs) % dofs.DOFS_PER_NODE
    free = np.zeros(model.n_dofs, dtype=bool)
    free[model.free] = True
    groups = [('axial', (dofs.U,)), ('torsional', (dofs.THETA_X,)),
              ('lateral', (dofs.V, dofs.THETA_Z)), ('lateral', (dofs.W, dofs.THETA_Y))]
    return [(kind, np.flatnonzero(free & np.isin(local, members))) for kind, members in groups]


def _groups_are_uncoupled(matrix, groups) -> bool:
    label = np.full(matrix.shape[0], -1)
    for number, (_, index) in enumerate(groups):
        label[index] = number
    coo = matrix.tocoo()
    inside = (label[coo.row] >= 0) & (label[coo.col] >= 0)
    cross = inside & (label[coo.row] != label[coo.col])
    scale = np.max(np.abs(coo.data)) if coo.nnz else 0.0
    return not np.any(np.abs(coo.data[cross]) > 1e-12 * scale)


def solve_normal_modes(model: FiniteElementModel) -> NormalModes:
    """
    Solve Eq. 32 on the free DOFs with a dense symmetric solver (a few hundred DOFs).

    The linearised, prestressed string does not couple axial, torsional and the two planes
    of bending motion: when the matrices confirm it, each group is solved on its own, so
    that every lateral mode lies in one plane (a degenerate pair is not an arbitrary mix of
    the two). Otherwise the coupled problem is solved as a whole.
    """
    free = model.free
    mass_full = model.total_mass
    stiffness_full = model.total_stiffness
    groups = _dof_groups(model)
    if _groups_are_uncoupled(stiffness_full, groups) and _groups_are_uncoupled(mass_full, groups):
        blocks = [(index, *_eigh(stiffness_full, mass_full, index)) for _, index in groups]
    else:
        blocks = [(free, *_eigh(stiffness_full, mass_full, free))]
    eigenvalue = np.concatenate([values for _, values, _ in blocks])
    shapes = np.zeros((model.n_dofs, eigenvalue.size))
    start = 0
    for index, values, vectors in blocks:
        shapes[index, start:start + values.size] = vectors
        start += values.size
    order = np.argsort(eigenvalue, kind='stable')
    eigenvalue, shapes = eigenvalue[order], shapes[:, order]

    groups_of_dofs = dof_kind(model.mesh.n_nodes)
    fractions = np.empty((eigenvalue.size, len(MODE_TYPES)))
    for g in range(len(MODE_TYPES)):
        part = np.where((groups_of_dofs == g)[:, None], shapes, 0.0)
        fractions[:, g] = np.einsum('im,im->m', part, mass_full @ part)
    fractions /= fractions.sum(axis=1, keepdims=True)
    kind = np.array(MODE_TYPES)[np.argmax(fractions, axis=1)]

    rigid = np.zeros(eigenvalue.size, dtype=bool)
    for name, count in expected_rigid_modes(model.config.boundary).items():
        if count:
            rigid[np.flatnonzero(kind == name)[:count]] = True
    scale = np.max(np.abs(eigenvalue))
    if np.any(np.abs(eigenvalue[rigid]) > 1e-8 * scale):
        raise RuntimeError('a mode expected to be rigid has a non-zero frequency')
    frequency = np.sqrt(np.clip(eigenvalue, 0.0, None)) / (2.0 * np.pi)
    frequency[rigid] = 0.0
    return NormalModes(eigenvalue=eigenvalue, frequency_hz=frequency, shapes=shapes,
                       kind=kind, energy_fraction=fractions, rigid=rigid)


def _eigh(stiffness, mass, index):
    k = stiffness[index][:, index].toarray()
    m = mass[index][:, index].toarray()
    return la.eigh(0.5 * (k + k.T), 0.5 * (m + m.T))
