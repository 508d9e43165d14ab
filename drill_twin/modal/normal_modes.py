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
    """All modes of ([K] + [K_f] + [K_g]) phi = omega^2 ([M] + [M_f]) phi, ascending.

    Attributes:
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


def solve_normal_modes(model: FiniteElementModel) -> NormalModes:
    """Solve Eq. 32 on the free DOFs with a dense symmetric solver (a few hundred DOFs)."""
    free = model.free
    mass = model.total_mass[free][:, free].toarray()
    stiffness = model.total_stiffness[free][:, free].toarray()
    stiffness = 0.5 * (stiffness + stiffness.T)
    eigenvalue, vectors = la.eigh(stiffness, mass)
    shapes = np.zeros((model.n_dofs, eigenvalue.size))
    shapes[free] = vectors

    groups = dof_kind(model.mesh.n_nodes)
    total_mass = model.total_mass
    fractions = np.empty((eigenvalue.size, len(MODE_TYPES)))
    for g in range(len(MODE_TYPES)):
        part = np.where((groups == g)[:, None], shapes, 0.0)
        fractions[:, g] = np.einsum('im,im->m', part, total_mass @ part)
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
