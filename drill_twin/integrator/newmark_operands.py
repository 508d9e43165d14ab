"""
The Newmark step's operands made from a reduced system, and a batch's work arrays.

:func:`step_operators` makes what depends on the system and dt only (S0^-1, the local
directions and their responses, the driven load); :func:`bit_law` the law's constants per
member; :func:`string_force_operands` the forces' kernels' operands; :class:`BatchWork` the
work arrays and the pools of returned arrays of a batch of m members. Every structure is
built by keyword (:mod:`~drill_twin.integrator.step_operands`).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as la

from drill_twin.integrator.newmark_scheme import BETA, effective_matrix
from drill_twin.integrator.step_operands import (
    Basis, BitLaw, CompactBuffers, DrivenLoad, ForceWork, KeptFlags, LinearOperators,
    LocalOperators, MemberWork, ModalWork, Scheme, StepOperators, StepOutputs, StringForces)
from drill_twin.model.bit_rock import fade_speeds
from drill_twin.model.bottom_hole_pattern import LobedBottom
from drill_twin.model.contact import ContactForces
from drill_twin.model.forces import ForceEvaluation, NonlinearForces
from drill_twin.numerics.records import record
from drill_twin.numerics.recycled import RecycledArrays

BLOCKS = ('axial', 'torsional', 'bending_y', 'bending_z')
"""Phi's blocks in the order of :class:`Basis`."""


def local_directions(forces: NonlinearForces) -> np.ndarray:
    """
    Return U (n, 3 + 2 N): the local laws' directions in reduced coordinates.

    The bit's axial and torsional rows of Phi, the v rows then the w rows of every node, and
    theta_x at the imbalance's node (zero without one).
    """
    system = forces.system
    nodes = system.n_nodes
    local = np.zeros((system.size, 3 + 2 * nodes))
    axial, torsion = system.blocks['axial'], system.blocks['torsional']
    local[axial.columns, 0] = axial.shapes[system.bit_node]
    local[torsion.columns, 1] = torsion.shapes[system.bit_node]
    bending_y, bending_z = system.blocks['bending_y'], system.blocks['bending_z']
    local[bending_y.columns, 2:2 + nodes] = bending_y.shapes[:nodes].T       # v rows
    local[bending_z.columns, 2 + nodes:2 + 2 * nodes] = bending_z.shapes[:nodes].T  # w
    if forces.imbalance is not None:
        local[torsion.columns, 2 + 2 * nodes] = torsion.shapes[forces.imbalance.node]
    return local


def stiffness_diagonal(stiffness: np.ndarray) -> np.ndarray | None:
    """[K_r]'s diagonal when it is diagonal (within 1e-9 of its largest entry), else None."""
    off_diagonal = stiffness - np.diag(np.diag(stiffness))
    if np.abs(off_diagonal).max() <= 1e-9 * np.abs(stiffness).max():
        return np.diag(stiffness).copy()
    return None


def step_operators(forces: NonlinearForces, time_step_s: float, tolerance: float,
                   max_iterations: int) -> StepOperators:
    """Return the step's operands that depend on the system and dt (s) only."""
    system, dt = forces.system, float(time_step_s)
    effective = effective_matrix(system.mass, system.damping, system.stiffness, dt)
    local = local_directions(forces)
    response = la.solve(effective, local)                               # S0^-1 U
    gram = local.T @ response                                           # U^T S0^-1 U
    blocks = [system.blocks[name] for name in BLOCKS]
    ranges = np.array([[block.rows.start, block.rows.stop, block.columns.start,
                        block.columns.stop] for block in blocks], dtype=np.int64)
    damping, groups, inverse = _diagonal_blocks(system.damping, la.inv(effective),
                                                ranges[:, 2:])
    diagonal = stiffness_diagonal(system.stiffness)
    mass = system.mass
    return StepOperators(
        basis=Basis(shapes=tuple(np.ascontiguousarray(block.shapes) for block in blocks),
                    shapes_t=tuple(np.ascontiguousarray(block.shapes_t) for block in blocks),
                    ranges=ranges, n_nodes=system.n_nodes, bit_node=system.bit_node,
                    bit_axial_dof=forces.bit_axial_index,
                    bit_torsion_dof=forces.bit_torsion_index),
        linear=LinearOperators(
            mass=np.ascontiguousarray(mass),
            # Mass-normalised modes: [M_r] = I and [K_r] = diag(omega^2) up to rounding.
            mass_is_identity=bool(np.allclose(mass, np.eye(system.size), rtol=0, atol=1e-9)),
            damping=damping, stiffness=np.ascontiguousarray(system.stiffness),
            stiffness_diagonal=np.ascontiguousarray(
                diagonal if diagonal is not None else np.empty(0)),
            inverse=inverse, groups=groups),
        local=LocalOperators(
            directions=np.ascontiguousarray(local), response=np.ascontiguousarray(response),
            gram=np.ascontiguousarray(gram), bit_rows=np.ascontiguousarray(local[:, :2].T),
            bit_response=np.ascontiguousarray(response[:, :2]),
            bit_flexibility=np.ascontiguousarray(gram[:2, :2]),
            bit_axial_row=np.ascontiguousarray(local[:, 0])),
        load=DrivenLoad(mass_driven=np.ascontiguousarray(system.mass_driven, dtype=float),
                        damping_driven=np.ascontiguousarray(system.damping_driven, dtype=float),
                        top_axial_row=np.ascontiguousarray(system.top_axial_row, dtype=float),
                        static_hook_n=float(system.model.prestress.hook_load_n)),
        scheme=Scheme(time_step_s=dt, beta_dt2=BETA * dt ** 2, tolerance=float(tolerance),
                      max_iterations=int(max_iterations)))


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


def bit_law(forces: NonlinearForces, germ: np.ndarray | None,
            law_scales: np.ndarray | None) -> BitLaw:
    """Return the law's operands of ``germ`` (m, 2, 2) or None and the factors (m, 5) or None."""
    law = forces.law
    rows = np.ascontiguousarray(law.rows(law_scales))
    return BitLaw(static_force_n=float(forces.static_weight_on_bit_n),
                  bit_rock=bool(forces.physics.bit_rock), rows=rows,
                  fade_speeds=np.ascontiguousarray(fade_speeds(rows)),
                  germs=(np.eye(2)[None] if germ is None
                         else np.ascontiguousarray(germ, dtype=float)),
                  random=germ is not None,
                  pattern=LobedBottom.arguments_of(forces.bottom_pattern))


def string_force_operands(forces: NonlinearForces) -> StringForces:
    """Return the operands of ``forces``' string_forces kernel (its ``*_arguments``)."""
    return StringForces(switches=forces.switches, strain=forces.strain_arguments,
                        coupling=forces.coupling_arguments, contact=forces.contact_arguments,
                        imbalance=forces.imbalance_arguments, rotating=forces.rotating_arguments)


class BatchWork:
    """
    The work arrays of a step of m members and the pools of what it returns, made once.

    modal (:class:`ModalWork`), members (:class:`MemberWork`), force_work (:class:`ForceWork`,
    the forces' step workspace), compact (:class:`CompactBuffers`); final_tangent
    (m, N, 2, 2) and final_solved (m,): the final evaluation's arrays that callers do not keep
    as they are (the tangents are copied out when a node touches); outputs and kept: pools
    (:class:`RecycledArrays`) of :class:`StepOutputs` and :class:`KeptFlags`; no_contact
    (m, N), no_lift (m,): the flags of a batch without a last step; batch_size: m.
    """

    def __init__(self, forces: NonlinearForces, members: int):
        system = forces.system
        n, nodes, n_dofs = system.size, system.n_nodes, system.n_dofs
        self.batch_size = members
        shape = (n, members)
        empty = np.empty
        self.modal = ModalWork(
            d_pred=empty(shape), v_pred=empty(shape), a=empty(shape), d=empty(shape),
            v=empty(shape), residual=empty(shape), y=empty(shape), modal=empty(shape),
            product=empty(shape), load=empty(shape))
        self.members = MemberWork(
            due=empty(members, dtype=np.bool_), touch=empty(members), hole=empty(members),
            error=empty(members), previous_error=empty(members),
            active=empty(members, dtype=np.bool_), bit_ok=empty(members, dtype=np.bool_),
            responses=empty((members, n, 2)), scratch=empty((6, members)),
            flexibilities=empty((members, 2, 2)), on_wall=empty(members, dtype=np.bool_))
        workspace = forces.step_workspace(members)
        self.force_work = ForceWork(**{name: getattr(workspace, name)
                                       for name in ForceWork._fields})
        self.final_tangent = empty((members, nodes, 2, 2))
        self.final_solved = empty(members, dtype=bool)
        self.outputs = RecycledArrays(lambda: new_outputs(n_dofs, n, nodes, members))
        self.kept = RecycledArrays(lambda: new_kept_flags(nodes, members))
        # The compacted iterations' buffers hold every array of the batch's iterations once
        # (their sizes by dtype), plus the law's operands per member.
        outputs, kept = new_outputs(n_dofs, n, nodes, members), new_kept_flags(nodes, members)
        arrays = (*self.modal, *self.members, *self.force_work, outputs.full, outputs.modal,
                  outputs.radial, outputs.rop, outputs.omega, outputs.force, outputs.torque,
                  outputs.jacobian, kept.contact, kept.lifted, self.final_tangent,
                  self.final_solved)
        del outputs, kept                 # (the state's arrays are not the iterations')
        floats = sum(x.size for x in arrays if x.dtype == np.float64) + 16 * members
        flags = sum(x.size for x in arrays if x.dtype == np.bool_)
        self.compact = CompactBuffers(floats=empty(floats), flags=empty(flags, dtype=np.bool_),
                                      index=empty(members, dtype=np.int64))
        self.no_contact = np.zeros((members, nodes), dtype=bool)
        self.no_lift = np.zeros(members, dtype=bool)


def new_outputs(n_dofs: int, n: int, nodes: int, members: int) -> StepOutputs:
    """Return new arrays for what a step hands its caller (:class:`StepOutputs`)."""
    empty = np.empty
    return StepOutputs(
        q=empty((members, n)), q_rate=empty((members, n)), q_acceleration=empty((members, n)),
        hole=empty(members), finite=empty(members, dtype=bool),
        converged=empty(members, dtype=bool), on_bottom=empty(members, dtype=bool),
        error=empty(members), full=empty((n_dofs, members)), modal=empty((n, members)),
        radial=empty((members, nodes)), rop=empty(members), omega=empty(members),
        force=empty(members), torque=empty(members), jacobian=empty((members, 2, 2)))


def new_kept_flags(nodes: int, members: int) -> KeptFlags:
    """
    Return new arrays for what the integrator keeps a step longer than its caller.

    :class:`KeptFlags`. Recycled apart from :func:`new_outputs`' larger set, which then needs
    two sets, not three: the set written is the one of two steps back, still in cache (64
    members: 1-5 % of the step, measured).
    """
    return KeptFlags(saved_rate=np.empty(members), contact=np.empty((members, nodes), dtype=bool),
                     lifted=np.empty(members, bool))


def final_evaluation(outputs: StepOutputs, kept: KeptFlags, tangent: np.ndarray,
                     touching: bool) -> ForceEvaluation:
    """
    Return a step's final evaluation from the arrays it wrote.

    The tangents (the batch's work array) are copied when ``touching`` (a node touches the
    wall), else the evaluation has none; the bit solve's flags are not in it.
    """
    return record(
        ForceEvaluation, full=outputs.full.T, modal=outputs.modal.T,
        weight_on_bit_n=outputs.force, torque_on_bit_nm=outputs.torque,
        rop_m_per_s=outputs.rop, bit_speed_rad_per_s=outputs.omega, lifted=kept.lifted,
        bit_jacobian=outputs.jacobian,
        contact=record(ContactForces, radial_force_n=outputs.radial, in_contact=kept.contact),
        contact_tangent=tangent.copy() if touching else None)
