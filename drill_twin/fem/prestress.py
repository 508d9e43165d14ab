"""The static prestressed state (Eq. 29): u_S = [K]^-1 (f_g + f_c + f_f), hook held fixed."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from drill_twin.fem import dofs
from drill_twin.fem.mesh import Mesh


@dataclass(frozen=True)
class Prestress:
    """
    The prestressed configuration.

    Fields:
        displacement_m: u_S, shape (n_dofs,) (axial entries only; m).
        axial_force_n: N of each element (constant per element; tension > 0), N.
        hook_load_n: force the hook holds the string up with (> 0 when it carries weight), N.
        static_weight_on_bit_n: f_c, the bit reaction (negative in compression), N.
        neutral_point_above_bit_m: height above the bit where N changes sign (None: the
            string is nowhere in compression).
        load_n: f_g + f_c + f_f, shape (n_dofs,), N.
    """

    displacement_m: np.ndarray
    axial_force_n: np.ndarray
    hook_load_n: float
    static_weight_on_bit_n: float
    neutral_point_above_bit_m: float | None
    load_n: np.ndarray

    @classmethod
    def none(cls, n_dofs: int, n_elements: int) -> 'Prestress':
        """No static preload (prestress switched off)."""
        return cls(np.zeros(n_dofs), np.zeros(n_elements), 0.0, 0.0, None, np.zeros(n_dofs))


def solve_prestress(mesh: Mesh, stiffness: sp.csr_matrix, load: np.ndarray,
                    bit_axially_fixed: bool, static_weight_on_bit_n: float) -> Prestress:
    """Solve the axial statics with the top (hook) held, and recover N and the hook load."""
    axial = dofs.node_dof(np.arange(mesh.n_nodes), dofs.U)
    k_axial = stiffness[axial][:, axial].tocsc()
    f_axial = load[axial]
    held = [0] + ([mesh.n_nodes - 1] if bit_axially_fixed else [])
    free = np.setdiff1d(np.arange(mesh.n_nodes), held)
    u_axial = np.zeros(mesh.n_nodes)
    u_axial[free] = spla.spsolve(k_axial[free][:, free], f_axial[free])
    reaction = k_axial @ u_axial - f_axial          # force of the supports on the string
    displacement = np.zeros(mesh.n_dofs)
    displacement[axial] = u_axial
    ea = mesh.young_modulus_pa * mesh.area_m2
    force = ea * np.diff(u_axial) / mesh.length_m
    return Prestress(
        displacement_m=displacement,
        axial_force_n=force,
        hook_load_n=float(-reaction[0]),      # the support pulls up (negative x)
        static_weight_on_bit_n=float(static_weight_on_bit_n),
        neutral_point_above_bit_m=neutral_point_above_bit(mesh, force),
        load_n=load.copy(),
    )


def neutral_point_above_bit(mesh: Mesh, axial_force_n: np.ndarray) -> float | None:
    """
    Height above the bit where N changes from compression (below) to tension (above).

    N is exact at element midpoints for a linear element with consistent loads; it is
    interpolated linearly between them (and extrapolated over the last half element).
    """
    mid = mesh.node_x_m[:-1] + 0.5 * mesh.length_m
    length = mesh.total_length_m
    if axial_force_n[-1] >= 0.0:
        return None
    for k in range(mesh.n_elements - 1, 0, -1):
        lower, upper = axial_force_n[k], axial_force_n[k - 1]
        if upper >= 0.0 > lower:
            x = mid[k] + (mid[k - 1] - mid[k]) * (0.0 - lower) / (upper - lower)
            return float(length - x)
    return float(length)
