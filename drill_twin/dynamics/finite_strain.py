"""f_se: the finite-strain forces beyond [K] + [K_g] (Eq. 14-16).

f_se = -B^T [dW/dg(g_S + g) - dW/dg(g_S) - H_S g] at every Gauss point: the strain energy's
force minus its value and tangent at the prestress, which [K] + [K_g] already carry.
Strains are held component first, (8, P, m), so that every operation runs on contiguous
memory.
"""
from __future__ import annotations

import numpy as np

from drill_twin.fem import strain_energy as se


def nonlinear_stress(system, strain: np.ndarray, linear_stress: np.ndarray) -> np.ndarray:
    """dW/dg(g_S + g) - dW/dg(g_S) - H_S g, shape (8, P, m), for strains g and their image
    H_S g by the prestress tangent, both (8, P, m)."""
    total = [system.prestress_strain_components[k] + strain[k] for k in range(se.N_STRAINS)]
    stress = np.array(se.stress_components(total, system.section_columns))
    stress -= system.prestress_stress_components
    stress -= linear_stress
    return stress


def finite_strain_force(system, displacement: np.ndarray) -> np.ndarray:
    """f_se on the field-wise DOFs (right-hand side), shape (m, n_dofs).

    displacement: u from the prestressed state, shape (m, n_dofs).
    """
    m = displacement.shape[0]
    both = (system.strain_and_tangent_operator @ displacement.T).reshape(
        2, se.N_STRAINS, system.n_gauss, m)
    stress = nonlinear_stress(system, both[0], both[1]) * system.gauss_weight_m[None, :, None]
    return -(system.strain_operator_t @ stress.reshape(-1, m)).T
