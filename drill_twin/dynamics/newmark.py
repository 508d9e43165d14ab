"""Implicit Newmark (average acceleration) on the reduced model, for a batch of members.

Each step solves, for the accelerations a = q''(t + dt) of every member,

    R(a) = [M_r] a + [C_r] v + [K_r] d - Phi^T f_NL(d, v, a) - g(t + dt) = 0,
    d = d* + beta dt^2 a,   v = v* + gamma dt a   (beta = 1/4, gamma = 1/2).

Iteration. At an iterate a_k the finite-strain and kinetic-coupling forces are frozen (a fixed
point, as in the paper: they are small and smooth), the wall contact is linearised (Newton:
its 2x2 stiffness k_ip [n n^T + (p/r)(I - n n^T)] at every touching node) and the bit-rock law
is solved exactly. With S = S0 + U_c D_c U_c^T (S0 = M_r + gamma dt C_r + beta dt^2 K_r,
inverted once; the contact terms added per member by the Woodbury identity) the accelerations
are linear in the bit force F:

    a = a_k - S^-1 R_nobit(a_k) + S^-1 B (F(x) - F_c),

B holding the rows of Phi at the bit's axial and torsional DOFs and F_c = (f_c, 0) the
prestress reaction. So the bit velocities x = (ROP, omega) obey the 2x2 equation

    x = x_lin + gamma dt H (F(x) - F_c),   H = B^T S^-1 B,

solved per member by Newton with backtracking on its residual (the law is stiff, kinked at
lift-off, and flat or steep in places for random germs). The accelerations then follow. The
step ends when every member's velocity increment is below ``tolerance`` relative to its
velocity (failure after ``max_iterations``).

Acceptance after one iteration. With the bit solved exactly the first update already lands
within about 1e-12 of the solution, so a second force evaluation would only confirm it. As
scipy's implicit solvers do, each member keeps the contraction rate rho = |increment_2| /
|increment_1| of its last step that ran two iterations and accepts its first iterate when
rho / (1 - rho) |increment_1| (the estimated remaining error) is below the tolerance. It
verifies with a second iteration whenever its set of nodes touching the wall or its bit's
lift-off state changed, and at least every VERIFY_EVERY steps to refresh rho.

Members are independent: every decision (convergence, acceptance, verification) is taken per
member and converged members are frozen while others iterate, so a member's trajectory does
not depend on the rest of its batch (up to the rounding of batched products).

g(t) = -Phi^T (M psi theta_top'' + C psi theta_top') carries the imposed top rotation, and
-Phi^T e_top (H - H_S) the change of hook load from its prestressed value.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as la

from drill_twin.dynamics.bit_equation import solve_bit_equation
from drill_twin.dynamics.contact import ContactForces
from drill_twin.dynamics.forces import ForceEvaluation, Kinematics, NonlinearForces

BETA = 0.25
GAMMA = 0.5
VELOCITY_SCALE = 1e-9
"""Added to the velocity norm in the convergence test (modal units, sqrt(kg) m/s)."""
VERIFY_EVERY = 25
"""A step runs at least two iterations this often, to measure the contraction rate."""
ON_BOTTOM_TOLERANCE_M = 1e-6
"""The bit counts as on bottom when it is within this of the hole bottom (m)."""


@dataclass
class BatchState:
    """The state of m members at time ``time_s``.

    q, q_rate, q_acceleration: reduced coordinates and derivatives, shape (m, n).
    top_angle_rad, top_speed_rad_per_s, top_acceleration_rad_per_s2: the driven rotation
    (shared by all members); hook_load_n: the hook load in force. hole_u: the hole bottom as
    an axial displacement of the bit from the prestressed state, (m,) (m, down): the deepest
    the bit has been; the bit is off bottom when its displacement is smaller. None: the bit
    is on bottom (the hole bottom is where the bit is).
    """

    time_s: float
    q: np.ndarray
    q_rate: np.ndarray
    q_acceleration: np.ndarray
    top_angle_rad: float
    top_speed_rad_per_s: float
    top_acceleration_rad_per_s2: float
    hook_load_n: float
    hole_u: np.ndarray | None = None

    def copy(self) -> 'BatchState':
        return BatchState(self.time_s, self.q.copy(), self.q_rate.copy(),
                          self.q_acceleration.copy(), self.top_angle_rad,
                          self.top_speed_rad_per_s, self.top_acceleration_rad_per_s2,
                          self.hook_load_n, None if self.hole_u is None else self.hole_u.copy())

    def take(self, members) -> 'BatchState':
        """The state of ``members`` (indices) only, copied."""
        return BatchState(self.time_s, self.q[members].copy(), self.q_rate[members].copy(),
                          self.q_acceleration[members].copy(), self.top_angle_rad,
                          self.top_speed_rad_per_s, self.top_acceleration_rad_per_s2,
                          self.hook_load_n,
                          None if self.hole_u is None else self.hole_u[members].copy())


@dataclass(frozen=True)
class StepResult:
    """Outcome of one step: success unless a member diverged or did not converge.

    converged, finite: per member (m,); iterations: used; error: final relative velocity
    increment per member; message: why it failed ('' on success); forces: the forces of the
    final state (the bit's exactly, the others at each member's last evaluation).
    retries: (m,) sub-steps each member was integrated on after its full step failed (0 when
    the full step worked; set by the Simulator, None from the integrator alone).
    """

    success: bool
    converged: np.ndarray
    finite: np.ndarray
    iterations: int
    error: np.ndarray
    message: str
    forces: ForceEvaluation
    retries: np.ndarray | None = None


@dataclass
class Counters:
    """Work done so far."""

    steps: int = 0
    iterations: int = 0
    force_evaluations: int = 0
    bit_law_evaluations: int = 0
    failed_steps: int = 0


@dataclass(frozen=True)
class _BitSolution:
    """The bit's velocities and forces at a solution of its 2x2 equation, per member."""

    rop: np.ndarray
    omega: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    lifted: np.ndarray
    jacobian: np.ndarray
    solved: np.ndarray


_BIT_FIELDS = ('rop', 'omega', 'force', 'torque', 'lifted', 'jacobian', 'solved')


class NewmarkIntegrator:
    """Average-acceleration Newmark with a cached S0^-1 and an exact bit solve.

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
        # f_NL without the bit: the bit-rock law is solved with the 2x2 equation of each
        # iteration (forces at the iterate's velocities would cancel out, and are singular
        # at omega = 0).
        self._forces_without_bit = copy.copy(forces)
        self._forces_without_bit.physics = replace(forces.physics, bit_rock=False)
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
        self.bit_rows_t = np.ascontiguousarray(local[:, :2])               # B, (n, 2)
        self.bit_rows = np.ascontiguousarray(local[:, :2].T)               # B^T, (2, n)
        self.bit_response = np.ascontiguousarray(self.local_response[:, :2])   # S0^-1 B
        self.bit_flexibility = self.local_gram[:2, :2]                     # B^T S0^-1 B
        self.bit_axial_row = np.ascontiguousarray(local[:, 0])              # u_bit = q . row
        self.static_bit_force = np.array([forces.static_weight_on_bit_n, 0.0])
        self.top_axial_row = system.top_axial_row
        self.static_hook_load_n = system.model.prestress.hook_load_n
        self.counters = Counters()
        self._rate = None                 # per member: contraction rate of its last 2-iteration step
        self._steps_since_verified = None
        self._active = None               # (contact flags, lift-off flags) at the last step
        self._before_step = None          # the bookkeeping before the last step

    # -- initial state -------------------------------------------------------------------
    def initial_state(self, q: np.ndarray, q_rate: np.ndarray, top_speed_rad_per_s: float,
                      hook_load_n: float, top_angle_rad: float = 0.0,
                      hole_u: np.ndarray | None = None) -> BatchState:
        """A state at t = 0 with the accelerations that balance Eq. 35 (fixed point).

        hole_u: the hole bottom (m,), or None to put it where the bit is (on bottom)."""
        state = BatchState(0.0, np.array(q, dtype=float), np.array(q_rate, dtype=float),
                           np.zeros_like(q, dtype=float), top_angle_rad,
                           top_speed_rad_per_s, 0.0, hook_load_n)
        bit_u = state.q @ self.bit_axial_row
        state.hole_u = bit_u.copy() if hole_u is None else np.maximum(
            np.broadcast_to(np.asarray(hole_u, dtype=float), bit_u.shape), bit_u)
        load = self._external_load(state.top_speed_rad_per_s, 0.0, hook_load_n)
        for _ in range(5):
            evaluation = self.evaluate(state)
            residual_free = (evaluation.modal + load - state.q_rate @ self.damping_t
                             - self._stiffness_times(state.q))
            state.q_acceleration = la.solve(self.mass, residual_free.T).T
        return state

    def evaluate(self, state: BatchState) -> ForceEvaluation:
        """f_NL at a state, with the bit-rock law of Eq. 25 at its velocities when the bit is
        on bottom (and no rock force when it is off bottom)."""
        fields = Kinematics.of(self.system, state.q, state.q_rate, state.q_acceleration,
                               state.top_speed_rad_per_s, state.top_acceleration_rad_per_s2,
                               state.top_angle_rad)
        evaluation = self._forces_without_bit.evaluate(fields, self.germ)
        if not self.forces.physics.bit_rock:
            return evaluation
        rop, omega = evaluation.rop_m_per_s, evaluation.bit_speed_rad_per_s
        force, torque, lifted, jacobian = self.forces.law.forces_and_jacobian(rop, omega,
                                                                               self.germ)
        if state.hole_u is not None:
            off = state.q @ self.bit_axial_row < state.hole_u - ON_BOTTOM_TOLERANCE_M
            force, torque = np.where(off, 0.0, force), np.where(off, 0.0, torque)
            lifted = lifted | off
            jacobian = np.where(off[:, None, None], 0.0, jacobian)
        bit = _BitSolution(rop, omega, force, torque, lifted, jacobian,
                           np.ones(rop.shape, dtype=bool))
        return self._with_bit(evaluation, bit)

    def with_time_step(self, time_step_s: float) -> 'NewmarkIntegrator':
        """The same integrator (forces, tolerance, germs) with another time step."""
        return NewmarkIntegrator(self.forces, time_step_s, self.tolerance, self.max_iterations,
                                 self.germ)

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
        hole = state.hole_u if state.hole_u is not None else state.q @ self.bit_axial_row
        # The end-of-step ROP that puts the bit on the hole bottom (Newmark: d = d* +
        # (beta/gamma) dt (v - v*)); below it the bit ends the step above the bottom.
        row = self.bit_axial_row
        touch = d_pred @ row
        touch = np.maximum(v_pred @ row + GAMMA / (BETA * dt) * (hole - touch), 0.0)
        bookkeeping = self._bookkeeping()              # restored if the step fails
        a = state.q_acceleration.copy()
        error = np.full(members, np.inf)
        active = np.ones(members, dtype=bool)        # members still iterating
        bit_ok = np.ones(members, dtype=bool)
        final = bit = None
        iterations = 0
        for iterations in range(1, self.max_iterations + 1):
            d = d_pred + BETA * dt * dt * a
            v = v_pred + GAMMA * dt * a
            fields = Kinematics.of(self.system, d, v, a, top_speed_rad_per_s, top_acceleration,
                                   top_angle)
            evaluation = self._forces_without_bit.evaluate(fields, self.germ)
            self.counters.force_evaluations += 1
            # Frozen members were evaluated at their final state: keep that evaluation.
            final = evaluation if final is None else _merge(final, evaluation, ~active)
            residual = (self._mass_times(a) + v @ self.damping_t + self._stiffness_times(d)
                        - evaluation.modal - load)
            updated, solution = self._update(a, residual, evaluation, touch)
            if active.all():
                increment, a, bit = a - updated, updated, solution
            else:
                increment = np.where(active[:, None], a - updated, 0.0)
                a = np.where(active[:, None], updated, a)
                bit = _merge_bit(bit, solution, active)
            bit_ok &= ~active | solution.solved
            speed = np.linalg.norm(v, axis=1)
            previous_error = error
            new_error = GAMMA * dt * np.linalg.norm(increment, axis=1) / (speed + VELOCITY_SCALE)
            error = np.where(active, new_error, error)
            active &= np.isfinite(error) & bit_ok       # a failing member stops alone
            done = active & (error <= self.tolerance)
            if iterations == 1:
                accepted = active & self._accept_first_iterate(error, evaluation,
                                                               solution.lifted)
                error = np.where(accepted, self._rate / (1.0 - self._rate) * error, error)
                done |= accepted
            elif iterations == 2:
                measured = active & (previous_error > 0)
                rate = np.where(measured, error / np.where(measured, previous_error, 1.0), np.nan)
                usable = measured & (rate < 1.0)
                self._rate = np.where(usable, rate, self._rate)
                self._steps_since_verified = np.where(usable, 0, self._steps_since_verified)
            active &= ~done
            if not active.any():
                break
        evaluation = self._with_bit(final, bit)
        self._steps_since_verified += 1
        self._active = (evaluation.contact.in_contact.copy(), evaluation.lifted.copy())
        d = d_pred + BETA * dt * dt * a
        v = v_pred + GAMMA * dt * a
        hole = np.maximum(hole, d @ row)                 # the hole only deepens
        finite = np.all(np.isfinite(d), axis=1) & np.all(np.isfinite(v), axis=1)
        converged = finite & bit_ok & (error <= self.tolerance)
        success = bool(converged.all())
        time = state.time_s + dt
        message = ''
        if not np.all(finite):
            message = f'non-finite state at t = {time:.6g} s (members {np.flatnonzero(~finite)})'
        elif not np.all(bit_ok):
            message = (f'the bit-rock equation has no solution at t = {time:.6g} s '
                       f'(members {np.flatnonzero(~bit_ok)})')
        elif not success:
            message = (f'no convergence in {self.max_iterations} iterations at t = {time:.6g} s '
                       f'(members {np.flatnonzero(~converged)}, error {np.max(error):.3g})')
        self._before_step = bookkeeping
        if not success:                                # a failed member's step leaves no trace
            self._restore(bookkeeping, ~converged)
        self.counters.steps += 1
        self.counters.iterations += iterations
        self.counters.failed_steps += int(not success)
        new_state = BatchState(time, d, v, a, top_angle, top_speed_rad_per_s, top_acceleration,
                               hook_load_n, hole)
        return new_state, StepResult(success, converged, finite, iterations, error, message,
                                     evaluation)

    def _bookkeeping(self):
        copy = (lambda x: None if x is None else
                (tuple(v.copy() for v in x) if isinstance(x, tuple) else x.copy()))
        return copy(self._rate), copy(self._steps_since_verified), copy(self._active)

    def _restore(self, bookkeeping, members=None) -> None:
        """Put back the bookkeeping of ``members`` (a mask; None: all) as it was."""
        rate, since, active = bookkeeping
        if members is None or rate is None or active is None or self._rate is None:
            self._rate, self._steps_since_verified, self._active = bookkeeping
            return
        self._rate[members] = rate[members]
        self._steps_since_verified[members] = since[members]
        for now, before in zip(self._active, active):
            now[members] = before[members]

    def discard_last_step(self) -> None:
        """Forget the last step entirely (its caller did not keep it)."""
        if self._before_step is not None:
            self._restore(self._before_step)
            self._before_step = None

    def forget(self, members) -> None:
        """Drop the contraction-rate history of ``members`` (indices; None: of everyone), so
        that their next step verifies its first iterate."""
        if members is None:
            self._rate = self._steps_since_verified = self._active = None
        elif self._rate is not None:
            self._rate[members] = np.nan

    def _accept_first_iterate(self, error, evaluation, lifted) -> np.ndarray:
        """Members whose first iterate is accepted on their own contraction rate (m,)."""
        members = error.shape[0]
        if self._rate is None or self._rate.shape != (members,):
            self._rate = np.full(members, np.nan)
            self._steps_since_verified = np.zeros(members, dtype=int)
            return np.zeros(members, dtype=bool)
        accept = np.isfinite(self._rate) & (self._steps_since_verified < VERIFY_EVERY)
        if self._active is not None:
            contact = self._active[0]
            accept &= (contact == evaluation.contact.in_contact).all(axis=1)
            accept &= self._active[1] == lifted
        with np.errstate(invalid='ignore'):
            accept &= self._rate / (1.0 - self._rate) * error <= self.tolerance
        return accept

    # -- the update of one iteration -----------------------------------------------------
    def _update(self, a, residual, evaluation: ForceEvaluation, touch):
        """New accelerations (m, n) with the bit solved exactly (module docstring); the
        residual is without the bit's forces; touch: (m,) the ROP that reaches the hole bottom
        at the end of the step (0 on bottom)."""
        gdt = GAMMA * self.time_step_s
        y, response = self._inverse_with_contact(residual, evaluation)
        if response is None:                                  # no contact: constant S0
            flexibility = np.broadcast_to(self.bit_flexibility, (a.shape[0], 2, 2))
        else:
            flexibility = np.einsum('in,mnj->mij', self.bit_rows, response)   # B^T S^-1 B
        start = np.stack([evaluation.rop_m_per_s, evaluation.bit_speed_rad_per_s], axis=1)
        linear = start - gdt * (y @ self.bit_rows_t)
        solution = self._solve_bit(linear, flexibility, start, touch)
        force = np.stack([solution.force, solution.torque], axis=1) - self.static_bit_force
        if response is None:
            return a - y + force @ self.bit_response.T, solution
        return a - y + np.einsum('mnj,mj->mn', response, force), solution

    def _inverse_with_contact(self, vectors, evaluation: ForceEvaluation):
        """S^-1 r and S^-1 B per member, S = S0 + contact tangents of the touching nodes
        (S^-1 B is None when no member touches the wall: then it is the constant S0^-1 B)."""
        members = vectors.shape[0]
        y = vectors @ self.effective_inverse_t
        touching = evaluation.contact.in_contact
        if evaluation.contact_tangent is None or not touching.any():
            return y, None                                    # S = S0 for every member
        contact_members = np.flatnonzero(np.any(touching, axis=1))
        response = np.repeat(self.bit_response[None], members, axis=0)
        dt2 = BETA * self.time_step_s ** 2
        n_nodes = self.system.n_nodes
        for member in contact_members:
            nodes = np.flatnonzero(touching[member])
            index = np.ravel(np.column_stack([2 + nodes, 2 + n_nodes + nodes]))
            rank = index.size
            d = np.zeros((rank, rank))
            for k, node in enumerate(nodes):
                d[2 * k:2 * k + 2, 2 * k:2 * k + 2] = dt2 * evaluation.contact_tangent[member, node]
            gram = self.local_gram[np.ix_(index, index)]
            correction = np.linalg.solve(np.eye(rank) + d @ gram, d)     # (I + D G)^-1 D
            directions = self.local_response[:, index]
            y[member] -= directions @ (correction @ (self.local_directions[:, index].T
                                                     @ y[member]))
            response[member] -= directions @ (correction @ self.local_gram[np.ix_(index, [0, 1])])
        return y, response

    def _solve_bit(self, linear, flexibility, start, touch) -> _BitSolution:
        """Solve x = linear + gamma dt H (F(x) - F_c) per member.

        Fast path: one Newton step on Eq. 25 from the iterate's velocities ``start``, kept
        where it stays on the law's cutting branch (bit on bottom and cutting, omega > 0,
        same signs, ROP within a factor of two, the force below the torque-fade force):
        there the law is smooth and the outer iteration checks the linearisation. Everyone
        else gets the bracketed solve of :mod:`drill_twin.dynamics.bit_equation`, which
        cannot fail (lift-off, landing, rest on bottom, stopped or backward rotation).
        """
        gdt = GAMMA * self.time_step_s
        law, germ = self.forces.law, self.germ
        members = linear.shape[0]
        if not self.forces.physics.bit_rock:
            return _BitSolution(linear[:, 0], linear[:, 1],
                                np.full(members, self.static_bit_force[0]), np.zeros(members),
                                np.zeros(members, bool), np.zeros((members, 2, 2)),
                                np.ones(members, bool))
        force, torque, lifted, jacobian = law.forces_and_jacobian(start[:, 0], start[:, 1], germ)
        self.counters.bit_law_evaluations += 1
        applied = np.stack([force, torque], axis=1) - self.static_bit_force
        g = start - linear - gdt * np.einsum('mij,mj->mi', flexibility, applied)
        step = _solve2(np.eye(2) - gdt * flexibility @ jacobian, g)
        x = start - step
        carried = np.stack([force, torque], axis=1) - np.einsum('mij,mj->mi', jacobian, step)
        safe = (np.all(np.sign(x) == np.sign(start), axis=1)
                & (np.abs(step[:, 0]) <= 0.5 * np.abs(start[:, 0]))
                & ~lifted & (carried[:, 0] < 0) & (x[:, 0] > touch) & (x[:, 1] > 0))
        fast = x[:, 1] >= law.fade_speed_rad_per_s        # where the torque may fade
        if fast.any():
            with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
                mean_force = law.mean(x[:, 0], x[:, 1])[0]
                safe &= ~fast | (mean_force < law.fade_force(x[:, 1]))
        solution = _BitSolution(x[:, 0], x[:, 1], carried[:, 0], carried[:, 1],
                                np.zeros(members, bool), jacobian, np.ones(members, bool))
        if safe.all():
            return solution
        rest = np.flatnonzero(~safe)
        c = gdt * np.stack([flexibility[rest, 0, 0], flexibility[rest, 1, 1]], axis=1)
        b = linear[rest] - c * self.static_bit_force
        # A bit that cannot reach the rock (or outruns the law's cut at zero force) at the
        # speed it has without a rock torque is free: F = 0, omega = b2, no search.
        free = ~(b[:, 0] > np.maximum(touch[rest], law.cutting_rate(0.0, b[:, 1])))
        rop, omega = b[:, 0].copy(), b[:, 1].copy()
        f1, f2 = np.zeros(rest.size), np.zeros(rest.size)
        lf = np.ones(rest.size, dtype=bool)
        search = np.flatnonzero(~free)
        if search.size:
            sub_germ = None if germ is None else germ[rest[search]]
            found = solve_bit_equation(law, b[search], c[search], touch[rest[search]], sub_germ,
                                       omega_guess=start[rest[search], 1])
            for array, value in zip((rop, omega, f1, f2, lf), found):
                array[search] = value
        self.counters.bit_law_evaluations += 1
        # The Jacobian of a guarded member is the law's at the iterate (it informs nothing).
        jacobian[rest] = np.where(lf[:, None, None], 0.0, jacobian[rest])
        robust = _BitSolution(rop, omega, f1, f2, lf, jacobian[rest],
                              np.isfinite(rop) & np.isfinite(omega))
        for name in _BIT_FIELDS:
            getattr(solution, name)[rest] = getattr(robust, name)
        return solution

    def _with_bit(self, evaluation: ForceEvaluation, bit: _BitSolution) -> ForceEvaluation:
        """The evaluation with the bit's forces of the final state (exact)."""
        full = evaluation.full.copy()
        system = self.system
        axial = system.field(0).start + system.bit_node
        torsion = system.field(1).start + system.bit_node
        change = np.stack([bit.force - evaluation.weight_on_bit_n,
                           bit.torque - evaluation.torque_on_bit_nm], axis=1)
        full[:, axial] += change[:, 0]
        full[:, torsion] += change[:, 1]
        return replace(evaluation, full=full, modal=evaluation.modal + change @ self.bit_rows,
                       weight_on_bit_n=bit.force,
                       torque_on_bit_nm=bit.torque, rop_m_per_s=bit.rop,
                       bit_speed_rad_per_s=bit.omega, lifted=bit.lifted,
                       bit_jacobian=bit.jacobian)


def _solve2(matrix, vector):
    """Solve (m, 2, 2) x = (m, 2) explicitly."""
    a, b = matrix[:, 0, 0], matrix[:, 0, 1]
    c, d = matrix[:, 1, 0], matrix[:, 1, 1]
    determinant = a * d - b * c
    return np.stack([(d * vector[:, 0] - b * vector[:, 1]) / determinant,
                     (a * vector[:, 1] - c * vector[:, 0]) / determinant], axis=1)


def _pick(members, kept, new):
    mask = members.reshape((-1,) + (1,) * (np.ndim(kept) - 1))
    return np.where(mask, new, kept)


def _merge_bit(kept: _BitSolution, new: _BitSolution, members) -> _BitSolution:
    """``new`` for ``members``, ``kept`` for the others."""
    return _BitSolution(*(_pick(members, getattr(kept, f), getattr(new, f))
                          for f in _BIT_FIELDS))


def _merge(kept: ForceEvaluation, new: ForceEvaluation, members: np.ndarray) -> ForceEvaluation:
    """``new`` for ``members`` (their final state), ``kept`` for the others."""
    if not np.any(members):
        return kept
    if np.all(members):
        return new
    contact = ContactForces(_pick(members, kept.contact.radial_force_n,
                                  new.contact.radial_force_n),
                            _pick(members, kept.contact.in_contact, new.contact.in_contact))
    tangent = None
    if kept.contact_tangent is not None or new.contact_tangent is not None:
        tangent = _pick(members, _tangent_or_zero(kept), _tangent_or_zero(new))
    return ForceEvaluation(
        full=_pick(members, kept.full, new.full), modal=_pick(members, kept.modal, new.modal),
        weight_on_bit_n=_pick(members, kept.weight_on_bit_n, new.weight_on_bit_n),
        torque_on_bit_nm=_pick(members, kept.torque_on_bit_nm, new.torque_on_bit_nm),
        rop_m_per_s=_pick(members, kept.rop_m_per_s, new.rop_m_per_s),
        bit_speed_rad_per_s=_pick(members, kept.bit_speed_rad_per_s, new.bit_speed_rad_per_s),
        lifted=_pick(members, kept.lifted, new.lifted),
        bit_jacobian=_pick(members, kept.bit_jacobian, new.bit_jacobian),
        contact=contact, contact_tangent=tangent)


def _tangent_or_zero(evaluation: ForceEvaluation) -> np.ndarray:
    if evaluation.contact_tangent is not None:
        return evaluation.contact_tangent
    return np.zeros(evaluation.contact.in_contact.shape + (2, 2))
