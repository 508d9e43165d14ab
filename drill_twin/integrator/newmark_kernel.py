"""
The compiled Newmark step (:mod:`drill_twin.integrator.newmark` holds the method).

A step is :func:`begin` (the predictor), then per iteration :func:`fields` (the iterate's
displacements, rates and the kinematics the forces read, members last), the forces of the
string (:func:`drill_twin.model.forces.string_forces`, the one place they are summed), and
:func:`~drill_twin.integrator.newmark_update.update` (Phi^T f, the residual, S^-1 by the
Woodbury identity for members touching the wall, the bit's 2x2 equation per member, the new
accelerations and every per-member decision), and at the end :func:`finish` (the bit's forces
in the final evaluation, the new state, the checks). The iterations after the first run on
the members still iterating only (:mod:`~drill_twin.integrator.compaction`).

Arrays are members last, (rows, m), so that the dense products are BLAS (np.dot) over the
whole batch and the per-member work reads columns. Every operand is read by name from the
structures of :mod:`~drill_twin.integrator.step_operands`; the predictor and the corrector are
those of :mod:`~drill_twin.integrator.newmark_scheme`, compiled into the loops.
"""
from __future__ import annotations

import numpy as np

from drill_twin.integrator import newmark_scheme as scheme
from drill_twin.integrator.compaction import compacted, scatter_back, still_iterating
from drill_twin.integrator.newmark_scheme import BETA, GAMMA
from drill_twin.integrator.newmark_update import set_due, update
from drill_twin.integrator.step_operands import (AcceptanceHistory, FinalEvaluation, KeptFlags,
                                                 NewState, StepCounts, StepInputs, StepOutputs,
                                                 StepStart)
from drill_twin.model.bit_rock import maximum, minimum
from drill_twin.model.bottom_hole_pattern import surface
from drill_twin.model.excitation import imbalance_node_acceleration
from drill_twin.model.forces import string_forces
from drill_twin.numerics.compiled import inline, kernel

ON_BOTTOM_TOLERANCE_M = 1e-6
"""The bit counts as on bottom when it is within this of the hole bottom (m)."""

predicted_displacement = inline(scheme.predicted_displacement)
predicted_velocity = inline(scheme.predicted_velocity)
corrected_displacement = inline(scheme.corrected_displacement)
corrected_velocity = inline(scheme.corrected_velocity)


@kernel
def external_load(inputs, driven, load):
    """
    Set load (n, m) = g(t + dt): the driven rotation's and the hook's modal load.

    -Phi^T (M psi theta_top'' + C psi theta_top') - Phi^T e_top (H - H_S) of the top drive's
    speed and acceleration and the hook loads H (one for the batch or one per member) of
    ``inputs`` (:class:`~drill_twin.integrator.step_operands.StepInputs`); driven:
    :class:`~drill_twin.integrator.step_operands.DrivenLoad`.
    """
    n, members = load.shape
    hooks, top_speed, top_acceleration = inputs.hooks, inputs.top_speed, inputs.top_acceleration
    mass_driven, damping_driven = driven.mass_driven, driven.damping_driven
    top_axial_row, static_hook = driven.top_axial_row, driven.static_hook_n
    last = hooks.shape[0] - 1
    for j in range(n):
        rotation = -mass_driven[j] * top_acceleration - damping_driven[j] * top_speed
        row = top_axial_row[j]
        for i in range(members):
            load[j, i] = rotation - (hooks[min(i, last)] - static_hook) * row


@kernel
def begin(start, dt, bit_axial_row, rigid, modal, members):
    """
    Compute the predictor (the start members first (m, n), the work arrays members last).

    d*, v*, a = the last acceleration, the hole and ``touch``, the end-of-step ROP that puts the
    bit on the hole bottom (Newmark: d = d* + (beta/gamma) dt (v - v*); on a rigid rock 0 on
    bottom, on a compliant one negative where the bit presses the rock).
    """
    q, q_rate, q_acceleration = start.q, start.q_rate, start.q_acceleration
    hole_in, has_hole = start.hole, start.has_hole
    d_pred, v_pred, a = modal.d_pred, modal.v_pred, modal.a
    touch, hole = members.touch, members.hole
    error, active, bit_ok = members.error, members.active, members.bit_ok
    for i in range(q.shape[0]):
        reach = 0.0
        rate = 0.0
        bit_u = 0.0
        for j in range(q.shape[1]):
            dp = predicted_displacement(q[i, j], q_rate[i, j], q_acceleration[i, j], dt)
            vp = predicted_velocity(q_rate[i, j], q_acceleration[i, j], dt)
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
def fields(modal, dt, inputs, basis, work):
    """
    Set d = d* + beta dt^2 a, v = v* + gamma dt a (n, m), and the kinematics of the forces.

    The kinematics are forces.Kinematics, members last (``work``: ForceWork), with the top
    drive's speed and acceleration of ``inputs`` on theta_x; ``basis``: Phi's blocks.
    """
    a, d, v, d_pred, v_pred = modal.a, modal.d, modal.v, modal.d_pred, modal.v_pred
    n, members = a.shape
    for j in range(n):
        for i in range(members):
            d[j, i] = corrected_displacement(d_pred[j, i], a[j, i], dt)
            v[j, i] = corrected_velocity(v_pred[j, i], a[j, i], dt)
    shapes, ranges = basis.shapes, basis.ranges
    for b in range(4):
        np.dot(shapes[b], d[ranges[b, 2]:ranges[b, 3]],
               work.displacement_t[ranges[b, 0]:ranges[b, 1]])
    t0, t1 = ranges[1, 2], ranges[1, 3]
    np.dot(shapes[1], v[t0:t1], work.theta_x_rate_t)
    np.dot(shapes[1], a[t0:t1], work.theta_x_acceleration_t)
    theta_x_rate_t, theta_x_acceleration_t = work.theta_x_rate_t, work.theta_x_acceleration_t
    theta_x_rate_t += inputs.top_speed
    theta_x_acceleration_t += inputs.top_acceleration
    np.dot(shapes[2], v[ranges[2, 2]:ranges[2, 3]], work.bending_y_rate_t)
    np.dot(shapes[2], a[ranges[2, 2]:ranges[2, 3]], work.bending_y_acceleration_t)
    np.dot(shapes[3], v[ranges[3, 2]:ranges[3, 3]], work.bending_z_rate_t)


@inline
def on_rock(bit_u, hole, height):
    """
    Whether a bit at axial displacement bit_u is on the rock (m, m, m).

    At most ON_BOTTOM_TOLERANCE_M above the surface, which lies ``height`` below the hole's
    mean bottom ``hole`` (Simulator._on_surface, in numpy, is the same test).
    """
    return bit_u >= (hole + height) - ON_BOTTOM_TOLERANCE_M


@kernel
def finish(modal, members, final, basis, local, scheme, law, new):
    """
    Finish a step; return the number of members converged.

    The bit's exact forces into the final evaluation (final.full (D, m), final.modal (n, m)),
    the new state members first (``new``: :class:`NewState`: q, q_rate, q_acceleration (m, n),
    hole (m,): the hole only deepens, to where the bit ends less the depth -F1 / k by which it
    presses a compliant rock (1 / k the law's compliance, 0 for a rigid one), and less the
    lobes' height s of the law's pattern under it: the hole is the mean bottom), finite and
    converged (m,), on_bottom (m,): the bit within ON_BOTTOM_TOLERANCE_M of the rock's surface
    under it (the Simulator's on-bottom test), error (m,): the members' final relative
    velocity increments.
    """
    compliance, static_force, pattern = law.rows[0, 7], law.static_force_n, law.pattern
    a, d_pred, v_pred = modal.a, modal.d_pred, modal.v_pred
    bit_rows, bit_axial_row = local.bit_rows, local.bit_axial_row
    full, final_modal, force, torque = final.full, final.modal, final.force, final.torque
    q, q_rate, q_acceleration, hole = new.q, new.q_rate, new.q_acceleration, new.hole
    on_bottom, finite, converged, error = new.on_bottom, new.finite, new.converged, new.error
    hole_before, bit_ok, member_error = members.hole, members.bit_ok, members.error
    axial_dof, torsion_dof = basis.bit_axial_dof, basis.bit_torsion_dof
    n, count, dt, tolerance = a.shape[0], 0, scheme.time_step_s, scheme.tolerance
    for i in range(a.shape[1]):
        change0 = force[i] - static_force
        change1 = torque[i] - 0.0
        full[axial_dof, i] += change0
        full[torsion_dof, i] += change1
        bit_u = 0.0
        ok = True
        for j in range(n):
            final_modal[j, i] += change0 * bit_rows[0, j] + change1 * bit_rows[1, j]
            d = corrected_displacement(d_pred[j, i], a[j, i], dt)
            v = corrected_velocity(v_pred[j, i], a[j, i], dt)
            q[i, j], q_rate[i, j], q_acceleration[i, j] = d, v, a[j, i]
            bit_u += d * bit_axial_row[j]
            ok = ok and np.isfinite(d) and np.isfinite(v)
        height = 0.0
        if pattern[0]:
            twist = 0.0
            for j in range(n):
                twist += q[i, j] * bit_rows[1, j]
            height = surface(pattern, pattern[2][0] + twist)[0]
        hole[i] = maximum(hole_before[i], bit_u + compliance * minimum(force[i], 0.0) - height)
        on_bottom[i] = on_rock(bit_u, hole[i], height)
        finite[i] = ok
        converged[i] = ok and bit_ok[i] and member_error[i] <= tolerance
        error[i] = member_error[i]
        count += converged[i]
    return count


@kernel
def step(start, inputs, history, operands, outputs, kept):
    """
    One Newmark step of m members.

    :func:`begin`, then (:func:`fields`, the forces of the string, :func:`update`) until every
    member is done or the scheme's max_iterations, then :func:`finish`. The arguments are the
    structures of :mod:`~drill_twin.integrator.step_operands`: operands
    (:class:`StepOperands`: what does not change from step to step, unboxed as one pointer)
    and, as ``tuple(structure)`` (module docstring there), start (:class:`StepStart`), inputs
    (:class:`StepInputs`), history (:class:`AcceptanceHistory`), outputs
    (:class:`StepOutputs`) and kept (:class:`KeptFlags`): the new arrays the step writes its
    state and its final evaluation into.

    Returns its :class:`StepCounts` as a tuple (``StepCounts._make`` of it: 0.4 against 0.9 us
    for numba to return the namedtuple, measured): what the time loop's Python checks of every
    step, so that it needs no pass over the flags.
    """
    start, inputs, history = StepStart(*start), StepInputs(*inputs), AcceptanceHistory(*history)
    outputs, kept = StepOutputs(*outputs), KeptFlags(*kept)
    operators, law, forces = operands.operators, operands.law, operands.forces
    modal, members, work = operands.modal, operands.members, operands.force_work
    final = FinalEvaluation(
        full=outputs.full, modal=outputs.modal, radial=outputs.radial, contact=kept.contact,
        tangent=operands.final_tangent, rop=outputs.rop, omega=outputs.omega,
        force=outputs.force, torque=outputs.torque, lifted=kept.lifted,
        jacobian=outputs.jacobian, solved=operands.final_solved)
    scheme_, basis = operators.scheme, operators.basis
    external_load(inputs, operators.load, modal.load)
    set_due(history.clock, members.due)
    begin(start, scheme_.time_step_s, operators.local.bit_axial_row, law.rows[0, 7] == 0.0,
          modal, members)
    # The whole batch's structures: a member frozen after the first iteration is left there,
    # and the later iterations run on the members still iterating, gathered (compacted).
    whole_modal, whole_members, whole_final, whole_history = modal, members, final, history
    batch = modal.a.shape[1]
    iterations, robust, compacted_count, still = 0, 0, 0, batch
    for iteration in range(1, scheme_.max_iterations + 1):
        if iteration > 1 and still < batch and compacted_count == 0:
            compacted_count = still_iterating(members.active, operands.compact.index)
            modal, members, work, final, law, history = compacted(
                operands.compact, modal, members, work, final, law, history, compacted_count)
        iterations = iteration
        fields(modal, scheme_.time_step_s, inputs, basis, work)
        if forces.imbalance[0]:                    # the imbalance's node w'' (excitation.py)
            imbalance_node_acceleration(forces.imbalance, modal.a, work.bending_z_acceleration_t)
        work.force_t[:, :] = 0.0
        touching = string_forces(
            forces.switches, forces.strain, forces.coupling, forces.contact, forces.imbalance,
            forces.rotating, work.displacement_t, work.theta_x_rate_t,
            work.theta_x_acceleration_t, work.bending_y_rate_t, work.bending_y_acceleration_t,
            work.bending_z_rate_t, work.bending_z_acceleration_t, work.strain, work.linear,
            work.stress, work.coupling, work.force_t, work.radial, work.in_contact, work.tangent)
        still, used = update(iteration=iteration, touching=touching, operators=operators,
                             law=law, history=history, modal=modal, members=members,
                             work=work, final=final, imbalance=forces.imbalance)
        robust += used
        if still == 0:
            break
    if compacted_count > 0:                      # back into the whole batch
        scatter_back(operands.compact.index, compacted_count, modal=modal, members=members,
                     final=final, history=history, whole_modal=whole_modal,
                     whole_members=whole_members, whole_final=whole_final,
                     whole_history=whole_history)
    count = finish(whole_modal, whole_members, whole_final, basis, operators.local, scheme_,
                   operands.law,
                   NewState(q=outputs.q, q_rate=outputs.q_rate,
                            q_acceleration=outputs.q_acceleration, hole=outputs.hole,
                            finite=outputs.finite, converged=outputs.converged,
                            on_bottom=outputs.on_bottom, error=outputs.error))
    touching, contact = False, whole_final.contact
    for i in range(contact.shape[0]):
        for node in range(contact.shape[1]):
            touching = touching or contact[i, node]
    counts = StepCounts(iterations=iterations, robust=robust, converged=count,
                        touching=touching, on_bottom=np.count_nonzero(outputs.on_bottom),
                        lifted=np.count_nonzero(whole_final.lifted))
    return counts[:]                  # a tuple: numba returns a namedtuple by calling its class
