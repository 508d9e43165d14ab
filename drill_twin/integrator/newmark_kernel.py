"""
The compiled parts of a Newmark step (:mod:`drill_twin.integrator.newmark` holds the method).

A step is ``begin`` (the predictor), then per iteration ``fields`` (the iterate's
displacements, rates and the kinematics the forces read, members last), the forces of the
string (:meth:`NonlinearForces.accumulate`, the one place they are summed), and ``update``
(Phi^T f, the residual, S^-1 by the Woodbury identity for members touching the wall, the
bit's 2x2 equation per member, the new accelerations and every per-member decision), and at
the end ``finish`` (the bit's forces in the final evaluation, the new state, the checks).

Arrays are members last, (rows, m), so that the dense products are BLAS (np.dot) over the
whole batch and the per-member work reads columns. The work arrays belong to a
:class:`StepWork` made once per batch size; what a step returns is written into new arrays
given by the caller.
"""
from __future__ import annotations

import numpy as np

from drill_twin.model.bit_equation import solve_one
from drill_twin.model.bit_rock import (TORQUE_FADE_FORCE_N, cutting_rate, law_point, maximum,
                                       minimum)
from drill_twin.model.bottom_hole_pattern import surface, surface_at
from drill_twin.numerics.compiled import inline, kernel
from drill_twin.model.excitation import imbalance_node_acceleration
from drill_twin.model.forces import string_forces

BETA = 0.25
GAMMA = 0.5
VELOCITY_SCALE = 1e-9
"""Added to the velocity norm in the convergence test (modal units, sqrt(kg) m/s)."""
VERIFY_EVERY = 25
"""Every member runs at least two iterations once in this many steps of the model's clock, to
measure its contraction rate: member i on the steps n with (n + VERIFY_SPACING (g mod
VERIFY_SLOTS)) a multiple of VERIFY_EVERY, g = i // VERIFY_GROUP its group."""
VERIFY_GROUP = 8
"""Members that verify on the same step (a batch of 64 verifies in 8 groups, not all at once:
the later iterations run on the members still iterating only, so a step's extra cost is a
group's, not the batch's)."""
VERIFY_SPACING = 3
"""Steps between the verifications of consecutive groups (8 groups fit in VERIFY_EVERY)."""
VERIFY_SLOTS = 8
"""Steps of a VERIFY_EVERY cycle on which groups verify, group g on slot g mod VERIFY_SLOTS:
a batch of more than 8 groups verifies more members on those steps, not on more steps (256
members had a second iteration on every step; now on 8 of 25, 32 members each: 5.68 -> 5.47
ms a step, medians of one process each; a member's schedule still depends on its index only)."""
ON_BOTTOM_TOLERANCE_M = 1e-6
"""The bit counts as on bottom when it is within this of the hole bottom (m)."""


class StepWork:
    """
    Work arrays of a step for m members (n reduced coordinates), allocated once.

    d_pred, v_pred, a, d, v, residual, y: (n, m); modal: (n, m) (Phi^T f of the iterate);
    load: (n, m) the modal load of the driven rotation and the hook (g of the step); due (m,):
    the members whose first iterate is verified this step (VERIFY_EVERY);
    touch, hole: (m,); per-member state of the iteration: error, previous_error (m,),
    active, bit_ok (m,) bools; the bit of the iteration (rop, omega, force, torque, lifted,
    jacobian (m, 2, 2), solved) and the product buffer (n, m); responses (m, n, 2): S^-1 B of
    the members on the wall (on_wall (m,)), flexibilities (m, 2, 2): B^T S^-1 B; scratch
    (6, m).
    """

    def __init__(self, n: int, members: int):
        self.members = members
        shape = (n, members)
        self.d_pred, self.v_pred, self.a = np.empty(shape), np.empty(shape), np.empty(shape)
        self.d, self.v = np.empty(shape), np.empty(shape)
        self.residual, self.y = np.empty(shape), np.empty(shape)
        self.modal, self.product = np.empty(shape), np.empty(shape)
        self.load = np.empty(shape)
        self.due = np.empty(members, dtype=np.bool_)
        self.touch, self.hole = np.empty(members), np.empty(members)
        self.error, self.previous_error = np.empty(members), np.empty(members)
        self.active = np.empty(members, dtype=np.bool_)
        self.bit_ok = np.empty(members, dtype=np.bool_)
        self.responses = np.empty((members, n, 2))
        self.scratch = np.empty((6, members))
        self.flexibilities = np.empty((members, 2, 2))
        self.on_wall = np.empty(members, dtype=np.bool_)
        self.compact = None

    def make_compact(self, arrays) -> None:
        """
        Make the buffers of the compacted iterations (step's ``compact``) for ``arrays``.

        ``arrays``: the step's work and final arrays; the buffers hold every float and every
        flag array of the batch once, plus the law's operands per member and the
        members' indices.
        """
        members = self.members
        floats = sum(x.size for x in arrays if x.dtype == np.float64) + 16 * members
        flags = sum(x.size for x in arrays if x.dtype == np.bool_)
        self.compact = (np.empty(floats), np.empty(flags, dtype=np.bool_),
                        np.empty(members, dtype=np.int64))


@kernel
def external_load(top_speed, top_acceleration, hooks, mass_driven, damping_driven,
                  top_axial_row, static_hook, load):
    """
    Set load (n, m) = g(t + dt): the driven rotation's and the hook's modal load.

    -Phi^T (M psi theta_top'' + C psi theta_top') - Phi^T e_top (H - H_S), hooks (1 or m,)
    the hook loads H (N), one for the batch or one per member.
    """
    n, members = load.shape
    last = hooks.shape[0] - 1
    for j in range(n):
        driven = -mass_driven[j] * top_acceleration - damping_driven[j] * top_speed
        row = top_axial_row[j]
        for i in range(members):
            load[j, i] = driven - (hooks[min(i, last)] - static_hook) * row


@kernel
def begin(q, q_rate, q_acceleration, hole_in, has_hole, dt, bit_axial_row, rigid, d_pred,
          v_pred, a, touch, hole, error, active, bit_ok):
    """
    Compute the predictor (state arrays members first (m, n), work arrays members last).

    d*, v*, a = the last acceleration, the hole and ``touch``, the end-of-step ROP that puts the
    bit on the hole bottom (Newmark: d = d* + (beta/gamma) dt (v - v*); on a rigid rock 0 on
    bottom, on a compliant one negative where the bit presses the rock).
    """
    members, n = q.shape
    cd = (0.5 - BETA) * dt * dt
    cv = (1.0 - GAMMA) * dt
    for i in range(members):
        reach = 0.0
        rate = 0.0
        bit_u = 0.0
        for j in range(n):
            dp = q[i, j] + dt * q_rate[i, j] + cd * q_acceleration[i, j]
            vp = q_rate[i, j] + cv * q_acceleration[i, j]
            d_pred[j, i] = dp
            v_pred[j, i] = vp
            a[j, i] = q_acceleration[i, j]
            reach += dp * bit_axial_row[j]
            rate += vp * bit_axial_row[j]
            bit_u += q[i, j] * bit_axial_row[j]
        hole[i] = hole_in[i] if has_hole else bit_u
        touch[i] = rate + GAMMA / (BETA * dt) * (hole[i] - reach)
        if rigid:
            touch[i] = maximum(touch[i], 0.0)
        error[i] = np.inf
        active[i] = True
        bit_ok[i] = True


@kernel
def fields(a, d_pred, v_pred, cd, cv, top_speed, top_acceleration, shapes_axial,
           shapes_torsion, shapes_y, shapes_z, ranges, d, v, displacement_t, theta_x_rate_t,
           theta_x_acceleration_t, bending_y_rate_t, bending_y_acceleration_t,
           bending_z_rate_t):
    """
    Set d = d* + beta dt^2 a, v = v* + gamma dt a (n, m), and the kinematics of the forces.

    The kinematics are forces.Kinematics, members last. ranges (4, 4): rows and columns
    (start, stop, start, stop) of the axial, torsional, bending-y and bending-z blocks of Phi.
    """
    n, members = a.shape
    for j in range(n):
        for i in range(members):
            d[j, i] = d_pred[j, i] + cd * a[j, i]
            v[j, i] = v_pred[j, i] + cv * a[j, i]
    blocks = (shapes_axial, shapes_torsion, shapes_y, shapes_z)
    for b in range(4):
        np.dot(blocks[b], d[ranges[b, 2]:ranges[b, 3]],
               displacement_t[ranges[b, 0]:ranges[b, 1]])
    t0, t1 = ranges[1, 2], ranges[1, 3]
    np.dot(shapes_torsion, v[t0:t1], theta_x_rate_t)
    np.dot(shapes_torsion, a[t0:t1], theta_x_acceleration_t)
    theta_x_rate_t += top_speed
    theta_x_acceleration_t += top_acceleration
    np.dot(shapes_y, v[ranges[2, 2]:ranges[2, 3]], bending_y_rate_t)
    np.dot(shapes_y, a[ranges[2, 2]:ranges[2, 3]], bending_y_acceleration_t)
    np.dot(shapes_z, v[ranges[3, 2]:ranges[3, 3]], bending_z_rate_t)


@kernel
def update(iteration, force_t, radial, in_contact, tangent, touching, theta_x_rate_t,
           bit_node, n_nodes, shapes_t_axial, shapes_t_torsion, shapes_t_y, shapes_t_z, ranges,
           mass, mass_is_identity, damping, stiffness, stiffness_diagonal, effective_inverse,
           groups, local_directions, local_response, local_gram, bit_rows, bit_response,
           bit_flexibility, dt, dt2, tolerance, load, static_force, bit_rock, law, fade_speed,
           germ, random, have_rate, have_active, rate, due, previous_contact,
           previous_lifted, work_d, work_v, a, modal, residual, y, product, responses, touch,
           error, previous_error, active, bit_ok, scratch, flexibilities, on_wall, final_full,
           final_modal, final_radial, final_contact, final_tangent, bit_rop, bit_omega,
           bit_force, bit_torque, bit_lifted, bit_jacobian, bit_solved, imbalance,
           displacement_t, pattern):
    """
    One iteration after the forces of the iterate (force_t, members last, without the bit).

    The Newmark update of the module docstring of :mod:`newmark`, per member.

    Updates a, error, active, bit_ok, the bit of the active members and the contraction
    rates (rate) in place, and keeps the evaluation of the frozen members (at their final
    state) in final_*. Loops over the n coordinates run with the members innermost (the
    arrays' layout); the per-member work (the bit, the decisions) runs member by member.
    scratch (6, m), flexibilities (m, 2, 2), responses (m, n, 2) (S^-1 B of members on the
    wall), on_wall (m,): work arrays. pattern: the lobed hole bottom's operands
    (bottom_hole_pattern.LobedBottom.arguments): the bit equation is solved relative to the
    surface under the bit, taken at the iterate's angle and moving at kappa omega with the
    solved speed omega. Returns (members still active, 1 if any member needed the bracketed
    bit solve).
    """
    n, members = a.shape
    shapes_t = (shapes_t_axial, shapes_t_torsion, shapes_t_y, shapes_t_z)
    for b in range(4):                                        # Phi^T f, block by block
        np.dot(shapes_t[b], force_t[ranges[b, 0]:ranges[b, 1]],
               modal[ranges[b, 2]:ranges[b, 3]])
    # Frozen members were evaluated at their final state: keep that evaluation.
    if iteration == 1:
        final_full[:, :] = force_t
        final_modal[:, :] = modal
        final_radial[:, :] = radial
        final_contact[:, :] = in_contact
        if touching:
            final_tangent[:, :, :, :] = tangent
        else:
            final_tangent[:, :, :, :] = 0.0
    else:
        for i in range(members):
            if not active[i]:
                _keep_member(i, force_t, modal, radial, in_contact, tangent, touching,
                             final_full, final_modal, final_radial, final_contact,
                             final_tangent)
    # R = M a + C v + K d - Phi^T f - g, then y = S0^-1 R.
    if mass_is_identity:
        residual[:, :] = a
    else:
        np.dot(mass, a, residual)
    _block_product(damping, groups, work_v, product)
    residual += product
    if stiffness_diagonal.shape[0] > 0:
        for j in range(n):
            k = stiffness_diagonal[j]
            for i in range(members):
                residual[j, i] += work_d[j, i] * k
    else:
        np.dot(stiffness, work_d, product)
        residual += product
    for j in range(n):
        for i in range(members):
            residual[j, i] = residual[j, i] - modal[j, i] - load[j, i]
    _block_product(effective_inverse, groups, residual, y)
    # S^-1 with the contact tangents (Woodbury), members on the wall only.
    for i in range(members):
        on_wall[i] = touching > 0 and _touches(in_contact, i, n_nodes) or imbalance[0]
        if on_wall[i]:
            responses[i, :, :] = bit_response
            flexibilities[i, :, :] = _woodbury(i, in_contact, tangent, n_nodes, dt2,
                                               local_directions, local_response, local_gram,
                                               bit_rows, y, responses[i], imbalance,
                                               displacement_t)
        else:
            flexibilities[i, :, :] = bit_flexibility
    # The iterate's bit velocities (start), B^T y, |v|.
    rop, by0, by1 = scratch[0], scratch[1], scratch[2]
    speed, p0, p1 = scratch[3], scratch[4], scratch[5]
    rop[:] = 0.0
    by0[:] = 0.0
    by1[:] = 0.0
    speed[:] = 0.0
    for j in range(ranges[0, 2], ranges[0, 3]):
        row = bit_rows[0, j]
        for i in range(members):
            rop[i] += row * work_v[j, i]
    for j in range(n):
        row0, row1 = bit_rows[0, j], bit_rows[1, j]
        for i in range(members):
            by0[i] += y[j, i] * row0
            by1[i] += y[j, i] * row1
            speed[i] += work_v[j, i] * work_v[j, i]
    gdt = GAMMA * dt
    slope = law[0, 7] * GAMMA / (BETA * dt)            # a compliant rock's resting branch
    robust_used = 0
    for i in range(members):
        omega = theta_x_rate_t[bit_node, i]
        linear0, linear1 = rop[i] - gdt * by0[i], omega - gdt * by1[i]
        g = min(i, germ.shape[0] - 1)
        k = min(i, law.shape[0] - 1)
        if bit_rock:
            # The lobes: the surface lies s below the mean bottom and moves at kappa omega.
            height, kappa = surface_at(pattern, displacement_t, i)
            x0, x1, f0, f1, lifted, j00, j01, j10, j11, solved, robust = _solve_bit(
                linear0, linear1, flexibilities[i], rop[i], omega,
                touch[i] + GAMMA / (BETA * dt) * height, slope, gdt, static_force,
                germ[g, 0, 0], germ[g, 0, 1], germ[g, 1, 1], random, law[k], fade_speed[k],
                kappa)
            robust_used |= robust
        else:
            x0, x1, f0, f1 = linear0, linear1, static_force, 0.0
            lifted, solved = False, True
            j00 = j01 = j10 = j11 = 0.0
        p0[i], p1[i] = f0 - static_force, f1 - 0.0
        if active[i]:
            bit_rop[i], bit_omega[i], bit_force[i], bit_torque[i] = x0, x1, f0, f1
            bit_lifted[i], bit_solved[i] = lifted, solved
            bit_jacobian[i, 0, 0], bit_jacobian[i, 0, 1] = j00, j01
            bit_jacobian[i, 1, 0], bit_jacobian[i, 1, 1] = j10, j11
    # a = a - y + S^-1 B (F - F_c) for the active members, and |increment|^2.
    norm = by0                                           # (B^T y is used up)
    norm[:] = 0.0
    for j in range(n):
        r0, r1 = bit_response[j, 0], bit_response[j, 1]
        for i in range(members):
            if active[i]:
                if on_wall[i]:
                    updated = a[j, i] - y[j, i] + (p0[i] * responses[i, j, 0]
                                                   + p1[i] * responses[i, j, 1])
                else:
                    updated = a[j, i] - y[j, i] + (p0[i] * r0 + p1[i] * r1)
                increment = a[j, i] - updated
                norm[i] += increment * increment
                a[j, i] = updated
    still = 0
    for i in range(members):
        was_active = active[i]
        bit_ok[i] = bit_ok[i] and (not was_active or bit_solved[i])
        new_error = gdt * np.sqrt(norm[i]) / (np.sqrt(speed[i]) + VELOCITY_SCALE)
        previous_error[i] = error[i]
        if was_active:
            error[i] = new_error
        now = was_active and np.isfinite(error[i]) and bit_ok[i]
        done = now and error[i] <= tolerance and not (iteration == 1 and due[i])
        if iteration == 1 and now and have_rate:
            accept = np.isfinite(rate[i]) and not due[i]
            if accept and have_active:
                accept = previous_lifted[i] == bit_lifted[i]
                for node in range(n_nodes):
                    accept = accept and previous_contact[i, node] == in_contact[i, node]
            if accept and rate[i] / (1.0 - rate[i]) * error[i] <= tolerance:
                error[i] = rate[i] / (1.0 - rate[i]) * error[i]
                done = True
        elif iteration == 2 and now and previous_error[i] > 0:
            measured = error[i] / previous_error[i]
            if measured < 1.0:
                rate[i] = measured
            elif due[i]:
                rate[i] = np.nan                 # not contracting: verify until it does
        active[i] = now and not done
        still += active[i]
    return still, robust_used


@inline
def _block_product(blocks, groups, x, out):
    """
    Set out = A x for a block-diagonal A given by its diagonal blocks.

    The diagonal blocks (4,) sit on the row groups (4, 2) (start, stop) (an empty group is
    skipped).
    """
    for b in range(4):
        start, stop = groups[b, 0], groups[b, 1]
        if stop > start:
            np.dot(blocks[b], x[start:stop], out[start:stop])


@inline
def _keep_member(i, force_t, modal, radial, in_contact, tangent, touching, final_full,
                 final_modal, final_radial, final_contact, final_tangent):
    """Copy member i's evaluation into the final one."""
    for j in range(force_t.shape[0]):
        final_full[j, i] = force_t[j, i]
    for j in range(modal.shape[0]):
        final_modal[j, i] = modal[j, i]
    for node in range(radial.shape[1]):
        final_radial[i, node] = radial[i, node]
        final_contact[i, node] = in_contact[i, node]
        for r in range(2):
            for c in range(2):
                final_tangent[i, node, r, c] = tangent[i, node, r, c] if touching else 0.0


@inline
def _touches(in_contact, i, n_nodes):
    for node in range(n_nodes):
        if in_contact[i, node]:
            return True
    return False


@kernel
def _woodbury(i, in_contact, tangent, n_nodes, dt2, local_directions, local_response,
              local_gram, bit_rows, y, response, imbalance, displacement_t):
    """
    S^-1 with the contact tangents of member i's touching nodes and the imbalance (Woodbury).

    The wall's tangent k_ip [...] at each touching node enters as beta dt^2 times it on the
    node's (v, w); the imbalance, whose force -A (v'', w'', theta_x'') at its node is linear in
    the accelerations, as A = [[0, 0, -m e s], [0, 0, m e c], [-m e s, m e c, m e^2]] (s, c of
    the node's spin angle) on its (v, w, theta_x): the Newton step then takes its inertia
    whole instead of as a fixed point (which needed three iterations a step). Corrects y[:, i]
    and response (S^-1 B, (n, 2)) in place; returns B^T S^-1 B (2, 2).
    """
    count = 0
    for node in range(n_nodes):
        if in_contact[i, node]:
            count += 1
    extra = 3 if imbalance[0] else 0
    rank = 2 * count + extra
    index = np.empty(rank, dtype=np.int64)
    d = np.zeros((rank, rank))
    k = 0
    for node in range(n_nodes):
        if in_contact[i, node]:
            index[2 * k], index[2 * k + 1] = 2 + node, 2 + n_nodes + node
            for r in range(2):
                for c in range(2):
                    d[2 * k + r, 2 * k + c] = dt2 * tangent[i, node, r, c]
            k += 1
    if extra:
        indices, constants, top_angle = imbalance[1], imbalance[2], imbalance[3]
        node = indices[0]
        angle = top_angle[0] + displacement_t[indices[1], i]
        me, inertia = constants[0], constants[1]
        s, c = np.sin(angle), np.cos(angle)
        first = 2 * count
        index[first], index[first + 1], index[first + 2] = (2 + node, 2 + n_nodes + node,
                                                            2 + 2 * n_nodes)
        d[first, first + 2] = d[first + 2, first] = -me * s
        d[first + 1, first + 2] = d[first + 2, first + 1] = me * c
        d[first + 2, first + 2] = inertia
    gram = np.empty((rank, rank))
    for r in range(rank):
        for c in range(rank):
            gram[r, c] = local_gram[index[r], index[c]]
    system = np.eye(rank) + d @ gram
    if not np.all(np.isfinite(system)):
        # A diverged member (an infinite displacement has no direction on the wall): its
        # iterate becomes nan, the step's finiteness check fails it, and the caller retries
        # or restarts it; the other members go on.
        y[:, i] = np.nan
        response[:, :] = np.nan
        return np.full((2, 2), np.nan)
    correction = np.linalg.solve(system, d)                  # (I + D G)^-1 D
    n = y.shape[0]
    directions = np.empty((n, rank))
    responses = np.empty((n, rank))
    for j in range(n):
        for r in range(rank):
            directions[j, r] = local_directions[j, index[r]]
            responses[j, r] = local_response[j, index[r]]
    projected = directions.T @ np.ascontiguousarray(y[:, i])
    change = responses @ (correction @ projected)
    for j in range(n):
        y[j, i] -= change[j]
    bit_gram = np.empty((rank, 2))
    for r in range(rank):
        bit_gram[r, 0] = local_gram[index[r], 0]
        bit_gram[r, 1] = local_gram[index[r], 1]
    response -= responses @ (correction @ bit_gram)
    flexibility = np.empty((2, 2))
    for r in range(2):
        for c in range(2):
            total = 0.0
            for j in range(n):
                total += bit_rows[r, j] * response[j, c]
            flexibility[r, c] = total
    return flexibility


@inline
def _solve_bit(linear0, linear1, h, start0, start1, touch, slope, gdt, static_force, g11, g12,
               g22, random, law, fade_speed, kappa):
    """
    Solve x = linear + gamma dt H (F(x) - F_c) for one member (NewmarkIntegrator._solve_bit).

    One Newton step from the iterate's velocities kept where it stays on the law's cutting
    branch (ROP > 0: Eq. 25-26 read at a negative ROP, a bit rising while it presses a
    compliant rock, give a torque that drives the bit, +2.2 MN m at a member's rebound in
    the envelope sweep), else the bracketed solve of :mod:`bit_equation`. On a lobed bottom
    whose surface moves at kappa omega the law holds for the ROP relative to it,
    x0 - kappa x1 (its Jacobian taken with it); ``touch`` is the absolute end-of-step ROP
    that puts the bit on the surface. Returns (x0, x1, F0, F1, lifted, J00, J01, J10, J11,
    solved, robust).
    """
    f, t, j00, j01, j10, j11 = law_point(start0 - kappa * start1, start1, g11, g12, g22,
                                         random, law)
    j01 -= kappa * j00                   # d/d omega of F(x0 - kappa x1, x1)
    j11 -= kappa * j10
    lifted = f >= 0.0
    if lifted:
        f = t = j00 = j01 = j10 = j11 = 0.0
    a0, a1 = f - static_force, t - 0.0
    g0 = start0 - linear0 - gdt * (h[0, 0] * a0 + h[0, 1] * a1)
    g1 = start1 - linear1 - gdt * (h[1, 0] * a0 + h[1, 1] * a1)
    # (I - gdt H J) step = g.
    m00 = 1.0 - gdt * (h[0, 0] * j00 + h[0, 1] * j10)
    m01 = 0.0 - gdt * (h[0, 0] * j01 + h[0, 1] * j11)
    m10 = 0.0 - gdt * (h[1, 0] * j00 + h[1, 1] * j10)
    m11 = 1.0 - gdt * (h[1, 0] * j01 + h[1, 1] * j11)
    determinant = m00 * m11 - m01 * m10
    s0 = (m11 * g0 - m01 * g1) / determinant
    s1 = (m00 * g1 - m10 * g0) / determinant
    x0, x1 = start0 - s0, start1 - s1
    c0 = f - (j00 * s0 + j01 * s1)
    c1 = t - (j10 * s0 + j11 * s1)
    relative, start_relative = x0 - kappa * x1, start0 - kappa * start1
    safe = (np.sign(relative) == np.sign(start_relative) and np.sign(x1) == np.sign(start1)
            and abs(start_relative - relative) <= 0.5 * abs(start_relative) and not lifted
            and c0 < 0 and x0 > touch and relative > 0 and x1 > 0)
    if safe and slope > 0.0:              # on the cutting branch, beyond the rock's spring
        safe = x0 > touch - slope * c0
    if safe and x1 >= fade_speed:                           # where the torque may fade
        mean_force = law_point(relative, x1, 1.0, 0.0, 1.0, False, law)[0]
        threshold = (law[2] * np.sqrt(x1 * x1 + law[5] * law[5]) - law[0]) / law[1]
        safe = mean_force < minimum(threshold, -TORQUE_FADE_FORCE_N)
    if safe:
        return x0, x1, c0, c1, False, j00, j01, j10, j11, True, 0
    c_0, c_1 = gdt * h[0, 0], gdt * h[1, 1]
    b0, b1 = linear0 - c_0 * static_force, linear1 - c_1 * 0.0
    if not b0 - kappa * b1 > maximum(touch - kappa * b1, cutting_rate(0.0, b1, law)):
        # A bit that cannot reach the rock (or outruns the law's cut at zero force) at the
        # speed it has without a rock torque is free: F = 0, omega = b2, no search.
        rop, omega, f1, f2 = b0, b1, 0.0, 0.0
    else:
        rop, omega, f1, f2, _, _ = solve_one(b0, b1, c_0, c_1, touch, slope, g11, g12, g22,
                                             random, start1, law, kappa)
        rop += kappa * omega                                     # absolute again
    free = f1 >= 0.0
    if free:                      # the Jacobian of a guarded member is the law's at the iterate
        j00 = j01 = j10 = j11 = 0.0
    solved = np.isfinite(rop) and np.isfinite(omega)
    return rop, omega, f1, f2, free, j00, j01, j10, j11, solved, 1


@inline
def on_rock(bit_u, hole, height):
    """
    Whether a bit at axial displacement bit_u is on the rock (m, m, m).

    At most ON_BOTTOM_TOLERANCE_M above the surface, which lies ``height`` below the hole's
    mean bottom ``hole`` (Simulator._on_surface, in numpy, is the same test).
    """
    return bit_u >= (hole + height) - ON_BOTTOM_TOLERANCE_M


@kernel
def finish(d_pred, v_pred, a, cd, cv, bit_axial_row, hole, bit_force, bit_torque, compliance,
           static_force, bit_rows, axial_index, torsion_index, final_full, final_modal,
           error, bit_ok, tolerance, q, q_rate, q_acceleration, hole_out, finite, converged,
           on_bottom, pattern):
    """
    Finish a step.

    The bit's exact forces into the final evaluation (final_full (n_dofs, m), final_modal (n,
    m)), the new state members first (q, q_rate, q_acceleration (m, n), hole_out (m,): the hole
    only deepens, to where the bit ends less the depth -F1 / k by which it presses a compliant
    rock, ``compliance`` = 1 / k, 0 for a rigid one, and less the lobes' height s of a
    ``pattern``'s surface under it: the hole is the mean bottom), finite and converged (m,),
    on_bottom (m,): the bit within ON_BOTTOM_TOLERANCE_M of the rock's surface under it (the
    Simulator's on-bottom test). Returns the number of members converged.
    """
    n, members = a.shape
    count = 0
    for i in range(members):
        change0 = bit_force[i] - static_force
        change1 = bit_torque[i] - 0.0
        final_full[axial_index, i] += change0
        final_full[torsion_index, i] += change1
        bit_u = 0.0
        ok = True
        for j in range(n):
            final_modal[j, i] += change0 * bit_rows[0, j] + change1 * bit_rows[1, j]
            d = d_pred[j, i] + cd * a[j, i]
            v = v_pred[j, i] + cv * a[j, i]
            q[i, j], q_rate[i, j], q_acceleration[i, j] = d, v, a[j, i]
            bit_u += d * bit_axial_row[j]
            ok = ok and np.isfinite(d) and np.isfinite(v)
        height = 0.0
        if pattern[0]:
            twist = 0.0
            for j in range(n):
                twist += q[i, j] * bit_rows[1, j]
            height = surface(pattern, pattern[2][0] + twist)[0]
        hole_out[i] = maximum(hole[i], bit_u + compliance * minimum(bit_force[i], 0.0) - height)
        on_bottom[i] = on_rock(bit_u, hole_out[i], height)
        finite[i] = ok
        converged[i] = ok and bit_ok[i] and error[i] <= tolerance
        count += converged[i]
    return count


@kernel
def step(state, step_inputs, bookkeeping, operands, final, out):
    """
    One Newmark step of m members.

    Begin, then (fields, forces of the string, update) until every member is done or
    max_iterations, then finish. Arguments are tuples, but for ``operands``
    (:class:`step_operands.StepOperands`, whose fields forces, operators, work and compact are
    the tuples below, unboxed as one pointer):

    state: (q, q_rate, q_acceleration (m, n) members first, hole (m,), has_hole);
    step_inputs: (top_speed, top_acceleration, hook loads (1 or m,) (N), max_iterations);
    bookkeeping: (have_rate, have_active, rate, the step's number on the model's clock (its
    end over dt: which members verify, VERIFY_EVERY), previous_contact, previous_lifted);
    forces: the arguments of forces.string_forces before the kinematics (the last two: the
    imbalance's, excitation.ImbalanceForce.arguments, and the rotating damping's,
    rotating_damping.RotatingDampingOperators.arguments);
    operators: (shapes (4,), shapes_t (4,), ranges, bit_node, n_nodes, mass, mass is I,
    damping blocks (4,), stiffness, stiffness diagonal, S0^-1 blocks (4,), their row groups
    (4, 2), local directions, S0^-1 U, U^T S0^-1 U, B^T, S0^-1 B, B^T S0^-1 B, bit axial row,
    bit axial and torsion DOF, dt, beta dt^2 (the contact's), tolerance, Phi^T (M + M_f) psi,
    Phi^T (C + C_f) psi and the top's axial row of Phi (n,) each, the prestressed hook load
    (N), static force on bit, bit_rock, the law's constants (m or 1, 8; BitRockLaw.rows: e, r
    and 1/k the same in every row), their fade speeds (m or 1,), germs, random);
    work: StepWork arrays and the forces' Workspace arrays (the last: the (w, theta_y)
    accelerations, of which only the imbalance's node row is computed, when it is on);
    final: _FinalEvaluation.arrays;
    out: (q, q_rate, q_acceleration, hole, finite, converged, on_bottom) of the new state;
    compact: (floats, flags, index) the work buffers of the iterations after the first
    (:class:`StepWork`), which run on the members still iterating only, gathered into arrays
    of their own (a member frozen after the first iteration costs nothing more: with wall
    contact, one member's Newton iterations used to cost the whole batch's).

    Returns (iterations, iterations in which a member needed the bracketed bit solve,
    members converged, whether any node of the final evaluation touches the wall, members
    on bottom, members whose bit the final evaluation has lifted off): the counts are what
    the time loop's Python checks of every step, so that it needs no pass over the flags.
    """
    forces, operators = operands.forces, operands.operators
    work, compact = operands.work, operands.compact
    q, q_rate, q_acceleration, hole_in, has_hole = state
    top_speed, top_acceleration, hooks, max_iterations = step_inputs
    have_rate, have_active, rate, clock, previous_contact, previous_lifted = bookkeeping
    (switches, strain_arguments, coupling_arguments, contact_arguments, imbalance,
     rotating) = forces
    (shapes, shapes_t, ranges, bit_node, n_nodes, mass, mass_is_identity, damping, stiffness,
     stiffness_diagonal, effective_inverse, groups, local_directions, local_response, local_gram,
     bit_rows, bit_response, bit_flexibility, bit_axial_row, axial_index, torsion_index, dt,
     dt2, tolerance, mass_driven, damping_driven, top_axial_row, static_hook, static_force,
     bit_rock, law, fade_speed, germ, random, pattern) = operators
    (d_pred, v_pred, a, d, v, residual, y, modal, product, responses, touch, hole, error,
     previous_error, active, bit_ok, scratch, flexibilities, on_wall, load, due,
     displacement_t, theta_x_rate_t, theta_x_acceleration_t, bending_y_rate_t,
     bending_y_acceleration_t, bending_z_rate_t, strain, linear, stress, coupling, force_t,
     radial, in_contact, tangent, bending_z_acceleration_t) = work
    (final_full, final_modal, final_radial, final_contact, final_tangent, bit_rop, bit_omega,
     bit_force, bit_torque, bit_lifted, bit_jacobian, bit_solved) = final
    q_out, q_rate_out, q_acceleration_out, hole_out, finite, converged, on_bottom = out
    external_load(top_speed, top_acceleration, hooks, mass_driven, damping_driven,
                  top_axial_row, static_hook, load)
    for i in range(due.shape[0]):
        due[i] = (clock + VERIFY_SPACING * (i // VERIFY_GROUP % VERIFY_SLOTS)) % VERIFY_EVERY == 0
    begin(q, q_rate, q_acceleration, hole_in, has_hole, dt, bit_axial_row, law[0, 7] == 0.0,
          d_pred, v_pred, a, touch, hole, error, active, bit_ok)
    cd, cv = BETA * dt * dt, GAMMA * dt
    iterations, robust = 0, 0
    # The whole batch's arrays: a member frozen after the first iteration is left there, and
    # the later iterations run on the members still iterating, gathered (compacted, below).
    full = (a, error, previous_error, active, bit_ok, rate, final_full, final_modal,
            final_radial, final_contact, final_tangent, bit_rop, bit_omega, bit_force,
            bit_torque, bit_lifted, bit_jacobian, bit_solved)
    floats, flags, index = compact
    members = a.shape[1]
    predictor = (d_pred, v_pred)
    compacted = 0
    still = members
    for iteration in range(1, max_iterations + 1):
        if iteration > 1 and still < members and compacted == 0:
            compacted = still
            k = 0
            for i in range(members):
                if active[i]:
                    index[k] = i
                    k += 1
            at, flag_at = 0, 0
            a, at = _narrow(floats, at, a, index, compacted, True)
            d_pred, at = _narrow(floats, at, d_pred, index, compacted, True)
            v_pred, at = _narrow(floats, at, v_pred, index, compacted, True)
            load, at = _narrow(floats, at, load, index, compacted, True)
            d, at = _narrow(floats, at, d, index, compacted, False)
            v, at = _narrow(floats, at, v, index, compacted, False)
            residual, at = _narrow(floats, at, residual, index, compacted, False)
            y, at = _narrow(floats, at, y, index, compacted, False)
            modal, at = _narrow(floats, at, modal, index, compacted, False)
            product, at = _narrow(floats, at, product, index, compacted, False)
            scratch, at = _narrow(floats, at, scratch, index, compacted, False)
            displacement_t, at = _narrow(floats, at, displacement_t, index, compacted, False)
            theta_x_rate_t, at = _narrow(floats, at, theta_x_rate_t, index, compacted, False)
            theta_x_acceleration_t, at = _narrow(floats, at, theta_x_acceleration_t, index,
                                                 compacted, False)
            bending_y_rate_t, at = _narrow(floats, at, bending_y_rate_t, index, compacted,
                                           False)
            bending_y_acceleration_t, at = _narrow(floats, at, bending_y_acceleration_t, index,
                                                   compacted, False)
            bending_z_rate_t, at = _narrow(floats, at, bending_z_rate_t, index, compacted,
                                           False)
            bending_z_acceleration_t, at = _narrow(floats, at, bending_z_acceleration_t, index,
                                                   compacted, False)
            strain, at = _narrow(floats, at, strain, index, compacted, False)
            linear, at = _narrow(floats, at, linear, index, compacted, False)
            stress, at = _narrow(floats, at, stress, index, compacted, False)
            coupling, at = _narrow(floats, at, coupling, index, compacted, False)
            force_t, at = _narrow(floats, at, force_t, index, compacted, False)
            final_full, at = _narrow(floats, at, final_full, index, compacted, True)
            final_modal, at = _narrow(floats, at, final_modal, index, compacted, True)
            touch, at = _take(floats, at, touch, index, compacted, True)
            error, at = _take(floats, at, error, index, compacted, True)
            previous_error, at = _take(floats, at, previous_error, index, compacted, True)
            rate, at = _take(floats, at, rate, index, compacted, True)
            bit_rop, at = _take(floats, at, bit_rop, index, compacted, True)
            bit_omega, at = _take(floats, at, bit_omega, index, compacted, True)
            bit_force, at = _take(floats, at, bit_force, index, compacted, True)
            bit_torque, at = _take(floats, at, bit_torque, index, compacted, True)
            fade_speed, at = _take(floats, at, fade_speed, index, compacted,
                                   fade_speed.shape[0] > 1)
            radial, at = _take(floats, at, radial, index, compacted, False)
            final_radial, at = _take(floats, at, final_radial, index, compacted, True)
            law, at = _take(floats, at, law, index, compacted, law.shape[0] > 1)
            flexibilities, at = _take(floats, at, flexibilities, index, compacted, False)
            responses, at = _take(floats, at, responses, index, compacted, False)
            bit_jacobian, at = _take(floats, at, bit_jacobian, index, compacted, True)
            germ, at = _take(floats, at, germ, index, compacted, germ.shape[0] > 1)
            tangent, at = _take(floats, at, tangent, index, compacted, False)
            final_tangent, at = _take(floats, at, final_tangent, index, compacted, True)
            active, flag_at = _take(flags, flag_at, active, index, compacted, True)
            bit_ok, flag_at = _take(flags, flag_at, bit_ok, index, compacted, True)
            on_wall, flag_at = _take(flags, flag_at, on_wall, index, compacted, False)
            bit_lifted, flag_at = _take(flags, flag_at, bit_lifted, index, compacted, True)
            bit_solved, flag_at = _take(flags, flag_at, bit_solved, index, compacted, True)
            due, flag_at = _take(flags, flag_at, due, index, compacted, True)
            in_contact, flag_at = _take(flags, flag_at, in_contact, index, compacted, False)
            final_contact, flag_at = _take(flags, flag_at, final_contact, index, compacted,
                                           True)
        iterations = iteration
        fields(a, d_pred, v_pred, cd, cv, top_speed, top_acceleration, shapes[0], shapes[1],
               shapes[2], shapes[3], ranges, d, v, displacement_t, theta_x_rate_t,
               theta_x_acceleration_t, bending_y_rate_t, bending_y_acceleration_t,
               bending_z_rate_t)
        if imbalance[0]:                          # the imbalance's node w'' (issue 12)
            imbalance_node_acceleration(imbalance, a, bending_z_acceleration_t)
        force_t[:, :] = 0.0
        touching = string_forces(switches, strain_arguments, coupling_arguments,
                                 contact_arguments, imbalance, rotating, displacement_t,
                                 theta_x_rate_t, theta_x_acceleration_t, bending_y_rate_t,
                                 bending_y_acceleration_t, bending_z_rate_t,
                                 bending_z_acceleration_t, strain, linear, stress, coupling,
                                 force_t, radial, in_contact, tangent)
        still, used = update(
            iteration, force_t, radial, in_contact, tangent, touching, theta_x_rate_t,
            bit_node, n_nodes, shapes_t[0], shapes_t[1], shapes_t[2], shapes_t[3], ranges,
            mass, mass_is_identity, damping, stiffness, stiffness_diagonal, effective_inverse,
            groups, local_directions, local_response, local_gram, bit_rows, bit_response,
            bit_flexibility, dt, dt2, tolerance, load, static_force, bit_rock, law,
            fade_speed, germ, random, have_rate, have_active, rate, due, previous_contact,
            previous_lifted, d, v, a, modal, residual, y, product, responses, touch, error,
            previous_error, active, bit_ok, scratch, flexibilities, on_wall, final_full,
            final_modal, final_radial, final_contact, final_tangent, bit_rop, bit_omega,
            bit_force, bit_torque, bit_lifted, bit_jacobian, bit_solved, imbalance,
            displacement_t, pattern)
        robust += used
        if still == 0:
            break
    if compacted > 0:                            # back into the whole batch
        (a_all, error_all, previous_error_all, active_all, bit_ok_all, rate_all,
         final_full_all, final_modal_all, final_radial_all, final_contact_all,
         final_tangent_all, bit_rop_all, bit_omega_all, bit_force_all, bit_torque_all,
         bit_lifted_all, bit_jacobian_all, bit_solved_all) = full
        for c in range(compacted):
            i = index[c]
            for j in range(a.shape[0]):
                a_all[j, i] = a[j, c]
            for j in range(final_full.shape[0]):
                final_full_all[j, i] = final_full[j, c]
            for j in range(final_modal.shape[0]):
                final_modal_all[j, i] = final_modal[j, c]
            error_all[i], previous_error_all[i] = error[c], previous_error[c]
            active_all[i], bit_ok_all[i], rate_all[i] = active[c], bit_ok[c], rate[c]
            final_radial_all[i] = final_radial[c]
            final_contact_all[i] = final_contact[c]
            final_tangent_all[i] = final_tangent[c]
            bit_rop_all[i], bit_omega_all[i] = bit_rop[c], bit_omega[c]
            bit_force_all[i], bit_torque_all[i] = bit_force[c], bit_torque[c]
            bit_lifted_all[i], bit_solved_all[i] = bit_lifted[c], bit_solved[c]
            bit_jacobian_all[i] = bit_jacobian[c]
        a, error, bit_ok = a_all, error_all, bit_ok_all
        d_pred, v_pred = predictor
        bit_force, bit_torque = bit_force_all, bit_torque_all
        final_full, final_modal, final_contact = final_full_all, final_modal_all, final_contact_all
    count = finish(d_pred, v_pred, a, cd, cv, bit_axial_row, hole, bit_force, bit_torque,
                   law[0, 7], static_force, bit_rows, axial_index, torsion_index, final_full,
                   final_modal, error, bit_ok, tolerance, q_out, q_rate_out,
                   q_acceleration_out, hole_out, finite, converged, on_bottom, pattern)
    touching = False
    for i in range(final_contact.shape[0]):
        for node in range(final_contact.shape[1]):
            touching = touching or final_contact[i, node]
    on_bottom_count = np.count_nonzero(on_bottom)
    lifted_count = np.count_nonzero(final[9])              # the whole batch's flags
    return iterations, robust, count, touching, on_bottom_count, lifted_count


@inline
def _narrow(floats, at, full, index, k, gather):
    """
    Return (the compact (rows, k) array of a members-last (rows, m) one, the next offset).

    Carved out of ``floats`` at ``at`` (the whole array's size is reserved, so every k gets
    the same layout); with ``gather`` it holds the columns ``index[:k]`` of ``full``.
    """
    rows = full.shape[0]
    view = floats[at:at + rows * k].reshape((rows, k))
    if gather:
        for j in range(rows):
            for c in range(k):
                view[j, c] = full[j, index[c]]
    return view, at + full.size


@inline
def _take(buffer, at, full, index, k, gather):
    """
    Return what :func:`_narrow` does, for a members-first (m, ...) array.

    An array with one row shared by the batch (shape[0] 1, gather False) stays as it is.
    """
    if full.shape[0] == 1 and not gather:
        return full, at
    size = full.size // full.shape[0] * k
    view = buffer[at:at + size].reshape((k,) + full.shape[1:])
    if gather:
        for c in range(k):
            view[c] = full[index[c]]
    return view, at + full.size
