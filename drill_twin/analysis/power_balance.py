"""
Energy balance of the lateral motion, term by term.

Where does the energy of the lateral modes come from? Along a run, the lateral energy
E = q'^T M_r q' / 2 + q^T K_r q / 2 (lateral columns of the reduced model: bending in y and z,
with the prestress and fluid stiffness) changes by the work of the forces on the lateral DOFs:

    E(t) - E(0) = W_damping + W_se + W_ke + W_contact + W_imbalance + W_rotating_damping

(no other load reaches the lateral DOFs: g(t) and the hook load act on the torsional and
axial columns, and the linear model does not couple them). Every term is accumulated along the
trapezoidal path of the average-acceleration Newmark step, W += (f_n + f_n+1) . (u_n+1 - u_n)
/ 2, for which the identity holds exactly when the steps are converged; its residual
(:meth:`LateralEnergyBalance.closure_j`) measures the iteration error and the share of the
steps integrated again on sub-steps (failed steps, and the steps in which a node touches or
leaves the wall when ``integration.contact_substeps`` > 1: the path inside them is finer
than the full step's trapezoid the balance accumulates). A term with W > 0 feeds
the lateral motion; the energy it brings comes from the axial and torsional motion it also
acts on (the top drive in the end). docs/LATERAL.md, "What feeds the lateral modes",
tabulates the terms per stick-slip cycle for each reading of the paper.
"""
from __future__ import annotations

import numpy as np

from drill_twin.model.contact import contact_force
from drill_twin.model.finite_strain import StrainOperators, finite_strain_force
from drill_twin.model.forces import Kinematics
from drill_twin.model.kinetic_coupling import CouplingOperators, kinetic_coupling_force
from drill_twin.model.rotating_damping import rotating_damping_force

TERMS = ('damping', 'finite_strain', 'kinetic_coupling', 'contact', 'imbalance',
         'rotating_damping')


class LateralEnergyBalance:
    """
    Accumulates the work of every term on the lateral DOFs of a :class:`Simulator`.

    Call :meth:`update` after every ``simulator.step()``. ``work_j``: term -> (m,) work since
    the start (J); :meth:`energy_j`: the lateral energy now, (m,) (J).
    """

    def __init__(self, simulator):
        system = simulator.system
        self.simulator = simulator
        self.system = system
        n = system.n_nodes
        self.rows = slice(2 * n, 6 * n)                # v, theta_z, w, theta_y (field-wise)
        blocks = system.blocks
        self.columns = np.concatenate([np.arange(system.size)[blocks[g].columns]
                                       for g in ('bending_y', 'bending_z')])
        pick = np.ix_(self.columns, self.columns)
        self.mass = system.mass[pick]
        self.stiffness = system.stiffness[pick]
        self.damping = system.damping[pick]
        self.strain_operators = StrainOperators.of(system)
        self.coupling_operators = CouplingOperators.of(system)
        self.work_j = {term: np.zeros(simulator.members) for term in TERMS}
        self.energy_at_start_j = self.energy_j()
        self._previous = self._forces()

    def energy_j(self) -> np.ndarray:
        """Lateral kinetic plus strain energy (reduced, lateral columns), (m,) (J)."""
        state = self.simulator.state
        q, rate = state.q[:, self.columns], state.q_rate[:, self.columns]
        return 0.5 * (np.einsum('mi,ij,mj->m', rate, self.mass, rate)
                      + np.einsum('mi,ij,mj->m', q, self.stiffness, q))

    def _forces(self):
        """(lateral displacement (m, k), {term: lateral generalised force (m, k)}) now."""
        simulator, system = self.simulator, self.system
        state = simulator.state
        physics = system.model.config.physics
        fields = Kinematics.of(system, state.q, state.q_rate, state.q_acceleration,
                               state.top_speed_rad_per_s, state.top_acceleration_rad_per_s2,
                               state.top_angle_rad)
        zero = np.zeros((state.q.shape[0], self.columns.size))
        # Forces projected on the lateral columns: Phi_lat^T f, so that f . du = F . dq.
        forces = {term: zero for term in TERMS}
        forces['damping'] = -state.q_rate[:, self.columns] @ self.damping.T
        if physics.finite_strain:
            forces['finite_strain'] = self._project(
                finite_strain_force(system, fields.displacement, self.strain_operators,
                                    top_angle_rad=state.top_angle_rad))
        if physics.kinetic_coupling:
            forces['kinetic_coupling'] = self._project(
                kinetic_coupling_force(system, fields, self.coupling_operators))
        if physics.contact:
            borehole = system.model.config.borehole
            force, _, _ = contact_force(
                system, borehole.contact_stiffness_n_per_m, borehole.friction_coefficient,
                borehole.friction_regularization_rad_per_s, fields,
                tangential=borehole.tangential_friction)
            forces['contact'] = self._project(force)
        imbalance = simulator.forces.imbalance
        if imbalance is not None:
            forces['imbalance'] = self._project(imbalance.force(system, fields))
        rotating = simulator.forces.rotating_damping
        if rotating.on:                 # lateral_readings.stiffness_damping: rotating_frame
            forces['rotating_damping'] = self._project(rotating_damping_force(
                system, fields.displacement, fields.theta_x_rate, rotating))
        return state.q[:, self.columns].copy(), forces

    def _project(self, force: np.ndarray) -> np.ndarray:
        return self.system.project(force)[:, self.columns]

    def update(self) -> None:
        """Accumulate the work of the last step (call after every step)."""
        q_before, before = self._previous
        q_now, now = self._forces()
        increment = q_now - q_before
        for term in TERMS:
            self.work_j[term] += 0.5 * np.einsum('mk,mk->m', before[term] + now[term],
                                                 increment)
        self._previous = (q_now, now)

    def closure_j(self) -> np.ndarray:
        """E(t) - E(0) - sum of the work: zero up to the iteration tolerance, (m,) (J)."""
        return (self.energy_j() - self.energy_at_start_j
                - sum(self.work_j[term] for term in TERMS))
