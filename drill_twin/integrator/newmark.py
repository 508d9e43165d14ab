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
still iterating only, a step's extra cost is that of a group (a 64-member batch verifying
all at once, as it did, cost a second full iteration on 4 % of its steps: the longest twin
ticks).

Members are independent: every decision (convergence, acceptance, verification) is taken per
member and converged members are frozen while others iterate, so a member's trajectory does
not depend on the rest of its batch (up to the rounding of batched products).

g(t) = -Phi^T (M psi theta_top'' + C psi theta_top') carries the imposed top rotation, and
-Phi^T e_top (H - H_S) the change of hook load from its prestressed value.

Implementation. A step is one compiled call (:func:`newmark_kernel.step`): arrays members
last, (n, m), so the dense products run in BLAS over the batch and the rest member by member
without the interpreter; the forces of the string are summed by
:func:`drill_twin.model.forces.string_forces`. Work arrays are made once per batch size;
the state and the evaluation a step returns are new arrays (callers keep them). It replaced
a numpy implementation of the same arithmetic and agrees with it to about 1e-14 relative
over 20 s of the paper's run (``benchmarks/agreement.py``).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as la

from drill_twin.integrator import newmark_kernel as compiled
from drill_twin.model.bit_rock import fade_speeds
from drill_twin.model.bottom_hole_pattern import LobedBottom
from drill_twin.model.contact import ContactForces
from drill_twin.model.forces import ForceEvaluation, Kinematics, NonlinearForces
from drill_twin.integrator.newmark_kernel import (BETA, GAMMA, VELOCITY_SCALE,  # noqa
                                                  VERIFY_EVERY)
from drill_twin.numerics.records import maker
from drill_twin.numerics.recycled import RecycledArrays
from drill_twin.integrator.step_operands import StepOperands, make_step_operands

ON_BOTTOM_TOLERANCE_M = compiled.ON_BOTTOM_TOLERANCE_M
"""The bit counts as on bottom when it is within this of the hole bottom (m)."""


@dataclass
class BatchState:
    """
    The state of m members at time ``time_s``.

    q, q_rate, q_acceleration: reduced coordinates and derivatives, shape (m, n).
    top_angle_rad, top_speed_rad_per_s, top_acceleration_rad_per_s2: the driven rotation
    (shared by all members); hook_load_n: the hook load in force (N), one for the batch or one
    per member, (m,) (an ensemble whose lines follow the rig's block). hole_u: the hole bottom as
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
    hook_load_n: float | np.ndarray
    hole_u: np.ndarray | None = None

    def copy(self) -> 'BatchState':
        return BatchState(self.time_s, self.q.copy(), self.q_rate.copy(),
                          self.q_acceleration.copy(), self.top_angle_rad,
                          self.top_speed_rad_per_s, self.top_acceleration_rad_per_s2,
                          np.copy(self.hook_load_n) if np.ndim(self.hook_load_n)
                          else self.hook_load_n,
                          None if self.hole_u is None else self.hole_u.copy())

    def take(self, members) -> 'BatchState':
        """Return the state of ``members`` (indices) only, copied."""
        return BatchState(self.time_s, self.q[members].copy(), self.q_rate[members].copy(),
                          self.q_acceleration[members].copy(), self.top_angle_rad,
                          self.top_speed_rad_per_s, self.top_acceleration_rad_per_s2,
                          np.asarray(self.hook_load_n)[members].copy()
                          if np.ndim(self.hook_load_n) else self.hook_load_n,
                          None if self.hole_u is None else self.hole_u[members].copy())


@dataclass(frozen=True)
class StepResult:
    """
    Outcome of one step: success unless a member diverged or did not converge.

    converged, finite: per member (m,); iterations: used; error: final relative velocity
    increment per member; message: why it failed ('' on success); forces: the forces of the
    final state (the bit's exactly, the others at each member's last evaluation).
    retries: (m,) sub-steps each member was integrated on after its full step failed (0 when
    the full step worked; set by the Simulator, None from the integrator alone). on_bottom: (m,)
    the bit on the rock at the step's end (within ON_BOTTOM_TOLERANCE_M of the surface under
    it), as the step's kernel found it; None where a state was merged from other steps (the
    Simulator then tests its state). members_on_bottom, members_lifted: how many of on_bottom
    and of the final evaluation's lift-off flags are set, counted by the kernel (so that the
    time loop's checks need no pass of their own over the flags); None like on_bottom.
    """

    success: bool
    converged: np.ndarray
    finite: np.ndarray
    iterations: int
    error: np.ndarray
    message: str
    forces: ForceEvaluation
    retries: np.ndarray | None = None
    on_bottom: np.ndarray | None = None
    members_on_bottom: int | None = None
    members_lifted: int | None = None


make_step_result = maker(StepResult)
"""StepResult(...) with every field given, at the time loop's rate (:mod:`records`)."""


def merged_result(result: StepResult, **changes) -> StepResult:
    """
    Return ``result`` with ``changes``, for a state merged from other steps.

    What the step's kernel found of its own output (on_bottom and the counts beside it) no
    longer holds: None.
    """
    return replace(result, on_bottom=None, members_on_bottom=None, members_lifted=None,
                   **changes)


_make_evaluation, _make_contact = maker(ForceEvaluation), maker(ContactForces)


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
        # Local-law directions: bit (axial, torsion), v and w of every node, then theta_x at
        # the imbalance's node (zero without one).
        local = np.zeros((n, 3 + 2 * system.n_nodes))
        axial, torsion = system.blocks['axial'], system.blocks['torsional']
        local[axial.columns, 0] = axial.shapes[system.bit_node]
        local[torsion.columns, 1] = torsion.shapes[system.bit_node]
        bending_y, bending_z = system.blocks['bending_y'], system.blocks['bending_z']
        nodes = system.n_nodes
        local[bending_y.columns, 2:2 + nodes] = bending_y.shapes[:nodes].T       # v rows
        local[bending_z.columns, 2 + nodes:2 + 2 * nodes] = bending_z.shapes[:nodes].T  # w
        if forces.imbalance is not None:
            local[torsion.columns, 2 + 2 * nodes] = torsion.shapes[forces.imbalance.node]
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
        # The step kernels' operands (newmark_kernel), made once.
        blocks = [system.blocks[name] for name in ('axial', 'torsional', 'bending_y',
                                                   'bending_z')]
        self._shapes = tuple(np.ascontiguousarray(block.shapes) for block in blocks)
        self._ranges = np.array([[block.rows.start, block.rows.stop, block.columns.start,
                                  block.columns.stop] for block in blocks], dtype=np.int64)
        diagonal = (self._stiffness_diagonal if self._stiffness_diagonal is not None
                    else np.empty(0))
        damping_blocks, groups, inverse_blocks = _diagonal_blocks(
            self.damping, la.inv(effective), self._ranges[:, 2:])
        # g(t + dt) of the driven rotation and the hook (newmark_kernel.external_load).
        self._load_operands = (np.ascontiguousarray(system.mass_driven, dtype=float),
                               np.ascontiguousarray(system.damping_driven, dtype=float),
                               np.ascontiguousarray(self.top_axial_row, dtype=float),
                               float(self.static_hook_load_n))
        self._operators = (
            self._shapes, tuple(np.ascontiguousarray(block.shapes_t) for block in blocks),
            self._ranges, system.bit_node, system.n_nodes,
            np.ascontiguousarray(self.mass), self._mass_is_identity,
            damping_blocks, np.ascontiguousarray(self.stiffness),
            np.ascontiguousarray(diagonal), inverse_blocks, groups,
            np.ascontiguousarray(local), np.ascontiguousarray(self.local_response),
            np.ascontiguousarray(self.local_gram), self.bit_rows, self.bit_response,
            np.ascontiguousarray(self.bit_flexibility), self.bit_axial_row,
            forces.bit_axial_index, forces.bit_torsion_index, self.time_step_s,
            BETA * self.time_step_s ** 2, self.tolerance) + self._load_operands
        self._hook_scalar = np.empty(1)                  # one hook load for the batch (N)
        without_bit = self._forces_without_bit
        self._forces_arguments = (without_bit.switches, without_bit.strain_arguments,
                                  without_bit.coupling_arguments, without_bit.contact_arguments,
                                  without_bit.imbalance_arguments,
                                  without_bit.rotating_arguments)
        self._set_law_constants(germ)
        self._work = None
        self._rate = None                 # per member: the contraction rate of its last
        #                                   2-iteration step
        self._active = None               # (contact flags, lift-off flags) at the last step
        self._before_step = None          # the bookkeeping before the last step
        self._flat_surface = None         # bottom_surface's zeros without a lobed bottom
        self._operands_of = None          # (operators, work, forces' tuples, StepOperands)

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
        bit = _BitSolution(rop + height_rate, omega, force, torque, lifted, jacobian,
                           np.ones(rop.shape, dtype=bool))
        return self._with_bit(evaluation, bit)

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
        """Make the step kernel's operands with the law's constants of ``germ`` and the scales."""
        law = self.forces.law
        germs = np.eye(2)[None] if germ is None else np.ascontiguousarray(germ, dtype=float)
        rows = np.ascontiguousarray(law.rows(self._law_scales))
        self._bit_constants = (float(self.static_bit_force[0]),
                               bool(self.forces.physics.bit_rock), rows,
                               np.ascontiguousarray(fade_speeds(rows)), germs, germ is not None,
                               LobedBottom.arguments_of(self.forces.bottom_pattern))
        self._step_operators = self._operators + self._bit_constants

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
        compiled.external_load(float(top_speed), float(top_acceleration),
                               np.ascontiguousarray(hooks), *self._load_operands, load)
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
        in :meth:`NonlinearForces.accumulate`.
        """
        dt = self.time_step_s
        top_acceleration = (top_speed_rad_per_s - state.top_speed_rad_per_s) / dt
        top_angle = state.top_angle_rad + 0.5 * dt * (state.top_speed_rad_per_s
                                                      + top_speed_rad_per_s)
        if type(hook_load_n) is float or np.ndim(hook_load_n) == 0:
            hooks = self._hook_scalar
            hooks[0] = hook_load_n
        else:
            hooks = np.ascontiguousarray(hook_load_n, dtype=float)
        members = state.q.shape[0]
        work = self._step_work(members)
        has_hole = state.hole_u is not None
        # Restored if the step fails: the rates (updated in place) and the flags (replaced).
        rate, active = self._rate, self._active
        have_rate = rate is not None and rate.shape == (members,)
        if not have_rate:
            self._rate = np.full(members, np.nan)
        (q, q_rate, q_acceleration, hole, finite, converged, on_bottom, error,
         full, modal, radial, rop, omega, force, torque, jacobian) = work.results.take()
        saved_rate, contact, lifted = work.kept_flags.take()
        final = (full, modal, radial, contact, work.final_tangent, rop, omega, force, torque,
                 lifted, jacobian, work.final_solved)
        if have_rate:
            saved_rate[:] = rate
        bookkeeping = (saved_rate if have_rate else None if rate is None else rate.copy(),
                       active)
        clock = round((state.time_s + dt) / dt)         # the step's number on the model clock
        have_active = active is not None and active[1].shape == (members,)
        previous_contact, previous_lifted = (active if have_active
                                             else (work.no_contact, work.no_lift))
        self.forces.strain_operators.set_top_angle(top_angle)   # printed_absolute's
        if self.forces.imbalance is not None:          # the angle its force turns with
            self.forces.imbalance.set_top_angle(top_angle)
        if self.forces.bottom_pattern is not None:     # the angle the lobes turn with
            self.forces.bottom_pattern.set_top_angle(top_angle)
        (iterations, robust, count, touching, on_bottom_count,
         lifted_count) = compiled.step(
            (np.ascontiguousarray(state.q), np.ascontiguousarray(state.q_rate),
             np.ascontiguousarray(state.q_acceleration),
             state.hole_u if has_hole else work.touch, has_hole),
            (float(top_speed_rad_per_s), float(top_acceleration), hooks,
             self.max_iterations),
            (have_rate, have_active, self._rate, clock, previous_contact, previous_lifted),
            self._operands(work), final,
            (q, q_rate, q_acceleration, hole, finite, converged, on_bottom))
        evaluation = _final_evaluation(final, touching)
        self._active = (contact, lifted)               # shared, never written in place
        error[:] = work.error
        bit_ok = work.bit_ok
        success = count == members
        time = state.time_s + dt
        message = ''
        if success:
            pass
        elif not np.all(finite):
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
        counters = self.counters
        counters.steps += 1
        counters.iterations += iterations
        counters.force_evaluations += iterations
        counters.bit_law_evaluations += (iterations + robust) if self.forces.physics.bit_rock \
            else 0
        counters.failed_steps += int(not success)
        new_state = BatchState(time, q, q_rate, q_acceleration, top_angle, top_speed_rad_per_s,
                               top_acceleration, hook_load_n, hole)
        return new_state, make_step_result(success, converged, finite, iterations, error,
                                           message, evaluation, None, on_bottom,
                                           on_bottom_count, lifted_count)

    def _operands(self, work: compiled.StepWork) -> StepOperands:
        """Return the step's operands object, made again when one of its tuples changed."""
        made = self._operands_of
        if (made is None or made[0] is not self._step_operators or made[1] is not work
                or made[2] is not self._forces_arguments):
            parts = (self._forces_arguments, self._step_operators, work.arrays, work.compact)
            made = self._operands_of = (self._step_operators, work, self._forces_arguments,
                                        make_step_operands(*parts))
        return made[3]

    def _step_work(self, members: int) -> compiled.StepWork:
        """Return the work arrays of a step of ``members`` (made again only when m changes)."""
        work = self._work
        if work is None or work.members != members:
            work = compiled.StepWork(self.system.size, members)
            forces = self._forces_without_bit.step_workspace(members)
            work.arrays = (work.d_pred, work.v_pred, work.a, work.d, work.v, work.residual,
                           work.y, work.modal, work.product, work.responses, work.touch,
                           work.hole, work.error, work.previous_error, work.active,
                           work.bit_ok, work.scratch, work.flexibilities, work.on_wall,
                           work.load, work.due,
                           *forces.kinematics, forces.strain, forces.linear,
                           forces.stress, forces.coupling, forces.force_t, forces.radial,
                           forces.in_contact, forces.tangent,
                           forces.bending_z_acceleration_t)
            nodes = self.system.n_nodes
            # The final evaluation's arrays that callers do not keep as they are: the tangents
            # (copied out when a node touches) and the bit solve's flags.
            work.final_tangent = np.empty((members, nodes, 2, 2))
            work.final_solved = np.empty(members, dtype=bool)
            size, n_dofs = self.system.size, self.system.n_dofs
            work.results = RecycledArrays(
                lambda: _new_step_arrays(n_dofs, size, nodes, members))
            work.kept_flags = RecycledArrays(lambda: _new_kept_flags(nodes, members))
            final = (_new_step_arrays(n_dofs, size, nodes, members)[8:]
                     + _new_kept_flags(nodes, members)[1:]
                     + (work.final_tangent, work.final_solved))
            work.make_compact(work.arrays + final)    # (sizes by type: any order)
            work.no_contact = np.zeros((members, nodes), dtype=bool)
            work.no_lift = np.zeros(members, dtype=bool)
            self._work = work
        return work

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

    def _with_bit(self, evaluation: ForceEvaluation, bit: _BitSolution) -> ForceEvaluation:
        """Return the evaluation with the bit's forces of the final state (exact)."""
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


def _diagonal_blocks(damping, inverse, groups):
    """
    ([C_r] blocks (4,), row groups (4, 2), S0^-1 blocks (4,)) as the step kernel takes them.

    The diagonal blocks on the coordinate groups of Phi's blocks when [C_r] and S0^-1 have
    nothing outside them (the fields do not couple linearly), else the whole matrices as one
    group.
    """
    outside = np.ones(damping.shape, dtype=bool)
    for start, stop in groups:
        outside[start:stop, start:stop] = False
    if np.any(damping[outside] != 0) or np.any(inverse[outside] != 0):
        n = damping.shape[0]
        groups = np.array([[0, n]] + [[n, n]] * 3, dtype=np.int64)
    else:
        groups = np.ascontiguousarray(groups, dtype=np.int64)
    empty = np.empty((0, 0))

    def blocks(matrix):
        return tuple(np.ascontiguousarray(matrix[start:stop, start:stop]) if stop > start
                     else empty for start, stop in groups)

    return blocks(damping), groups, blocks(inverse)


def _new_step_arrays(n_dofs: int, n: int, nodes: int, members: int) -> tuple:
    """
    Return new arrays for what a step hands its caller (recycled: :mod:`recycled`).

    q, q', q'' (m, n), hole (m,), finite, converged, on_bottom (m,) flags, error (m,); then
    the final evaluation's full (n_dofs, m), modal (n, m), radial (m, n_nodes) and the bit's
    rop, omega, force, torque (m,), jacobian (m, 2, 2). The evaluation's contact and lift-off
    flags are in :func:`_new_kept_flags`, its tangents and the bit solve's flags are the
    batch's work arrays (``StepWork.final_tangent``, ``final_solved``).
    """
    empty = np.empty
    return (empty((members, n)), empty((members, n)), empty((members, n)), empty(members),
            empty(members, dtype=bool), empty(members, dtype=bool), empty(members, dtype=bool),
            empty(members),
            empty((n_dofs, members)), empty((n, members)), empty((members, nodes)),
            empty(members), empty(members), empty(members), empty(members),
            empty((members, 2, 2)))


def _new_kept_flags(nodes: int, members: int) -> tuple:
    """
    Return new arrays for what the integrator keeps a step longer than its caller.

    The contraction rates before the step (m,) (to undo it), the final evaluation's contact
    (m, n_nodes) and lift-off (m,) flags (the next step compares with them). Recycled apart
    from :func:`_new_step_arrays`' larger set, which then needs two sets, not three: the
    set written is the one of two steps back, still in cache (64 members: 1-5 % of the
    step, measured).
    """
    return np.empty(members), np.empty((members, nodes), dtype=bool), np.empty(members, bool)


def _final_evaluation(final: tuple, touching: bool) -> ForceEvaluation:
    """
    Return a step's final evaluation from its arrays, in the order the step kernel takes them.

    The tangents (the batch's work array) are copied when ``touching`` (a node touches the
    wall), else the evaluation has none; the bit solve's flags are not in it.
    """
    full, modal, radial, contact, tangent, rop, omega, force, torque, lifted, jacobian, _ = final
    return _make_evaluation(
        full=full.T, modal=modal.T, weight_on_bit_n=force, torque_on_bit_nm=torque,
        rop_m_per_s=rop, bit_speed_rad_per_s=omega, lifted=lifted, bit_jacobian=jacobian,
        contact=_make_contact(radial, contact),
        contact_tangent=tangent.copy() if touching else None)
