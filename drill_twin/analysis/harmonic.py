"""
Steady forced whirl of the linearised string: the closed form that checks the imbalance.

A mass imbalance m e at node k, spinning at a constant Omega, loads the node with the
rotating force m e Omega^2 (cos(Omega t + phi), sin(Omega t + phi)). The linearised,
prestressed string of Eq. 30 (no f_NL) answers, once the transient has died out, with

    u(t) = Re(U e^(i Omega t)),  ([K] + [K_f] + [K_g] - Omega^2 ([M] + [M_f])
                                  + i Omega ([C] + [C_f])) U = F,
    F_v = m e Omega^2 e^(i phi),  F_w = -i m e Omega^2 e^(i phi)

on the free DOFs (sin(Omega t + phi) = Re(-i e^(i(Omega t + phi)))): one sparse complex
solve per speed, on the full finite-element model (not its reduced basis). The lateral
groups of Eq. 30 do not couple with axial and torsional motion, nor the y plane with the z
plane, so the node describes an ellipse, a circle when the two planes are alike.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from drill_twin.fem import dofs
from drill_twin.fem.model import FiniteElementModel


@dataclass(frozen=True)
class ForcedWhirl:
    """
    Steady response of a node to a rotating unit-phase force.

    spin_rad_per_s: Omega; v, w: complex amplitudes at the node (m), phase measured from the
    force's direction (the imbalance's angle); radius_m: the orbit's mean radius
    (|v| + |w|) / 2 (a circle when they are equal); lag_rad: the angle in [0, 2 pi) by which
    the displacement trails the imbalance, minus the argument of the forward-whirl amplitude
    (v + i w) / 2 (near 0 below the first resonance, pi/2 at an isolated one); field: the
    complex amplitudes of every DOF, (n_dofs,).
    """

    spin_rad_per_s: float
    v: complex
    w: complex
    radius_m: float
    lag_rad: float
    field: np.ndarray


def forced_whirl(model: FiniteElementModel, node: int, unbalance_kg_m: float,
                 spin_rad_per_s: float) -> ForcedWhirl:
    """
    Return the steady whirl of ``node`` under an imbalance.

    The imbalance m e (kg m) spins at Omega (rad/s).
    """
    omega = float(spin_rad_per_s)
    free = model.free
    dynamic = (model.total_stiffness - omega ** 2 * model.total_mass
               + 1j * omega * model.damping()).tocsc()
    force = np.zeros(model.n_dofs, dtype=complex)
    amplitude = unbalance_kg_m * omega ** 2
    force[dofs.node_dof(node, dofs.V)] = amplitude
    force[dofs.node_dof(node, dofs.W)] = -1j * amplitude
    field = np.zeros(model.n_dofs, dtype=complex)
    reduced = dynamic[free][:, free]
    field[free] = spla.spsolve(sp.csc_matrix(reduced), force[free])
    v = complex(field[dofs.node_dof(node, dofs.V)])
    w = complex(field[dofs.node_dof(node, dofs.W)])
    forward = 0.5 * (v + 1j * w)            # amplitude of the forward-whirling part
    return ForcedWhirl(spin_rad_per_s=omega, v=v, w=w, radius_m=0.5 * (abs(v) + abs(w)),
                       lag_rad=float(-np.angle(forward)) % (2 * np.pi), field=field)
