"""Implicit Newmark (average acceleration) on the reduced model, for a batch of members.

Each step solves, for the accelerations a = q''(t + dt) of every member,

    R(a) = [M_r] a + [C_r] v + [K_r] d - Phi^T f_NL(d, v, a) - g(t + dt) = 0,
    d = d* + beta dt^2 a,   v = v* + gamma dt a   (beta = 1/4, gamma = 1/2),

by a Newton iteration whose matrix is S0 + U D U^T: S0 = M_r + gamma dt C_r + beta dt^2 K_r is
constant and inverted once; U holds the rows of Phi at the bit's axial and torsional DOFs and
at the lateral DOFs of the nodes touching the wall, and D the tangents of the stiff local
laws there: -gamma dt J with J the 2x2 Jacobian of the bit-rock law (its axial damping
1/(a2 Z^2) grows without bound as the bit stops turning) and beta dt^2 K_c with K_c the 2x2
contact stiffness of each touching node (k_ip = 1e8 N/m). The Woodbury identity applies it
with one small solve per member. The finite-strain and kinetic-coupling forces, small and
smooth, are iterated as a fixed point, as in the paper. The step ends when every member's velocity increment is below
``tolerance`` relative to its velocity (or ``max_iterations`` is reached: failure).

Acceptance after one iteration. The first Newton update already lands within about 1e-12 of
the solution (the stiff bit-rock law is linearised exactly, the fixed-point forces are tiny),
so a second force evaluation would only confirm it. As scipy's implicit solvers do, each
member keeps the contraction rate rho = |increment_2| / |increment_1| of its last step that
ran two iterations and accepts its first iterate when rho / (1 - rho) |increment_1| (the
estimated remaining error) is below the tolerance. It verifies with a second iteration
whenever its set of nodes touching the wall or its bit's lift-off state changed, and at
least every VERIFY_EVERY steps to refresh rho. Bit forces of a member whose last update
came after its last evaluation are carried to the final velocities with their exact
Jacobian.

Members are independent: every decision (convergence, acceptance, verification) is taken
per member and converged members are frozen while others iterate, so a member's trajectory
does not depend on the rest of its batch (up to the rounding of batched products).

g(t) = -Phi^T (M psi theta_top'' + C psi theta_top') carries the imposed top rotation, and
-Phi^T e_top (H - H_S) the change of hook load from its prestressed value.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg as la

from drill_twin.dynamics.forces import ForceEvaluation, Kinematics, NonlinearForces

BETA = 0.25
GAMMA = 0.5
VELOCITY_SCALE = 1e-9
"""Added to the velocity norm in the convergence test (modal units, sqrt(kg) m/s)."""
VERIFY_EVERY = 25
"""A step runs at least two iterations this often, to measure the contraction rate."""


@dataclass
class BatchState:
    """The state of m members at time ``time_s``.

    q, q_rate, q_acceleration: reduced coordinates and derivatives, shape (m, n).
    top_angle_rad, top_speed_rad_per_s, top_acceleration_rad_per_s2: the driven rotation
    (shared by all members); hook_load_n: the hook load in force.
    """

    time_s: float
    q: np.ndarray
    q_rate: np.ndarray
    q_acceleration: np.ndarray
    top_angle_rad: float
    top_speed_rad_per_s: float
    top_acceleration_rad_per_s2: float
    hook_load_n: float

    def copy(self) -> 'BatchState':
        return BatchState(self.time_s, self.q.copy(), self.q_rate.copy(),
                          self.q_acceleration.copy(), self.top_angle_rad,
                          self.top_speed_rad_per_s, self.top_acceleration_rad_per_s2,
                          self.hook_load_n)


@dataclass(frozen=True)
class StepResult:
    """Outcome of one step: success unless a member diverged or did not converge.

    converged, finite: per member (m,); iterations: used; error: final relative velocity
    increment per member; message: why it failed ('' on success).
    """

    success: bool
    converged: np.ndarray
    finite: np.ndarray
    iterations: int
    error: np.ndarray
    message: str
    forces: ForceEvaluation


@dataclass
class Counters:
    """Work done so far."""

    steps: int = 0
    iterations: int = 0
    force_evaluations: int = 0
    failed_steps: int = 0
    history: list = field(default_factory=list, repr=False)


class NewmarkIntegrator:
    """Average-acceleration Newmark with a cached S0^-1 and Newton on the bit-rock law.

    Args:
        forces: the non-linear forces of a reduced system.
        time_step_s: dt (s).
        tolerance: relative velocity increment that ends the iteration.
        max_iterations: iteration cap per step.
        germ: (m, 2, 2) random germs of the bit-rock law, or None for the mean model.
    """

    def __init__(self, forces: NonlinearForces, time_step_s: float, tolerance: float,
                 max_iterations: int, germ: np.ndarray | None = None):
        system = forces.system
        self.forces = forces
        self.system = system
        self.time_step_s = float(time_step_s)
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.germ = germ
        n = system.size
        self.mass = system.mass
        self.damping = system.damping
        self.stiffness = system.stiffness
        # Mass-normalised modes: [M_r] = I and [K_r] = diag(omega^2) up to rounding.
        self._mass_is_identity = np.allclose(self.mass, np.eye(n), rtol=0, atol=1e-9)
        off_diagonal = self.stiffness - np.diag(np.diag(self.stiffness))
        self._stiffness_diagonal = (np.diag(self.stiffness).copy()
                                    if np.abs(off_diagonal).max() <= 1e-9 * np.abs(
                                        self.stiffness).max() else None)
        self.damping_t = np.ascontiguousarray(self.damping.T)
        dt = self.time_step_s
        effective = self.mass + GAMMA * dt * self.damping + BETA * dt * dt * self.stiffness
        # S0 is within 1e-3 of the identity (mass-normalised modes, dt << periods): its
        # explicit inverse is as accurate as an LU and a product is cheaper for a batch.
        self.effective_inverse_t = np.ascontiguousarray(la.inv(effective).T)
        # Local-law directions: bit (axial, torsion), then v and w of every node.
        local = np.zeros((n, 2 + 2 * system.n_nodes))
        axial, torsion = system.blocks['axial'], system.blocks['torsional']
        local[axial.columns, 0] = axial.shapes[system.bit_node]
        local[torsion.columns, 1] = torsion.shapes[system.bit_node]
        bending_y, bending_z = system.blocks['bending_y'], system.blocks['bending_z']
        nodes = system.n_nodes
        local[bending_y.columns, 2:2 + nodes] = bending_y.shapes[:nodes].T       # v rows
        local[bending_z.columns, 2 + nodes:] = bending_z.shapes[:nodes].T        # w rows
        self.local_directions = local
        self.local_response = la.solve(effective, local)                  # S0^-1 U
        self.local_gram = local.T @ self.local_response                   # U^T S0^-1 U
        self.bit_rows_t = np.ascontiguousarray(local[:, :2])
        self.bit_response_t = np.ascontiguousarray(self.local_response[:, :2].T)
        self.bit_flexibility = self.local_gram[:2, :2]
        self.top_axial_row = system.top_axial_row
        self.static_hook_load_n = system.model.prestress.hook_load_n
        self.counters = Counters()
        self._rate = None                 # per member: contraction rate of its last 2-iteration step
        self._steps_since_verified = None
        self._active = None               # (contact flags, lift-off flags) at the last step

    # -- initial state -------------------------------------------------------------------
    def initial_state(self, q: np.ndarray, q_rate: np.ndarray, top_speed_rad_per_s: float,
                      hook_load_n: float, top_angle_rad: float = 0.0) -> BatchState:
        """A state at t = 0 with the accelerations that balance Eq. 35 (fixed point)."""
        state = BatchState(0.0, np.array(q, dtype=float), np.array(q_rate, dtype=float),
                           np.zeros_like(q, dtype=float), top_angle_rad,
                           top_speed_rad_per_s, 0.0, hook_load_n)
        load = self._external_load(state.top_speed_rad_per_s, 0.0, hook_load_n)
        for _ in range(5):
            fields = Kinematics.of(self.system, state.q, state.q_rate, state.q_acceleration,
                                   state.top_speed_rad_per_s, 0.0)
            evaluation = self.forces.evaluate(fields, self.germ)
            residual_free = (evaluation.modal + load - state.q_rate @ self.damping_t
                             - self._stiffness_times(state.q))
            state.q_acceleration = la.solve(self.mass, residual_free.T).T
        return state

    def _external_load(self, top_speed, top_acceleration, hook_load_n):
        system = self.system
        return (-system.mass_driven * top_acceleration - system.damping_driven * top_speed
                - self.top_axial_row * (hook_load_n - self.static_hook_load_n))

    def _stiffness_times(self, q):
        if self._stiffness_diagonal is not None:
            return q * self._stiffness_diagonal
        return q @ self.stiffness.T

    def _mass_times(self, a):
        return a if self._mass_is_identity else a @ self.mass.T

    # -- one step ------------------------------------------------------------------------
    def step(self, state: BatchState, top_speed_rad_per_s: float,
             hook_load_n: float) -> tuple[BatchState, StepResult]:
        """Advance ``state`` by dt with the top speed and hook load given for t + dt.

        Returns the new state and the step's outcome; on failure the new state holds the
        last iterate (callers must not continue from it silently).
        """
        dt = self.time_step_s
        top_acceleration = (top_speed_rad_per_s - state.top_speed_rad_per_s) / dt
        top_angle = state.top_angle_rad + 0.5 * dt * (state.top_speed_rad_per_s
                                                      + top_speed_rad_per_s)
        d_pred = state.q + dt * state.q_rate + (0.5 - BETA) * dt * dt * state.q_acceleration
        v_pred = state.q_rate + (1.0 - GAMMA) * dt * state.q_acceleration
        load = self._external_load(top_speed_rad_per_s, top_acceleration, hook_load_n)
        members = state.q.shape[0]
        a = state.q_acceleration.copy()
        error = np.full(members, np.inf)
        active = np.ones(members, dtype=bool)        # members still iterating
        carried = np.zeros(members, dtype=bool)      # updated after their last evaluation
        final = None
        last_increment = np.zeros_like(a)
        iterations = 0
        for iterations in range(1, self.max_iterations + 1):
            d = d_pred + BETA * dt * dt * a
            v = v_pred + GAMMA * dt * a
            fields = Kinematics.of(self.system, d, v, a, top_speed_rad_per_s, top_acceleration)
            evaluation = self.forces.evaluate(fields, self.germ)
            self.counters.force_evaluations += 1
            # Frozen members were evaluated at their final state: keep that evaluation.
            final = evaluation if final is None else _merge(final, evaluation, ~active)
            carried &= active
            residual = (self._mass_times(a) + v @ self.damping_t + self._stiffness_times(d)
                        - evaluation.modal - load)
            increment = self._solve(residual, evaluation)
            increment[~active] = 0.0
            a -= increment
            last_increment = np.where(active[:, None], increment, last_increment)
            speed = np.linalg.norm(v, axis=1)
            previous_error = error
            new_error = GAMMA * dt * np.linalg.norm(increment, axis=1) / (speed + VELOCITY_SCALE)
            error = np.where(active, new_error, error)
            if not np.all(np.isfinite(error)):
                break
            done = active & (error <= self.tolerance)
            if iterations == 1:
                accepted = active & self._accept_first_iterate(error, evaluation)
                error = np.where(accepted, self._rate / (1.0 - self._rate) * error, error)
                done |= accepted
            elif iterations == 2:
                measured = active & (previous_error > 0)
                rate = np.where(measured, error / np.where(measured, previous_error, 1.0), np.nan)
                usable = measured & (rate < 1.0)
                self._rate = np.where(usable, rate, self._rate)
                self._steps_since_verified = np.where(usable, 0, self._steps_since_verified)
            carried |= done
            active &= ~done
            if not np.any(active):
                break
        evaluation = self._carry_bit_forces(final, last_increment, carried)
        self._steps_since_verified += 1
        self._active = (evaluation.contact.in_contact.copy(), evaluation.lifted.copy())
        d = d_pred + BETA * dt * dt * a
        v = v_pred + GAMMA * dt * a
        finite = np.all(np.isfinite(d), axis=1) & np.all(np.isfinite(v), axis=1)
        converged = finite & (error <= self.tolerance)
        success = bool(np.all(converged))
        time = state.time_s + dt
        message = ''
        if not np.all(finite):
            message = f'non-finite state at t = {time:.6g} s (members {np.flatnonzero(~finite)})'
        elif not success:
            message = (f'no convergence in {self.max_iterations} iterations at t = {time:.6g} s '
                       f'(members {np.flatnonzero(~converged)}, error {np.max(error):.3g})')
        self.counters.steps += 1
        self.counters.iterations += iterations
        self.counters.failed_steps += int(not success)
        new_state = BatchState(time, d, v, a, top_angle, top_speed_rad_per_s, top_acceleration,
                               hook_load_n)
        return new_state, StepResult(success, converged, finite, iterations, error, message,
                                     evaluation)

    def _accept_first_iterate(self, error, evaluation) -> np.ndarray:
        """Members whose first iterate is accepted on their own contraction rate (m,)."""
        members = error.shape[0]
        if self._rate is None or self._rate.shape != (members,):
            self._rate = np.full(members, np.nan)
            self._steps_since_verified = np.zeros(members, dtype=int)
            return np.zeros(members, dtype=bool)
        accept = np.isfinite(self._rate) & (self._steps_since_verified < VERIFY_EVERY)
        if self._active is not None:
            contact, lifted = self._active
            accept &= np.all(contact == evaluation.contact.in_contact, axis=1)
            accept &= lifted == evaluation.lifted
        with np.errstate(invalid='ignore'):
            accept &= self._rate / (1.0 - self._rate) * error <= self.tolerance
        return accept

    def _carry_bit_forces(self, evaluation: ForceEvaluation, increment,
                          members) -> ForceEvaluation:
        """Bit forces of ``members`` carried to their accepted velocities: f + J dx, with
        dx = -gamma dt B^T increment (their last update came after their last evaluation)."""
        if not np.any(members):
            return evaluation
        change = -GAMMA * self.time_step_s * increment @ self.bit_rows_t       # (m, 2)
        change[~members] = 0.0
        corrected = np.einsum('mij,mj->mi', evaluation.bit_jacobian, change)
        lifted = evaluation.lifted
        return replace(evaluation,
                       weight_on_bit_n=np.where(lifted, 0.0,
                                                evaluation.weight_on_bit_n + corrected[:, 0]),
                       torque_on_bit_nm=np.where(lifted, 0.0,
                                                 evaluation.torque_on_bit_nm + corrected[:, 1]),
                       rop_m_per_s=evaluation.rop_m_per_s + change[:, 0],
                       bit_speed_rad_per_s=evaluation.bit_speed_rad_per_s + change[:, 1])

    def _solve(self, residual: np.ndarray, evaluation: ForceEvaluation) -> np.ndarray:
        """(S0 + U D U^T)^-1 residual for every member (Woodbury; see the module docstring)."""
        gdt = GAMMA * self.time_step_s
        jacobian = evaluation.bit_jacobian
        base = residual @ self.effective_inverse_t                     # S0^-1 r, (m, n)
        z = base @ self.bit_rows_t                                     # B^T S0^-1 r, (m, 2)
        jz = jacobian @ z[..., None]                                   # (m, 2, 1)
        small = np.eye(2) - gdt * (jacobian @ self.bit_flexibility)    # (m, 2, 2)
        determinant = small[:, 0, 0] * small[:, 1, 1] - small[:, 0, 1] * small[:, 1, 0]
        w = np.empty_like(z)
        w[:, 0] = (small[:, 1, 1] * jz[:, 0, 0] - small[:, 0, 1] * jz[:, 1, 0]) / determinant
        w[:, 1] = (small[:, 0, 0] * jz[:, 1, 0] - small[:, 1, 0] * jz[:, 0, 0]) / determinant
        result = base + gdt * w @ self.bit_response_t
        touching = evaluation.contact.in_contact
        for member in np.flatnonzero(np.any(touching, axis=1)):
            result[member] = self._solve_with_contact(base[member], jacobian[member],
                                                      evaluation.contact_tangent[member],
                                                      np.flatnonzero(touching[member]))
        return result

    def _solve_with_contact(self, base, jacobian, tangent, nodes):
        """One member: bit and touching nodes in U, D = blockdiag(-gamma dt J, beta dt^2 K_c)."""
        dt = self.time_step_s
        n_nodes = self.system.n_nodes
        index = np.concatenate([[0, 1], np.ravel(np.column_stack([2 + nodes,
                                                                  2 + n_nodes + nodes]))])
        rank = index.size
        d = np.zeros((rank, rank))
        d[:2, :2] = -GAMMA * dt * jacobian
        for k in range(nodes.size):
            d[2 + 2 * k:4 + 2 * k, 2 + 2 * k:4 + 2 * k] = BETA * dt * dt * tangent[nodes[k]]
        z = self.local_directions[:, index].T @ base
        gram = self.local_gram[np.ix_(index, index)]
        w = np.linalg.solve(np.eye(rank) + d @ gram, d @ z)
        return base - self.local_response[:, index] @ w


def _merge(kept: ForceEvaluation, new: ForceEvaluation, members: np.ndarray) -> ForceEvaluation:
    """``new`` for ``members`` (their final state), ``kept`` for the others."""
    if not np.any(members):
        return kept
    if np.all(members):
        return new

    def pick(a, b):
        if a is None or b is None:
            return b if a is None else a
        mask = members.reshape((-1,) + (1,) * (np.ndim(a) - 1))
        return np.where(mask, b, a)

    from drill_twin.dynamics.contact import ContactForces
    contact = ContactForces(pick(kept.contact.radial_force_n, new.contact.radial_force_n),
                            pick(kept.contact.in_contact, new.contact.in_contact))
    tangent = (None if kept.contact_tangent is None and new.contact_tangent is None else
               pick(_tangent_or_zero(kept), _tangent_or_zero(new)))
    return ForceEvaluation(
        full=pick(kept.full, new.full), modal=pick(kept.modal, new.modal),
        weight_on_bit_n=pick(kept.weight_on_bit_n, new.weight_on_bit_n),
        torque_on_bit_nm=pick(kept.torque_on_bit_nm, new.torque_on_bit_nm),
        rop_m_per_s=pick(kept.rop_m_per_s, new.rop_m_per_s),
        bit_speed_rad_per_s=pick(kept.bit_speed_rad_per_s, new.bit_speed_rad_per_s),
        lifted=pick(kept.lifted, new.lifted), bit_jacobian=pick(kept.bit_jacobian,
                                                                new.bit_jacobian),
        contact=contact, contact_tangent=tangent)


def _tangent_or_zero(evaluation: ForceEvaluation) -> np.ndarray:
    if evaluation.contact_tangent is not None:
        return evaluation.contact_tangent
    return np.zeros(evaluation.contact.in_contact.shape + (2, 2))
