"""
Implicit Newmark (average acceleration) on the reduced model, for a batch of members.

Each step solves, for the accelerations a = q''(t + dt) of every member,

    R(a) = [M_r] a + [C_r] v + [K_r] d - Phi^T f_NL(d, v, a) - g(t + dt) = 0,
    d = d* + beta dt^2 a,   v = v* + gamma dt a   (beta = 1/4, gamma = 1/2).

Iteration. At an iterate a_k the finite-strain and kinetic-coupling forces are frozen (a fixed
point, as in the paper: they are small and smooth), the wall contact is linearised (Newton:
its 2x2 stiffness k_ip [n n^T + (p/r)(I - n n^T)] at every touching node) and the bit-rock law
is solved exactly. With S = S0 + U_c D_c U_c^T (S0 = M_r + gamma dt C_r + beta dt^2 K_r,
inverted once; the contact terms, and the inertia of an imbalance (excitation.py) on its node's
(v, w, theta_x), added per member by the Woodbury identity) the accelerations are linear in
the bit force F:

    a = a_k - S^-1 R_nobit(a_k) + S^-1 B (F(x) - F_c),

B holding the rows of Phi at the bit's axial and torsional DOFs and F_c = (f_c, 0) the
prestress reaction. So the bit velocities x = (ROP, omega) obey the 2x2 equation

    x = x_lin + gamma dt H (F(x) - F_c),   H = B^T S^-1 B,

solved per member: one Newton step from the iterate's velocities where it stays on the law's
cutting branch, else the bracketed solve of :mod:`drill_twin.model.bit_equation`, which
cannot fail (the law is stiff, kinked at lift-off, and flat or steep in places for random
germs). The accelerations then follow. The
step ends when every member's velocity increment is below ``tolerance`` relative to its
velocity (failure after ``max_iterations``).

Acceptance after one iteration. With the bit solved exactly the first update already lands
within about 1e-12 of the solution, so a second force evaluation would only confirm it. As
scipy's implicit solvers do, each member keeps the contraction rate rho = |increment_2| /
|increment_1| of its last step that ran two iterations and accepts its first iterate when
rho / (1 - rho) |increment_1| (the estimated remaining error) is below the tolerance. It
verifies with a second iteration whenever its set of nodes touching the wall or its bit's
lift-off state changed, and once every VERIFY_EVERY steps of the model's clock to refresh rho,
in groups of VERIFY_GROUP members VERIFY_SPACING steps apart (at most VERIFY_SLOTS steps of a
cycle: further groups share them). The schedule is the clock's, not
counted from each member's last verification, so two runs of the same members take the same
decisions whenever they were started; and since the later iterations run on the members
still iterating only, a step's extra cost is that of a group, not of the batch (a 64-member
batch verifying all at once would run a second full iteration on 4 % of its steps).

Members are independent: every decision (convergence, acceptance, verification) is taken per
member and converged members are frozen while others iterate, so a member's trajectory does
not depend on the rest of its batch (up to the rounding of batched products).

g(t) = -Phi^T (M psi theta_top'' + C psi theta_top') carries the imposed top rotation, and
-Phi^T e_top (H - H_S) the change of hook load from its prestressed value.

Implementation. A step is one compiled call (:func:`newmark_kernel.step`): arrays members
last, (n, m), so the dense products run in BLAS over the batch and the rest member by member
without the interpreter; the forces of the string are summed by
:func:`drill_twin.model.forces.string_forces`. The compiled step reads its operands by name
from the structures of :mod:`~drill_twin.integrator.step_operands`, made by
:mod:`~drill_twin.integrator.newmark_operands`: those that depend on the system and dt once,
the law's with the germs and factors, the work arrays once per batch size; the state and the
evaluation a step returns are new arrays (callers keep them).
"""
from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
import scipy.linalg as la

from drill_twin.integrator import newmark_kernel as compiled
from drill_twin.integrator.batch_state import (BatchState, Counters, StepResult,  # noqa: F401
                                               make_step_result, merged_result)
from drill_twin.integrator.newmark_kernel import ON_BOTTOM_TOLERANCE_M
from drill_twin.integrator.newmark_operands import (BatchWork, bit_law, final_evaluation,
                                                    stiffness_diagonal, step_operators,
                                                    string_force_operands)
from drill_twin.integrator.step_operands import (AcceptanceHistory, StepCounts, StepInputs,
                                                 StepOperands, StepStart, make_step_operands)
from drill_twin.model.forces import ForceEvaluation, Kinematics, NonlinearForces
from drill_twin.numerics.records import record

BEARING_AGREEMENT = 1e-7
"""Relative difference between the law's force at the bit's velocities and the force the
compliant rock bears beyond which :meth:`NewmarkIntegrator.evaluate` takes the bit to rest on
the rock's spring (its Jacobian is then zero); on the cutting branch they agree to rounding."""


class NewmarkIntegrator:
    """
    Average-acceleration Newmark with a cached S0^-1 and an exact bit solve.

    :param forces: the non-linear forces of a reduced system.
    :param time_step_s: dt (s).
    :param tolerance: relative velocity increment that ends the iteration.
    :param max_iterations: iteration cap per step.
    :param germ: (m, 2, 2) random germs of the bit-rock law, or None for the mean model.
    :param law_scales: (m, 5) factors of the law's a1 ... a5 per member, or None (the
        configured law for all).

    ``operators`` (:class:`~drill_twin.integrator.step_operands.StepOperators`) holds what
    the step reads of the system and dt, by name (S0^-1, the local directions U and their
    responses, B^T = ``operators.local.bit_rows``, ...).
    """

    def __init__(self, forces: NonlinearForces, time_step_s: float, tolerance: float,
                 max_iterations: int, germ: np.ndarray | None = None,
                 law_scales: np.ndarray | None = None):
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
        self._germ = germ
        self._law_scales = None if law_scales is None else np.array(law_scales, dtype=float)
        self.mass, self.damping, self.stiffness = system.mass, system.damping, system.stiffness
        self._stiffness_diagonal = stiffness_diagonal(self.stiffness)
        self.damping_t = np.ascontiguousarray(self.damping.T)
        self.operators = step_operators(forces, self.time_step_s, self.tolerance,
                                        self.max_iterations)
        self.bit_rows = self.operators.local.bit_rows                     # B^T, (2, n)
        self.bit_rows_t = np.ascontiguousarray(self.bit_rows.T)            # B, (n, 2)
        self.bit_axial_row = self.operators.local.bit_axial_row            # u_bit = q . row
        self.counters = Counters()
        self._hook_scalar = np.empty(1)                  # one hook load for the batch (N)
        self._string_forces = string_force_operands(self._forces_without_bit)
        self._law = bit_law(forces, germ, self._law_scales)
        self._work: BatchWork | None = None
        self._rate = None                 # per member: the contraction rate of its last
        #                                   2-iteration step
        self._active = None               # (contact flags, lift-off flags) at the last step
        self._before_step = None          # the bookkeeping before the last step
        self._flat_surface = None         # bottom_surface's zeros without a lobed bottom
        self._operands_of = None          # (law, work, StepOperands)

    # -- initial state -------------------------------------------------------------------
    def initial_state(self, q: np.ndarray, q_rate: np.ndarray, top_speed_rad_per_s: float,
                      hook_load_n: float, top_angle_rad: float = 0.0,
                      hole_u: np.ndarray | None = None) -> BatchState:
        """
        Return a state at t = 0 with the accelerations that balance Eq. 35 (fixed point).

        hole_u: the hole bottom (m,), or None to put it where the bit is (on bottom; on a
        compliant rock, above the bit by the depth its force presses the rock).
        """
        state = BatchState(0.0, np.array(q, dtype=float), np.array(q_rate, dtype=float),
                           np.zeros_like(q, dtype=float), top_angle_rad,
                           top_speed_rad_per_s, 0.0, hook_load_n)
        # The bit's own position, on the lobes' surface when it has one (the hole's mean
        # bottom is s above that surface).
        bit_u = state.q @ self.bit_axial_row - self.bottom_surface(state)[0]
        state.hole_u = bit_u.copy() if hole_u is None else np.maximum(
            np.broadcast_to(np.asarray(hole_u, dtype=float), bit_u.shape), bit_u)
        compliance = self.forces.law.compliance
        if compliance > 0.0 and self.forces.physics.bit_rock:
            # A bit on bottom presses a compliant rock by -f / k, f the law's force at the
            # bit's velocities: the hole's (undeformed) bottom is that much above the bit. A
            # given hole is kept unless the bit is deeper in the rock than its force explains.
            pressed = bit_u + compliance * np.minimum(
                self.evaluate(state, bearing=False).weight_on_bit_n, 0.0)
            if hole_u is None:
                state.hole_u = pressed
            else:
                given = np.broadcast_to(np.asarray(hole_u, dtype=float), bit_u.shape)
                state.hole_u = np.where(given < pressed - ON_BOTTOM_TOLERANCE_M, pressed, given)
        load = self._external_load(state.top_speed_rad_per_s, 0.0, hook_load_n)
        for _ in range(5):
            evaluation = self.evaluate(state)
            residual_free = (evaluation.modal + load - state.q_rate @ self.damping_t
                             - self._stiffness_times(state.q))
            previous, state.q_acceleration = (state.q_acceleration,
                                              la.solve(self.mass, residual_free.T).T)
            if np.array_equal(state.q_acceleration, previous):
                break                     # a fixed point: every further pass gives the same
        return state

    def evaluate(self, state: BatchState, bearing: bool = True) -> ForceEvaluation:
        """
        f_NL at a state.

        With the bit-rock law of Eq. 25 at its velocities when the bit is on bottom (and no
        rock force when it is off bottom); a bit rising on bottom (ROP < 0) gets the torque of
        the law's resting branch at its force (docs/MODEL-CHOICES.md).

        On a compliant rock the state also holds the force the rock bears: -k times the depth
        by which the bit presses the hole's bottom, which is what every step ends with (the
        hole's bottom ends where the bit ends less -F1 / k, on both branches of the bit's
        solve). For every bit on bottom the rock's force is the spring's and the torque that
        of the law's graph at that force (:meth:`BitRockLaw.bearing_torque`), as the step has
        them: on the cutting branch they equal the law's at the velocities to rounding; on the
        resting branch (moving faster than its law cuts at that force) the law there would
        give twice the force or more. Taken for every member, not only where the two differ,
        so that the evaluation is continuous in the state. The law's Jacobian is kept where
        the two agree (cutting) and is zero on the resting branch. ``bearing=False``: the law
        at the velocities only (what a hole being placed under the bit needs).
        """
        fields = Kinematics.of(self.system, state.q, state.q_rate, state.q_acceleration,
                               state.top_speed_rad_per_s, state.top_acceleration_rad_per_s2,
                               state.top_angle_rad)
        evaluation = self._forces_without_bit.evaluate(fields, self.germ)
        if not self.forces.physics.bit_rock:
            return evaluation
        rop, omega = evaluation.rop_m_per_s, evaluation.bit_speed_rad_per_s
        height, height_rate = self.bottom_surface(state, omega)
        rop = rop - height_rate                    # the law: relative to the lobes' surface
        force, torque, lifted, jacobian = self.forces.law.forces_and_jacobian(
            rop, omega, self.germ, self._law_scales)
        rising = (rop < 0.0) & ~lifted
        if np.any(rising):
            # A bit rising while it still presses the rock does not cut: its torque is the
            # resting branch's at that force (as the step's solve has it; Eq. 26 read at a
            # negative ROP would make the rock drive the bit). Its Jacobian is not the law's.
            torque, jacobian = np.array(torque, dtype=float), np.array(jacobian)
            for i in np.flatnonzero(rising):
                law = (self.forces.law if self._law_scales is None
                       else self.forces.law.scaled(self._law_scales[i]))
                torque[i] = law.torque_of_force(force[i], omega[i])
                jacobian[i] = 0.0
        if state.hole_u is not None:
            bit_u = state.q @ self.bit_axial_row
            off = bit_u < state.hole_u + height - ON_BOTTOM_TOLERANCE_M
            force, torque = np.where(off, 0.0, force), np.where(off, 0.0, torque)
            lifted = lifted | off
            jacobian = np.where(off[:, None, None], 0.0, jacobian)
            compliance = self.forces.law.compliance
            if bearing and compliance > 0.0:
                borne = np.where(off, 0.0, -np.maximum(bit_u - state.hole_u - height, 0.0)
                                 / compliance)
                resting = ~off & (np.abs(borne - force)
                                  > BEARING_AGREEMENT * np.abs(borne) + 1e-9)
                law_torque = self.forces.law.bearing_torque(borne, omega, self.germ,
                                                            self._law_scales)
                force = np.where(off, force, borne)
                torque = np.where(off, torque, law_torque)
                lifted = np.where(off, lifted, borne >= 0.0)
                jacobian = np.where(resting[:, None, None], 0.0, jacobian)
        return self._with_bit(evaluation, rop=rop + height_rate, omega=omega, force=force,
                              torque=torque, lifted=lifted, jacobian=jacobian)

    def bottom_surface(self, state: BatchState, omega: np.ndarray | None = None):
        """
        Return (s, ds/dt) of the lobed hole bottom under each member's bit, (m,) each (m, m/s).

        s: how far the undeformed rock under the bit lies below the hole's mean bottom
        (``state.hole_u``), at the bit's angle (top-drive angle plus twist); ds/dt at the bit's
        spin rate ``omega`` (m,) (rad/s; zeros if None). Zeros without a pattern.
        """
        members = state.q.shape[0]
        pattern = self.forces.bottom_pattern
        if pattern is None:                      # (read-only zeros, kept per batch size)
            if self._flat_surface is None or self._flat_surface[0].shape[0] != members:
                zeros = np.zeros(members)
                zeros.flags.writeable = False
                self._flat_surface = (zeros, zeros)
            return self._flat_surface
        angle = self.bit_angle_rad(state.q, state.top_angle_rad)
        rate = np.zeros(members) if omega is None else omega
        return pattern.height_m(angle), pattern.height_rate_m_per_s(angle, rate)

    def bit_angle_rad(self, q: np.ndarray, top_angle_rad: float) -> np.ndarray:
        """Return the bits' spin angles (top-drive angle plus twist) of coordinates q (m, n)."""
        return top_angle_rad + q @ self.bit_rows[1]

    @property
    def germ(self) -> np.ndarray | None:
        """(m, 2, 2) random germs of the bit-rock law, or None (mean model)."""
        return self._germ

    @germ.setter
    def germ(self, germ: np.ndarray | None) -> None:
        self._germ = germ
        self._set_law_constants(germ)

    @property
    def law_scales(self) -> np.ndarray | None:
        """(m, 5) factors of the bit-rock law's a1 ... a5 per member, or None (the law's)."""
        return self._law_scales

    @law_scales.setter
    def law_scales(self, scales: np.ndarray | None) -> None:
        if scales is not None:
            scales = np.array(scales, dtype=float)
            if scales.ndim != 2 or scales.shape[1] != 5 or not np.all(scales > 0):
                raise ValueError('law scales must be positive, shape (m, 5)')
        self._law_scales = scales
        self._set_law_constants(self._germ)

    def adopt(self, source: 'NewmarkIntegrator', members) -> None:
        """Take ``source``'s germs and law scales of ``members`` (an index or a slice)."""
        germ, scales = source.germ, source.law_scales
        self._germ = None if germ is None else germ[members]
        self.law_scales = None if scales is None else scales[members]

    def _set_law_constants(self, germ) -> None:
        """Make the step's law operands of ``germ`` and the scales (:func:`bit_law`)."""
        self._law = bit_law(self.forces, germ, self._law_scales)

    def with_time_step(self, time_step_s: float) -> 'NewmarkIntegrator':
        """Return the same integrator (forces, tolerance, germs, law) with another time step."""
        return NewmarkIntegrator(self.forces, time_step_s, self.tolerance, self.max_iterations,
                                 self.germ, self._law_scales)

    def _external_load(self, top_speed, top_acceleration, hook_load_n):
        """
        Return the modal load of the driven rotation and the hook, (n,) or (m, n).

        ``hook_load_n``: one hook load for the batch (N), or one per member, (m,).
        """
        hooks = np.atleast_1d(np.asarray(hook_load_n, dtype=float))
        load = np.empty((self.system.size, hooks.shape[0]))
        compiled.external_load(
            StepInputs(top_speed=float(top_speed), top_acceleration=float(top_acceleration),
                       hooks=np.ascontiguousarray(hooks)), self.operators.load, load)
        return load[:, 0] if np.ndim(hook_load_n) == 0 else load.T

    def _stiffness_times(self, q):
        if self._stiffness_diagonal is not None:
            return q * self._stiffness_diagonal
        return q @ self.stiffness.T

    # -- one step ------------------------------------------------------------------------
    def load_kernels(self, state: BatchState, top_speed_rad_per_s: float,
                     hook_load_n) -> None:
        """
        Load the compiled step for this batch by a step that leaves no trace.

        numba loads a kernel from its on-disk cache (or compiles it) at its first call in a
        process: 0.11-0.13 s for the paper model's step, measured. Done here, at set-up, the
        time loop's first step costs what the others do. The step's result is dropped; the
        contraction rates, the contact and lift-off flags and the counters are put back as
        they were (every evaluation sets the top angle it reads from its own state).
        """
        rate = None if self._rate is None else self._rate.copy()
        active, before, counters = self._active, self._before_step, replace(self.counters)
        with np.errstate(all='ignore'):
            self.step(state, top_speed_rad_per_s, hook_load_n)
        self._rate, self._active, self._before_step = rate, active, before
        for name in vars(counters):                   # in place: callers hold the object
            setattr(self.counters, name, getattr(counters, name))

    def step(self, state: BatchState, top_speed_rad_per_s: float,
             hook_load_n: float) -> tuple[BatchState, StepResult]:
        """
        Advance ``state`` by dt with the top speed and hook load given for t + dt.

        Returns the new state and the step's outcome; on failure the new state holds the
        last iterate (callers must not continue from it silently). The arithmetic runs in
        the kernels of :mod:`drill_twin.integrator.newmark_kernel`; the forces of the string
        in :func:`drill_twin.model.forces.string_forces`.
        """
        dt = self.time_step_s
        top_acceleration = (top_speed_rad_per_s - state.top_speed_rad_per_s) / dt
        top_angle = state.top_angle_rad + 0.5 * dt * (state.top_speed_rad_per_s
                                                      + top_speed_rad_per_s)
        members = state.q.shape[0]
        work = self._batch_work(members)
        history, bookkeeping, outputs, kept = self._acceptance_history(work, state.time_s + dt)
        self._set_top_angle(top_angle)
        start = StepStart(
            q=np.ascontiguousarray(state.q), q_rate=np.ascontiguousarray(state.q_rate),
            q_acceleration=np.ascontiguousarray(state.q_acceleration),
            hole=work.members.touch if state.hole_u is None else state.hole_u,
            has_hole=state.hole_u is not None)
        inputs = StepInputs(top_speed=float(top_speed_rad_per_s),
                            top_acceleration=float(top_acceleration),
                            hooks=self._hooks(hook_load_n))
        counts = StepCounts._make(compiled.step(
            tuple(start), tuple(inputs), tuple(history), self._operands(work), tuple(outputs),
            tuple(kept)))
        evaluation = final_evaluation(outputs, kept, work.final_tangent, counts.touching)
        self._active = (kept.contact, kept.lifted)     # shared, never written in place
        time = state.time_s + dt
        success = counts.converged == members
        message = '' if success else self._failure(time, outputs, work)
        self._before_step = bookkeeping
        if not success:                                # a failed member's step leaves no trace
            self._restore(bookkeeping, ~outputs.converged)
        self._count(counts, success)
        new_state = BatchState(
            time_s=time, q=outputs.q, q_rate=outputs.q_rate,
            q_acceleration=outputs.q_acceleration, top_angle_rad=top_angle,
            top_speed_rad_per_s=top_speed_rad_per_s,
            top_acceleration_rad_per_s2=top_acceleration, hook_load_n=hook_load_n,
            hole_u=outputs.hole)
        return new_state, record(
            StepResult, success=success, converged=outputs.converged, finite=outputs.finite,
            iterations=counts.iterations, error=outputs.error, message=message,
            forces=evaluation, retries=None, on_bottom=outputs.on_bottom,
            members_on_bottom=counts.on_bottom, members_lifted=counts.lifted)

    def _hooks(self, hook_load_n) -> np.ndarray:
        """Return the hook loads (1 or m,) (N) of a step: one for the batch, or per member."""
        if type(hook_load_n) is float or np.ndim(hook_load_n) == 0:
            hooks = self._hook_scalar
            hooks[0] = hook_load_n
            return hooks
        return np.ascontiguousarray(hook_load_n, dtype=float)

    def _acceptance_history(self, work: BatchWork, end_s: float):
        """
        Return a step's (AcceptanceHistory, bookkeeping to undo it, outputs, kept flags).

        The contraction rates (updated in place by the step) are saved in the kept flags'
        saved_rate, the flags of the last step (replaced) kept as they are; ``end_s``: the
        step's end (s), its number on the model's clock.
        """
        members = work.batch_size
        rate, active = self._rate, self._active
        have_rate = rate is not None and rate.shape == (members,)
        if not have_rate:
            self._rate = np.full(members, np.nan)
        outputs, kept = work.outputs.take(), work.kept.take()
        if have_rate:
            kept.saved_rate[:] = rate
        bookkeeping = (kept.saved_rate if have_rate else None if rate is None else rate.copy(),
                       active)
        have_active = active is not None and active[1].shape == (members,)
        previous_contact, previous_lifted = (active if have_active
                                             else (work.no_contact, work.no_lift))
        history = AcceptanceHistory(
            have_rate=have_rate, have_active=have_active, rate=self._rate,
            clock=round(end_s / self.time_step_s), previous_contact=previous_contact,
            previous_lifted=previous_lifted)
        return history, bookkeeping, outputs, kept

    def _set_top_angle(self, top_angle: float) -> None:
        """Set the top-drive angle (rad) the forces of the step's end turn with."""
        self.forces.strain_operators.set_top_angle(top_angle)   # printed_absolute's
        if self.forces.imbalance is not None:          # the angle its force turns with
            self.forces.imbalance.set_top_angle(top_angle)
        if self.forces.bottom_pattern is not None:     # the angle the lobes turn with
            self.forces.bottom_pattern.set_top_angle(top_angle)

    def _failure(self, time: float, outputs, work: BatchWork) -> str:
        """Say why a step ending at ``time`` (s) failed: non-finite, the bit, convergence."""
        finite, converged, bit_ok = outputs.finite, outputs.converged, work.members.bit_ok
        if not np.all(finite):
            return f'non-finite state at t = {time:.6g} s (members {np.flatnonzero(~finite)})'
        if not np.all(bit_ok):
            return (f'the bit-rock equation has no solution at t = {time:.6g} s '
                    f'(members {np.flatnonzero(~bit_ok)})')
        return (f'no convergence in {self.max_iterations} iterations at t = {time:.6g} s '
                f'(members {np.flatnonzero(~converged)}, error {np.max(outputs.error):.3g})')

    def _count(self, counts, success: bool) -> None:
        """Add a step's work to the counters."""
        counters = self.counters
        counters.steps += 1
        counters.iterations += counts.iterations
        counters.force_evaluations += counts.iterations
        counters.bit_law_evaluations += ((counts.iterations + counts.robust)
                                         if self.forces.physics.bit_rock else 0)
        counters.failed_steps += int(not success)

    def _operands(self, work: BatchWork) -> StepOperands:
        """Return the step's operands object, made again when the law or the work changed."""
        made = self._operands_of
        if made is None or made[0] is not self._law or made[1] is not work:
            operands = make_step_operands(
                forces=self._string_forces, operators=self.operators, law=self._law,
                modal=work.modal, members=work.members, force_work=work.force_work,
                compact=work.compact, final_tangent=work.final_tangent,
                final_solved=work.final_solved)
            made = self._operands_of = (self._law, work, operands)
        return made[2]

    def _batch_work(self, members: int) -> BatchWork:
        """Return the work arrays of a step of ``members`` (made again only when m changes)."""
        if self._work is None or self._work.batch_size != members:
            self._work = BatchWork(self._forces_without_bit, members)
        return self._work

    def _restore(self, bookkeeping, members=None) -> None:
        """Put back the bookkeeping of ``members`` (a mask; None: all) as it was."""
        rate, active = bookkeeping
        if members is None or rate is None or active is None or self._rate is None:
            self._rate, self._active = bookkeeping
            return
        self._rate[members] = rate[members]
        # New arrays: the flags are the last evaluation's own, which callers hold.
        contact, lifted = self._active
        self._active = (np.where(members[:, None], active[0], contact),
                        np.where(members, active[1], lifted))

    def discard_last_step(self) -> None:
        """Forget the last step entirely (its caller did not keep it)."""
        if self._before_step is not None:
            self._restore(self._before_step)
            self._before_step = None

    def forget(self, members) -> None:
        """
        Drop the contraction-rate history of ``members`` (indices; None: of everyone).

        So that their next step verifies its first iterate.
        """
        if members is None:
            self._rate = self._active = None
        elif self._rate is not None:
            self._rate[members] = np.nan

    def _with_bit(self, evaluation: ForceEvaluation, *, rop, omega, force, torque, lifted,
                  jacobian) -> ForceEvaluation:
        """
        Return the evaluation with the bit's forces of the final state (exact).

        rop, omega, force, torque (m,), lifted (m,) and jacobian (m, 2, 2): the bit's
        velocities and forces at a solution of its equation, per member.
        """
        full = evaluation.full.copy()
        system = self.system
        axial = system.field(0).start + system.bit_node
        torsion = system.field(1).start + system.bit_node
        change = np.stack([force - evaluation.weight_on_bit_n,
                           torque - evaluation.torque_on_bit_nm], axis=1)
        full[:, axial] += change[:, 0]
        full[:, torsion] += change[:, 1]
        return replace(evaluation, full=full, modal=evaluation.modal + change @ self.bit_rows,
                       weight_on_bit_n=force, torque_on_bit_nm=torque, rop_m_per_s=rop,
                       bit_speed_rad_per_s=omega, lifted=lifted, bit_jacobian=jacobian)
