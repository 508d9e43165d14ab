"""
The iterations after a step's first run on the members still iterating, gathered.

After the first iteration most members of a batch are done (accepted or converged); the
later iterations run on the others only, gathered into arrays of their own carved out of the
batch's :class:`~drill_twin.integrator.step_operands.CompactBuffers`: a member frozen after
the first iteration costs nothing more (with wall contact, one member's Newton iterations
would otherwise cost the whole batch's). :func:`compacted` gathers, :func:`scatter_back` puts what
the iterations wrote back into the whole batch's arrays. Every structure keeps its type: the
gathered arrays are C-contiguous arrays of the same rank.

The arrays are carved in a fixed order, so that every count of members still iterating gets
the same layout; arrays the iterations only write are carved but not gathered, and the law's
operands shared by the batch (one row) stay as they are.
"""
from __future__ import annotations

from drill_twin.integrator.step_operands import (AcceptanceHistory, BitLaw, FinalEvaluation,
                                                 ForceWork, MemberWork, ModalWork)
from drill_twin.numerics.compiled import inline


@inline
def narrow(floats, at, full, index, k, gather):
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
def take(buffer, at, full, index, k, gather):
    """
    Return what :func:`narrow` does, for a members-first (m, ...) array.

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


@inline
def still_iterating(active, index):
    """Write the indices of the active members into ``index``; return how many there are."""
    k = 0
    for i in range(active.shape[0]):
        if active[i]:
            index[k] = i
            k += 1
    return k


@inline
def _compact_modal(floats, at, modal, index, k):
    """Return the iterate's arrays of the members index[:k] (d*, v*, a and g gathered)."""
    a, at = narrow(floats, at, modal.a, index, k, True)
    d_pred, at = narrow(floats, at, modal.d_pred, index, k, True)
    v_pred, at = narrow(floats, at, modal.v_pred, index, k, True)
    load, at = narrow(floats, at, modal.load, index, k, True)
    d, at = narrow(floats, at, modal.d, index, k, False)
    v, at = narrow(floats, at, modal.v, index, k, False)
    residual, at = narrow(floats, at, modal.residual, index, k, False)
    y, at = narrow(floats, at, modal.y, index, k, False)
    product_modal, at = narrow(floats, at, modal.modal, index, k, False)
    product, at = narrow(floats, at, modal.product, index, k, False)
    return ModalWork(d_pred=d_pred, v_pred=v_pred, a=a, d=d, v=v, residual=residual, y=y,
                     modal=product_modal, product=product, load=load), at


@inline
def _compact_kinematics(floats, at, work, index, k):
    """
    Return the force kernels' members-last arrays for k members (written before read).

    Returned in a :class:`ForceWork` whose radial, in_contact and tangent are still the
    batch's (:func:`compacted` carves them further on).
    """
    displacement_t, at = narrow(floats, at, work.displacement_t, index, k, False)
    theta_x_rate_t, at = narrow(floats, at, work.theta_x_rate_t, index, k, False)
    theta_x_acceleration_t, at = narrow(floats, at, work.theta_x_acceleration_t, index, k,
                                        False)
    bending_y_rate_t, at = narrow(floats, at, work.bending_y_rate_t, index, k, False)
    bending_y_acceleration_t, at = narrow(floats, at, work.bending_y_acceleration_t, index, k,
                                          False)
    bending_z_rate_t, at = narrow(floats, at, work.bending_z_rate_t, index, k, False)
    bending_z_acceleration_t, at = narrow(floats, at, work.bending_z_acceleration_t, index, k,
                                          False)
    strain, at = narrow(floats, at, work.strain, index, k, False)
    linear, at = narrow(floats, at, work.linear, index, k, False)
    stress, at = narrow(floats, at, work.stress, index, k, False)
    coupling, at = narrow(floats, at, work.coupling, index, k, False)
    force_t, at = narrow(floats, at, work.force_t, index, k, False)
    return ForceWork(displacement_t=displacement_t, theta_x_rate_t=theta_x_rate_t,
                     theta_x_acceleration_t=theta_x_acceleration_t,
                     bending_y_rate_t=bending_y_rate_t,
                     bending_y_acceleration_t=bending_y_acceleration_t,
                     bending_z_rate_t=bending_z_rate_t,
                     bending_z_acceleration_t=bending_z_acceleration_t, strain=strain,
                     linear=linear, stress=stress, coupling=coupling, force_t=force_t,
                     radial=work.radial, in_contact=work.in_contact, tangent=work.tangent), at


@inline
def _with_contact(work, radial, in_contact, tangent):
    """Return ``work`` with the wall's arrays radial, in_contact and tangent."""
    return ForceWork(displacement_t=work.displacement_t, theta_x_rate_t=work.theta_x_rate_t,
                     theta_x_acceleration_t=work.theta_x_acceleration_t,
                     bending_y_rate_t=work.bending_y_rate_t,
                     bending_y_acceleration_t=work.bending_y_acceleration_t,
                     bending_z_rate_t=work.bending_z_rate_t,
                     bending_z_acceleration_t=work.bending_z_acceleration_t,
                     strain=work.strain, linear=work.linear, stress=work.stress,
                     coupling=work.coupling, force_t=work.force_t, radial=radial,
                     in_contact=in_contact, tangent=tangent)


@inline
def compacted(compact, modal, members, work, final, law, history, k):
    """
    Return (modal, members, work, final, law, history) of the members ``compact.index[:k]``.

    The structures of :mod:`step_operands` with their arrays gathered (what the iterations
    read) or carved only (what they write first); the hole and the last step's flags are not
    read after the first iteration and stay the batch's.
    """
    floats, flags, index = compact.floats, compact.flags, compact.index
    modal, at = _compact_modal(floats, 0, modal, index, k)
    scratch, at = narrow(floats, at, members.scratch, index, k, False)
    kinematic, at = _compact_kinematics(floats, at, work, index, k)
    full, at = narrow(floats, at, final.full, index, k, True)
    final_modal, at = narrow(floats, at, final.modal, index, k, True)
    touch, at = take(floats, at, members.touch, index, k, True)
    error, at = take(floats, at, members.error, index, k, True)
    previous_error, at = take(floats, at, members.previous_error, index, k, True)
    rate, at = take(floats, at, history.rate, index, k, True)
    rop, at = take(floats, at, final.rop, index, k, True)
    omega, at = take(floats, at, final.omega, index, k, True)
    force, at = take(floats, at, final.force, index, k, True)
    torque, at = take(floats, at, final.torque, index, k, True)
    fade_speeds, at = take(floats, at, law.fade_speeds, index, k, law.fade_speeds.shape[0] > 1)
    radial, at = take(floats, at, work.radial, index, k, False)
    final_radial, at = take(floats, at, final.radial, index, k, True)
    rows, at = take(floats, at, law.rows, index, k, law.rows.shape[0] > 1)
    flexibilities, at = take(floats, at, members.flexibilities, index, k, False)
    responses, at = take(floats, at, members.responses, index, k, False)
    jacobian, at = take(floats, at, final.jacobian, index, k, True)
    germs, at = take(floats, at, law.germs, index, k, law.germs.shape[0] > 1)
    tangent, at = take(floats, at, work.tangent, index, k, False)
    final_tangent, at = take(floats, at, final.tangent, index, k, True)
    active, flag_at = take(flags, 0, members.active, index, k, True)
    bit_ok, flag_at = take(flags, flag_at, members.bit_ok, index, k, True)
    on_wall, flag_at = take(flags, flag_at, members.on_wall, index, k, False)
    lifted, flag_at = take(flags, flag_at, final.lifted, index, k, True)
    solved, flag_at = take(flags, flag_at, final.solved, index, k, True)
    due, flag_at = take(flags, flag_at, members.due, index, k, True)
    in_contact, flag_at = take(flags, flag_at, work.in_contact, index, k, False)
    contact, flag_at = take(flags, flag_at, final.contact, index, k, True)
    return (modal,
            MemberWork(touch=touch, hole=members.hole, error=error,
                       previous_error=previous_error, active=active, bit_ok=bit_ok, due=due,
                       on_wall=on_wall, scratch=scratch, responses=responses,
                       flexibilities=flexibilities),
            _with_contact(kinematic, radial, in_contact, tangent),
            FinalEvaluation(full=full, modal=final_modal, radial=final_radial, contact=contact,
                            tangent=final_tangent, rop=rop, omega=omega, force=force,
                            torque=torque, lifted=lifted, jacobian=jacobian, solved=solved),
            BitLaw(static_force_n=law.static_force_n, bit_rock=law.bit_rock, rows=rows,
                   fade_speeds=fade_speeds, germs=germs, random=law.random,
                   pattern=law.pattern),
            AcceptanceHistory(have_rate=history.have_rate, have_active=history.have_active,
                              rate=rate, clock=history.clock,
                              previous_contact=history.previous_contact,
                              previous_lifted=history.previous_lifted))


@inline
def scatter_back(index, k, modal, members, final, history, whole_modal, whole_members,
                 whole_final, whole_history):
    """Write what the iterations of the members index[:k] computed into the whole batch's."""
    _scatter_columns(index, k, modal.a, whole_modal.a)
    _scatter_columns(index, k, final.full, whole_final.full)
    _scatter_columns(index, k, final.modal, whole_final.modal)
    _scatter_rows(index, k, members.error, whole_members.error)
    _scatter_rows(index, k, members.previous_error, whole_members.previous_error)
    _scatter_rows(index, k, members.active, whole_members.active)
    _scatter_rows(index, k, members.bit_ok, whole_members.bit_ok)
    _scatter_rows(index, k, history.rate, whole_history.rate)
    _scatter_rows(index, k, final.radial, whole_final.radial)
    _scatter_rows(index, k, final.contact, whole_final.contact)
    _scatter_rows(index, k, final.tangent, whole_final.tangent)
    _scatter_rows(index, k, final.rop, whole_final.rop)
    _scatter_rows(index, k, final.omega, whole_final.omega)
    _scatter_rows(index, k, final.force, whole_final.force)
    _scatter_rows(index, k, final.torque, whole_final.torque)
    _scatter_rows(index, k, final.lifted, whole_final.lifted)
    _scatter_rows(index, k, final.solved, whole_final.solved)
    _scatter_rows(index, k, final.jacobian, whole_final.jacobian)


@inline
def _scatter_columns(index, k, compact, whole):
    """Set whole[:, index[c]] = compact[:, c] for c < k (members-last arrays)."""
    for c in range(k):
        i = index[c]
        for j in range(compact.shape[0]):
            whole[j, i] = compact[j, c]


@inline
def _scatter_rows(index, k, compact, whole):
    """Set whole[index[c]] = compact[c] for c < k (members-first arrays)."""
    for c in range(k):
        whole[index[c]] = compact[c]
