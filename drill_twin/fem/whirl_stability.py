"""
Linear whirl stability of the spinning string under internal, rotating damping.

Here Rayleigh's stiffness-proportional damping acts on the strain rates of the spinning string
(internal, rotating damping): one reading of the paper selectable for its lateral response
(``lateral_readings.stiffness_damping``; docs/LATERAL.md, "What feeds the lateral modes").

In the fixed frame the paper's damping is [C] = alpha (M + M_f) + beta (K + K_f + K_g), acting
on u'. Read as material damping, the beta term acts on the strain rates of the string, i.e. on
the velocities seen in the frame that spins with it: u' - Omega J u, where J turns a lateral
shape a quarter turn about x, (v, theta_z, w, theta_y) -> (-w, theta_y, v, -theta_z) (a
right-handed spin Omega > 0 turns y towards z). The linearised lateral equations at a constant
spin Omega become

    (M + M_f) u'' + (C + C_f) u' + (K_t - Omega beta K_t J) u = 0,   K_t = K + K_f + K_g,

a circulatory term (not symmetric). For a mode pair of frequency omega_k (mass-normalised,
light damping), first-order perturbation gives the growth rates of its forward and backward
whirl (the classical Jeffcott result with external damping alpha m and internal beta k):

    sigma_forward  = -alpha / 2 - beta omega_k^2 / 2 + beta Omega omega_k / 2
    sigma_backward = -alpha / 2 - beta omega_k^2 / 2 - beta Omega omega_k / 2

so forward whirl of mode k grows when Omega > omega_k + alpha / (beta omega_k); the smallest
such spin over all omega_k is Omega* = 2 sqrt(alpha / beta), reached at omega_k = Omega / 2.
:func:`whirl_growth_rates` computes the growth rates of the full finite-element model (fluid
and prestress included) from its eigenvalues, which checks the formula and answers the
question for the paper's string.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as la

from drill_twin.fem import dofs
from drill_twin.fem.model import FiniteElementModel


def quarter_turn(n_dofs: int) -> np.ndarray:
    """J: the lateral DOFs turned a quarter turn about x, (n_dofs, n_dofs) (zero elsewhere)."""
    nodes = np.arange(n_dofs // dofs.DOFS_PER_NODE)
    j = np.zeros((n_dofs, n_dofs))
    v, w = dofs.node_dof(nodes, dofs.V), dofs.node_dof(nodes, dofs.W)
    tz, ty = dofs.node_dof(nodes, dofs.THETA_Z), dofs.node_dof(nodes, dofs.THETA_Y)
    j[v, w] = -1.0          # new v = -w
    j[w, v] = 1.0           # new w = v
    j[tz, ty] = 1.0         # new theta_z = theta_y
    j[ty, tz] = -1.0        # new theta_y = -theta_z
    return j


def whirl_growth_rates(model: FiniteElementModel, spin_rad_per_s: float,
                       rotating_damping: bool = True, shapes: bool = False) -> tuple:
    """
    Eigenvalues of the linearised lateral motion at a constant spin.

    Returns (growth rate Re s (1/s), frequency Im s (rad/s), forward) of every eigenvalue
    with Im s > 0, sorted by frequency; forward: the mode whirls with the spin (its
    displacement v + i w turns like e^(i Im s t)), else against it. A positive growth rate
    is a self-excited whirl.
    ``rotating_damping``: the beta term acts in the spinning frame (the reading above);
    False gives the paper's fixed-frame damping (all growth rates negative). ``shapes``: also
    return the complex mode shapes U on all the model's DOFs, (n_dofs, count), the mode
    being u = Re(U e^(s t)).
    """
    n = model.n_dofs
    lateral = np.isin(np.arange(n) % dofs.DOFS_PER_NODE, dofs.LATERAL_DOFS)
    keep = np.flatnonzero(lateral & np.isin(np.arange(n), model.free))
    mass = model.total_mass.toarray()[np.ix_(keep, keep)]
    damping = model.damping().toarray()[np.ix_(keep, keep)]
    stiffness_full = model.total_stiffness.toarray()
    stiffness = stiffness_full[np.ix_(keep, keep)]
    if rotating_damping:
        beta = model.config.damping.stiffness_coefficient_s
        circulatory = (stiffness_full @ quarter_turn(n))[np.ix_(keep, keep)]
        stiffness = stiffness - spin_rad_per_s * beta * circulatory
    size = keep.size
    # First-order form: [0 I; -M^-1 K  -M^-1 C].
    m_inv_k = la.solve(mass, stiffness)
    m_inv_c = la.solve(mass, damping)
    system = np.block([[np.zeros((size, size)), np.eye(size)], [-m_inv_k, -m_inv_c]])
    values, vectors = la.eig(system)
    upper = values.imag > 1e-9
    values, vectors = values[upper], vectors[:size, upper]
    if shapes:
        full = np.zeros((n, vectors.shape[1]), dtype=complex)
        full[keep] = vectors
    # The mode is u = Re(U e^(s t)); its forward part is (V + i W) / 2, backward (V - i W)/2
    # (conjugated), with V, W the amplitudes of v and w at the same node.
    kind = np.arange(n)[keep] % dofs.DOFS_PER_NODE
    v_rows = np.flatnonzero(kind == dofs.V)
    w_rows = np.flatnonzero(kind == dofs.W)
    v, w = vectors[v_rows], vectors[w_rows]
    forward = (np.sum(np.abs(v + 1j * w) ** 2, axis=0)
               > np.sum(np.abs(v - 1j * w) ** 2, axis=0))
    order = np.argsort(values.imag)
    result = values.real[order], values.imag[order], forward[order]
    return result + (full[:, order],) if shapes else result
