"""
One iteration of the Newmark step after the forces of the iterate: the update of a batch.

The update of the module docstring of :mod:`~drill_twin.integrator.newmark`, per member:
Phi^T f; the evaluation of members already done kept as their final one; the residual R and
y = S0^-1 R; S^-1 by the Woodbury identity for members on the wall
(:mod:`~drill_twin.integrator.woodbury`); the bit's 2x2 equation
(:mod:`~drill_twin.integrator.bit_solve`); the new accelerations; and every per-member
decision (converged, accepted after one iteration, verifying). :func:`update` runs them in
order; each part is compiled into it (one compiled function per iteration, the batch loop not
split across calls). Loops over the n coordinates run with the members innermost (the arrays'
layout); the per-member work (the bit, the decisions) runs member by member.

The operands are the named structures of :mod:`~drill_twin.integrator.step_operands`.
"""
from __future__ import annotations

import numpy as np

from drill_twin.integrator.bit_solve import BitEquation, BitSolution, MemberLaw, solve_bit
from drill_twin.integrator.newmark_scheme import BETA, GAMMA
from drill_twin.integrator.woodbury import corrected_response, touches
from drill_twin.model.bottom_hole_pattern import surface_at
from drill_twin.numerics.compiled import inline, kernel

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
members: a second iteration on 8 steps of 25, 32 members each, against every step with a slot
per group: 5.47 against 5.68 ms a step, medians of one process each). A member's schedule
depends on its index only."""


@inline
def set_due(clock, due):
    """Set due (m,): the members that verify their first iterate on step ``clock``."""
    for i in range(due.shape[0]):
        due[i] = (clock + VERIFY_SPACING * (i // VERIFY_GROUP % VERIFY_SLOTS)) % VERIFY_EVERY == 0


@kernel
def update(iteration, touching, operators, law, history, modal, members, work, final,
           imbalance):
    """
    One iteration after the forces of the iterate (work.force_t, without the bit).

    iteration: its number (from 1); touching: the (member, node) pairs on the wall; the
    structures of :mod:`step_operands` (operators, law, history, modal, members, work, final)
    and the imbalance's operands. Updates modal.a, the members' error, active and bit_ok, the
    bit of the active members and the contraction rates (history.rate) in place, and keeps
    the evaluation of the frozen members (at their final state) in ``final``. Returns
    (members still active, 1 if any member needed the bracketed bit solve).
    """
    basis, linear = operators.basis, operators.linear
    _project(basis, work.force_t, modal.modal)
    _keep_final(iteration, touching, members.active, work, modal.modal, final)
    _residual(linear, modal)
    _wall_responses(touching, operators, imbalance, work, modal.y, members)
    _bit_rates(basis, operators.local, modal, members.scratch)
    robust_used = _solve_bits(operators, law, work, members, final)
    _accelerate(operators.local, modal, members)
    return _decide(iteration, operators, history, work, members, final), robust_used


@inline
def _project(basis, force_t, modal):
    """Set modal (n, m) = Phi^T f, block by block, of force_t (D, m)."""
    ranges, shapes_t = basis.ranges, basis.shapes_t
    for b in range(4):
        np.dot(shapes_t[b], force_t[ranges[b, 0]:ranges[b, 1]],
               modal[ranges[b, 2]:ranges[b, 3]])


@inline
def _keep_final(iteration, touching, active, work, modal, final):
    """Keep the evaluation of the members no longer active: their final state's."""
    force_t, radial, in_contact, tangent = work.force_t, work.radial, work.in_contact, work.tangent
    full, final_modal, final_radial = final.full, final.modal, final.radial
    final_contact, final_tangent = final.contact, final.tangent
    if iteration == 1:
        full[:, :] = force_t
        final_modal[:, :] = modal
        final_radial[:, :] = radial
        final_contact[:, :] = in_contact
        if touching:
            final_tangent[:, :, :, :] = tangent
        else:
            final_tangent[:, :, :, :] = 0.0
        return
    for i in range(active.shape[0]):
        if active[i]:
            continue
        for j in range(force_t.shape[0]):
            full[j, i] = force_t[j, i]
        for j in range(modal.shape[0]):
            final_modal[j, i] = modal[j, i]
        for node in range(radial.shape[1]):
            final_radial[i, node] = radial[i, node]
            final_contact[i, node] = in_contact[i, node]
            for r in range(2):
                for c in range(2):
                    final_tangent[i, node, r, c] = tangent[i, node, r, c] if touching else 0.0


@inline
def _residual(linear, modal):
    """R = M a + C v + K d - Phi^T f - g into modal.residual, then y = S0^-1 R."""
    a, residual, product, d = modal.a, modal.residual, modal.product, modal.d
    forces, load, diagonal = modal.modal, modal.load, linear.stiffness_diagonal
    n, members = a.shape
    if linear.mass_is_identity:
        residual[:, :] = a
    else:
        np.dot(linear.mass, a, residual)
    _block_product(linear.damping, linear.groups, modal.v, product)
    residual += product
    if diagonal.shape[0] > 0:
        for j in range(n):
            k = diagonal[j]
            for i in range(members):
                residual[j, i] += d[j, i] * k
    else:
        np.dot(linear.stiffness, d, product)
        residual += product
    for j in range(n):
        for i in range(members):
            residual[j, i] = residual[j, i] - forces[j, i] - load[j, i]
    _block_product(linear.inverse, linear.groups, residual, modal.y)


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
def _wall_responses(touching, operators, imbalance, work, y, members):
    """Set S^-1 B with the contact tangents (Woodbury), for the members on the wall only."""
    local, n_nodes = operators.local, operators.basis.n_nodes
    beta_dt2, bit_response, bit_flexibility = (operators.scheme.beta_dt2, local.bit_response,
                                               local.bit_flexibility)
    in_contact, tangent, displacement_t = work.in_contact, work.tangent, work.displacement_t
    on_wall, responses, flexibilities = members.on_wall, members.responses, members.flexibilities
    for i in range(on_wall.shape[0]):
        on_wall[i] = touching > 0 and touches(in_contact, i, n_nodes) or imbalance[0]
        if on_wall[i]:
            responses[i, :, :] = bit_response
            flexibilities[i, :, :] = corrected_response(
                i, in_contact=in_contact, tangent=tangent, n_nodes=n_nodes, beta_dt2=beta_dt2,
                local=local, imbalance=imbalance, displacement_t=displacement_t, y=y,
                response=responses[i])
        else:
            flexibilities[i, :, :] = bit_flexibility


@inline
def _bit_rates(basis, local, modal, scratch):
    """Set the iterate's bit ROP (scratch[0]), B^T y (scratch[1:3]), |v|^2 (scratch[3])."""
    v, y, bit_rows = modal.v, modal.y, local.bit_rows
    rop, by0, by1, speed = scratch[0], scratch[1], scratch[2], scratch[3]
    rop[:] = 0.0
    by0[:] = 0.0
    by1[:] = 0.0
    speed[:] = 0.0
    members = rop.shape[0]
    for j in range(basis.ranges[0, 2], basis.ranges[0, 3]):
        row = bit_rows[0, j]
        for i in range(members):
            rop[i] += row * v[j, i]
    for j in range(v.shape[0]):
        row0, row1 = bit_rows[0, j], bit_rows[1, j]
        for i in range(members):
            by0[i] += y[j, i] * row0
            by1[i] += y[j, i] * row1
            speed[i] += v[j, i] * v[j, i]


@inline
def _solve_bits(operators, law, work, members, final):
    """
    Solve each member's bit equation: F - F_c into scratch[4:6], the active members' bit.

    The lobes: the surface lies s below the mean bottom and moves at kappa omega (the bit
    equation is solved relative to the surface under the bit, at the iterate's angle).
    Returns 1 if a member needed the bracketed solve.
    """
    dt, bit_node = operators.scheme.time_step_s, operators.basis.bit_node
    scratch, flexibilities, touch = members.scratch, members.flexibilities, members.touch
    active, theta_x_rate_t = members.active, work.theta_x_rate_t
    displacement_t = work.displacement_t
    rop, by0, by1, p0, p1 = scratch[0], scratch[1], scratch[2], scratch[4], scratch[5]
    rows, germs, fade_speeds, pattern = law.rows, law.germs, law.fade_speeds, law.pattern
    static_force, bit_rock, random = law.static_force_n, law.bit_rock, law.random
    bit_rop, bit_omega, bit_force, bit_torque = final.rop, final.omega, final.force, final.torque
    lifted, solved, jacobian = final.lifted, final.solved, final.jacobian
    gdt = GAMMA * dt
    slope = rows[0, 7] * GAMMA / (BETA * dt)            # a compliant rock's resting branch
    robust_used = 0
    for i in range(rop.shape[0]):
        omega = theta_x_rate_t[bit_node, i]
        linear0, linear1 = rop[i] - gdt * by0[i], omega - gdt * by1[i]
        g = min(i, germs.shape[0] - 1)
        k = min(i, rows.shape[0] - 1)
        if bit_rock:
            height, kappa = surface_at(pattern, displacement_t, i)
            bit = solve_bit(
                BitEquation(linear_rop=linear0, linear_omega=linear1,
                            flexibility=flexibilities[i], start_rop=rop[i], start_omega=omega,
                            touch=touch[i] + GAMMA / (BETA * dt) * height, slope=slope,
                            gdt=gdt, static_force_n=static_force, kappa=kappa),
                MemberLaw(g11=germs[g, 0, 0], g12=germs[g, 0, 1], g22=germs[g, 1, 1],
                          random=random, constants=rows[k], fade_speed=fade_speeds[k]))
            robust_used |= bit.robust
        else:
            bit = BitSolution(rop=linear0, omega=linear1, force=static_force, torque=0.0,
                              lifted=False, j00=0.0, j01=0.0, j10=0.0, j11=0.0, solved=True,
                              robust=0)
        p0[i], p1[i] = bit.force - static_force, bit.torque - 0.0
        if active[i]:
            bit_rop[i], bit_omega[i], bit_force[i], bit_torque[i] = (
                bit.rop, bit.omega, bit.force, bit.torque)
            lifted[i], solved[i] = bit.lifted, bit.solved
            jacobian[i, 0, 0], jacobian[i, 0, 1] = bit.j00, bit.j01
            jacobian[i, 1, 0], jacobian[i, 1, 1] = bit.j10, bit.j11
    return robust_used


@inline
def _accelerate(local, modal, members):
    """Set a = a - y + S^-1 B (F - F_c) of the active members; |increment|^2 in scratch[1]."""
    a, y, bit_response = modal.a, modal.y, local.bit_response
    scratch, responses, active = members.scratch, members.responses, members.active
    on_wall = members.on_wall
    p0, p1 = scratch[4], scratch[5]
    norm = scratch[1]                                    # (B^T y is used up)
    norm[:] = 0.0
    for j in range(a.shape[0]):
        r0, r1 = bit_response[j, 0], bit_response[j, 1]
        for i in range(a.shape[1]):
            if active[i]:
                if on_wall[i]:
                    updated = a[j, i] - y[j, i] + (p0[i] * responses[i, j, 0]
                                                   + p1[i] * responses[i, j, 1])
                else:
                    updated = a[j, i] - y[j, i] + (p0[i] * r0 + p1[i] * r1)
                increment = a[j, i] - updated
                norm[i] += increment * increment
                a[j, i] = updated


@inline
def _decide(iteration, operators, history, work, members, final):
    """
    Decide for each member: converged, accepted after one iteration, or iterating on.

    Sets the members' error, active and bit_ok and the contraction rates; returns how many
    members are still active.
    """
    scheme, n_nodes = operators.scheme, operators.basis.n_nodes
    gdt, tolerance = GAMMA * scheme.time_step_s, scheme.tolerance
    rate, due, error, active = history.rate, members.due, members.error, members.active
    bit_ok, previous_error, solved = members.bit_ok, members.previous_error, final.solved
    norm, speed = members.scratch[1], members.scratch[3]
    have_rate, have_active = history.have_rate, history.have_active
    previous_lifted, previous_contact = history.previous_lifted, history.previous_contact
    lifted, in_contact = final.lifted, work.in_contact
    still = 0
    for i in range(active.shape[0]):
        was_active = active[i]
        bit_ok[i] = bit_ok[i] and (not was_active or solved[i])
        new_error = gdt * np.sqrt(norm[i]) / (np.sqrt(speed[i]) + VELOCITY_SCALE)
        previous_error[i] = error[i]
        if was_active:
            error[i] = new_error
        now = was_active and np.isfinite(error[i]) and bit_ok[i]
        done = now and error[i] <= tolerance and not (iteration == 1 and due[i])
        if iteration == 1 and now and have_rate:
            accept = np.isfinite(rate[i]) and not due[i]
            if accept and have_active:
                accept = previous_lifted[i] == lifted[i]
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
    return still
