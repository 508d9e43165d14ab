"""The reduced basis [Phi] (Eq. 33) and the reduced matrices (Eq. 36)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.config.schema import ReducedBasis as BasisCounts
from drill_twin.fem.model import FiniteElementModel
from drill_twin.modal.normal_modes import NormalModes


@dataclass(frozen=True)
class ReducedBasis:
    """
    Columns of [Phi]: the rigid modes first, then the kept modes by frequency.

    Fields:
        shapes: [Phi], shape (n_dofs, n_basis); mass-normalised.
        frequency_hz, kind, rigid: per column.
        rank: 1-based rank of each elastic column among the elastic columns (0 if rigid);
            the numbering of the paper's Table 1.
        driven_rotation: the imposed rigid rotation psi (theta_x = 1 everywhere), which
            is not a column: its amplitude is the top-drive angle.
        rigid_body_modes: rigid columns plus the driven rotation.
    """

    shapes: np.ndarray
    frequency_hz: np.ndarray
    kind: np.ndarray
    rigid: np.ndarray
    rank: np.ndarray
    driven_rotation: np.ndarray
    rigid_body_modes: int

    @property
    def size(self) -> int:
        return self.shapes.shape[1]

    def count(self, kind: str) -> int:
        """Count the elastic columns of one type."""
        return int(np.sum((self.kind == kind) & ~self.rigid))


def select_basis(model: FiniteElementModel, modes: NormalModes,
                 counts: BasisCounts) -> ReducedBasis:
    """Keep the rigid modes and the lowest ``counts`` modes of each type."""
    wanted = {'lateral': counts.lateral_modes, 'torsional': counts.torsional_modes,
              'axial': counts.axial_modes}
    chosen = list(np.flatnonzero(modes.rigid))
    for kind, number in wanted.items():
        elastic = np.flatnonzero((modes.kind == kind) & ~modes.rigid)
        if number > elastic.size:
            raise ValueError(f'reduced_basis.{kind}_modes: asked for {number}, the mesh has '
                             f'only {elastic.size} {kind} modes')
        chosen += list(elastic[:number])
    chosen = np.array(sorted(chosen, key=lambda i: (not modes.rigid[i], modes.eigenvalue[i])),
                      dtype=int)
    rigid = modes.rigid[chosen]
    rank = np.zeros(chosen.size, dtype=int)
    rank[~rigid] = np.arange(1, int(np.sum(~rigid)) + 1)
    driven = model.config.boundary.top_torsion == 'driven'
    return ReducedBasis(
        shapes=modes.shapes[:, chosen],
        frequency_hz=modes.frequency_hz[chosen],
        kind=modes.kind[chosen],
        rigid=rigid,
        rank=rank,
        driven_rotation=model.driven_rotation if driven else np.zeros(model.n_dofs),
        rigid_body_modes=int(np.sum(rigid)) + int(driven),
    )


@dataclass(frozen=True)
class ReducedMatrices:
    """
    [M_r], [C_r], [K_r] of Eq. 36 and the couplings of the driven rotation psi.

    The matrices are dense, n_basis x n_basis; the couplings: mass_driven =
    Phi^T (M + M_f) psi, damping_driven = Phi^T (C + C_f) psi.
    """

    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    mass_driven: np.ndarray
    damping_driven: np.ndarray


def reduce_matrices(model: FiniteElementModel, basis: ReducedBasis) -> ReducedMatrices:
    """Project the full matrices on [Phi]."""
    phi = basis.shapes
    psi = basis.driven_rotation
    mass = model.total_mass
    damping = model.damping()
    return ReducedMatrices(
        mass=phi.T @ (mass @ phi),
        damping=phi.T @ (damping @ phi),
        stiffness=phi.T @ (model.total_stiffness @ phi),
        mass_driven=phi.T @ (mass @ psi),
        damping_driven=phi.T @ (damping @ psi),
    )


def modal_analysis(config) -> tuple[FiniteElementModel, NormalModes, ReducedBasis]:
    """Assemble the model of ``config``, solve its modes and select the reduced basis."""
    from drill_twin.fem.model import build_model
    from drill_twin.modal.normal_modes import solve_normal_modes

    model = build_model(config)
    modes = solve_normal_modes(model)
    return model, modes, select_basis(model, modes, config.reduced_basis)
