"""
The Newmark step's operands, named: what the compiled step (:mod:`newmark_kernel`) reads.

The compiled step reads every operand by its name, from namedtuples grouped by meaning (numba
resolves a field's name when it compiles: reading it costs nothing at run time). The
integrator (:mod:`newmark`, :mod:`newmark_operands`) builds every one of them by keyword, so
no operand is known by its position anywhere: two operands of the same shape and dtype cannot
be exchanged by a miscount. Shapes below: n reduced coordinates, m members, N nodes, D = the
field-wise DOFs (``ReducedSystem.n_dofs``), L = 3 + 2 N local directions; float64 unless said.

What does not change from step to step:

- :class:`StepOperators`: the reduced basis (:class:`Basis`), the linear part of the residual
  and S0^-1 (:class:`LinearOperators`), the local laws' directions and their responses
  (:class:`LocalOperators`), the driven rotation's and the hook's load (:class:`DrivenLoad`)
  and the scheme's numbers (:class:`Scheme`);
- :class:`BitLaw`: the bit-rock law's constants per member (made again with new germs or
  factors);
- :class:`StringForces`: the operands of :func:`drill_twin.model.forces.string_forces`;
- the batch's work arrays (:class:`ModalWork`, :class:`MemberWork`, :class:`ForceWork`,
  :class:`CompactBuffers`), made once per batch size.

They travel as one StructRef, :class:`StepOperands`. numba unboxes every array of a tuple
argument at every call: the step's operands are about 150 arrays, and their unboxing cost
about 8 us of the mean model's 110 us step; held in one StructRef they are unboxed as a single
pointer (0.7 us for 90 arrays against 5.9 us as tuples, measured). The arrays are shared, not
copied: a state array written from Python (the top-drive angle of the imbalance or of the
lobes) is seen by the step. The integrator makes the object again when one of its parts is
replaced (a new batch size, new germs or law factors).

What each step brings: :class:`StepStart`, :class:`StepInputs`, :class:`AcceptanceHistory`,
and the arrays it returns (:class:`StepOutputs`, :class:`KeptFlags`, new arrays from the
integrator's pools) from which the kernel makes its :class:`FinalEvaluation` and
:class:`NewState`; it reports a :class:`StepCounts`. numba reads the field names of a
namedtuple argument at every call (the step's five cost 2.7 us a step, measured), not a
tuple's: these cross into the kernel as ``tuple(structure)`` and the kernel makes the same
class of them first thing (``StepStart(*start)``), so the order is the class's own on both
sides and never written out.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba.core import types
from numba.experimental import structref

from drill_twin.numerics.compiled import kernel


# -- what does not change from step to step ----------------------------------------------

class Basis(NamedTuple):
    """
    The reduced basis Phi, block by block, and where the bit is.

    shapes: Phi's blocks (rows, columns) of the axial, torsional, bending-y and bending-z
    fields, in that order (4,); shapes_t: their transposes (C-contiguous); ranges (4, 4)
    int64: each block's rows and columns (start, stop, start, stop); n_nodes: N; bit_node: the
    bit's node; bit_axial_dof, bit_torsion_dof: the field-wise DOFs of the bit's axial
    displacement and twist (rows of the (D, m) forces).
    """

    shapes: tuple
    shapes_t: tuple
    ranges: np.ndarray
    n_nodes: int
    bit_node: int
    bit_axial_dof: int
    bit_torsion_dof: int


class LinearOperators(NamedTuple):
    """
    The linear part of the residual and the inverse of the step's matrix S0.

    mass (n, n) [M_r] and mass_is_identity (bool: the residual takes a for M a); damping
    (4,): [C_r]'s diagonal blocks on ``groups``; stiffness (n, n) [K_r] and
    stiffness_diagonal (n,) its diagonal when it is diagonal, else (0,); inverse (4,):
    S0^-1's diagonal blocks, S0 = M + gamma dt C + beta dt^2 K; groups (4, 2) int64: the
    blocks' rows (start, stop), or one group of all n when [C_r] or S0^-1 couple the fields.
    """

    mass: np.ndarray
    mass_is_identity: bool
    damping: tuple
    stiffness: np.ndarray
    stiffness_diagonal: np.ndarray
    inverse: tuple
    groups: np.ndarray


class LocalOperators(NamedTuple):
    """
    The directions U of the local laws and S0^-1's responses to them.

    directions (n, L) U: the bit's axial and torsional rows of Phi (columns 0, 1), the v and w
    rows of every node (2 ... 2 + 2 N), theta_x at the imbalance's node (last; zero without
    one); response (n, L) S0^-1 U; gram (L, L) U^T S0^-1 U; bit_rows (2, n) B^T (U's first two
    columns); bit_response (n, 2) S0^-1 B; bit_flexibility (2, 2) B^T S0^-1 B; bit_axial_row
    (n,): the bit's axial displacement is q . bit_axial_row (m).
    """

    directions: np.ndarray
    response: np.ndarray
    gram: np.ndarray
    bit_rows: np.ndarray
    bit_response: np.ndarray
    bit_flexibility: np.ndarray
    bit_axial_row: np.ndarray


class DrivenLoad(NamedTuple):
    """
    The modal load of the driven rotation and of the hook (:func:`newmark_kernel.external_load`).

    mass_driven, damping_driven (n,): Phi^T (M + M_f) psi and Phi^T (C + C_f) psi;
    top_axial_row (n,): the top's axial row of Phi; static_hook_n: the prestressed hook load (N).
    """

    mass_driven: np.ndarray
    damping_driven: np.ndarray
    top_axial_row: np.ndarray
    static_hook_n: float


class Scheme(NamedTuple):
    """
    The step's numbers: dt (s), beta dt^2 (s^2, the contact tangents' factor), the tolerance.

    tolerance: the relative velocity increment that ends a member's iteration; max_iterations:
    the iterations a step may run.
    """

    time_step_s: float
    beta_dt2: float
    tolerance: float
    max_iterations: int


class StepOperators(NamedTuple):
    """The operands of the step that depend on the system and dt only."""

    basis: Basis
    linear: LinearOperators
    local: LocalOperators
    load: DrivenLoad
    scheme: Scheme


class BitLaw(NamedTuple):
    """
    The bit-rock law as the step solves it.

    static_force_n: the prestress's force on bit f_c (N); bit_rock: whether the law is on;
    rows (m or 1, 8): the law's constants per member (:meth:`BitRockLaw.rows`: a1 ... a5, e,
    r, and the rock's compliance 1/k, the same in every row, 0 for a rigid rock); fade_speeds
    (m or 1,) (rad/s); germs (m or 1, 2, 2) and random (bool: germs given); pattern: the lobed
    bottom's operands (:meth:`LobedBottom.arguments`, inert when it is off).
    """

    static_force_n: float
    bit_rock: bool
    rows: np.ndarray
    fade_speeds: np.ndarray
    germs: np.ndarray
    random: bool
    pattern: tuple


class StringForces(NamedTuple):
    """
    The operands of :func:`drill_twin.model.forces.string_forces` before the kinematics.

    switches (finite strain, kinetic coupling, contact) and the operands of each force's
    kernel, as :class:`NonlinearForces` has them (``*_arguments``): strain, coupling, contact,
    imbalance (:meth:`ImbalanceForce.arguments`) and rotating
    (:meth:`RotatingDampingOperators.arguments`).
    """

    switches: tuple
    strain: tuple
    coupling: tuple
    contact: tuple
    imbalance: tuple
    rotating: tuple


# -- the batch's work arrays ----------------------------------------------------------------

class ModalWork(NamedTuple):
    """
    The iterate in reduced coordinates, members last, (n, m) each.

    d_pred, v_pred: the predictor d*, v*; a: the iterate's accelerations; d, v: its
    displacements and rates; residual, y = S^-1 R; modal: Phi^T f of the iterate; product: a
    buffer; load: g(t + dt), the driven rotation's and the hook's modal load.
    """

    d_pred: np.ndarray
    v_pred: np.ndarray
    a: np.ndarray
    d: np.ndarray
    v: np.ndarray
    residual: np.ndarray
    y: np.ndarray
    modal: np.ndarray
    product: np.ndarray
    load: np.ndarray


class MemberWork(NamedTuple):
    """
    Each member's state of the iteration, (m,) unless said.

    touch: the end-of-step ROP that puts the bit on the surface (m/s); hole: the hole bottom
    at the step's start (m); error, previous_error: the relative velocity increments of the
    last two iterations; active, bit_ok, due, on_wall (bool): still iterating, its bit
    equation solved, verifying its first iterate this step (``VERIFY_EVERY``), touching the
    wall or carrying an imbalance (the Woodbury correction); scratch (6, m): the iterate's
    ROP, B^T y, |v|^2 and F - F_c; responses (m, n, 2): S^-1 B of the members on the wall;
    flexibilities (m, 2, 2): B^T S^-1 B.
    """

    touch: np.ndarray
    hole: np.ndarray
    error: np.ndarray
    previous_error: np.ndarray
    active: np.ndarray
    bit_ok: np.ndarray
    due: np.ndarray
    on_wall: np.ndarray
    scratch: np.ndarray
    responses: np.ndarray
    flexibilities: np.ndarray


class ForceWork(NamedTuple):
    """
    The force kernels' arrays (:class:`drill_twin.model.forces.Workspace`), members last.

    The kinematics: displacement_t (D, m); theta_x_rate_t, theta_x_acceleration_t (N, m);
    bending_y_rate_t, bending_y_acceleration_t, bending_z_rate_t, bending_z_acceleration_t
    (2 N, m) (the last: only the imbalance's node row is computed, when it is on); the kernels'
    work arrays strain, stress (9, m) (the 8 strains and the twist angle), linear (8, m),
    coupling (9, m); and the forces: force_t (D, m) (f_NL without the bit), radial (m, N) (N),
    in_contact (m, N) bool, tangent (m, N, 2, 2).
    """

    displacement_t: np.ndarray
    theta_x_rate_t: np.ndarray
    theta_x_acceleration_t: np.ndarray
    bending_y_rate_t: np.ndarray
    bending_y_acceleration_t: np.ndarray
    bending_z_rate_t: np.ndarray
    bending_z_acceleration_t: np.ndarray
    strain: np.ndarray
    linear: np.ndarray
    stress: np.ndarray
    coupling: np.ndarray
    force_t: np.ndarray
    radial: np.ndarray
    in_contact: np.ndarray
    tangent: np.ndarray


class CompactBuffers(NamedTuple):
    """
    The buffers of the iterations after the first (:mod:`compaction`).

    floats, flags (bool): room for every float and flag array of the batch once, plus the
    law's operands per member; index (m,) int64: the members still iterating.
    """

    floats: np.ndarray
    flags: np.ndarray
    index: np.ndarray


# -- what a step brings and returns -------------------------------------------------------

class StepStart(NamedTuple):
    """
    The state a step starts from, members first.

    q, q_rate, q_acceleration (m, n); hole (m,) the hole bottom (m), read when has_hole (else
    the bit is on bottom where it is).
    """

    q: np.ndarray
    q_rate: np.ndarray
    q_acceleration: np.ndarray
    hole: np.ndarray
    has_hole: bool


class StepInputs(NamedTuple):
    """The top drive's speed (rad/s) and acceleration (rad/s^2), the hook loads (1 or m,) (N)."""

    top_speed: float
    top_acceleration: float
    hooks: np.ndarray


class AcceptanceHistory(NamedTuple):
    """
    What decides whether a member's first iterate is accepted.

    have_rate: ``rate`` holds the batch's contraction rates (m,) (else nan, written here);
    clock: the step's number on the model's clock (its end over dt: who verifies,
    ``VERIFY_EVERY``); have_active: previous_contact (m, N) and previous_lifted (m,) are the
    last step's contact and lift-off flags.
    """

    have_rate: bool
    have_active: bool
    rate: np.ndarray
    clock: int
    previous_contact: np.ndarray
    previous_lifted: np.ndarray


class StepOutputs(NamedTuple):
    """
    New arrays for what a step hands its caller (recycled: :mod:`drill_twin.numerics.recycled`).

    The new state: q, q_rate, q_acceleration (m, n), hole (m,), finite, converged, on_bottom
    (m,) bool, error (m,); the final evaluation: full (D, m), modal (n, m), radial (m, N) and
    the bit's rop, omega, force, torque (m,), jacobian (m, 2, 2).
    """

    q: np.ndarray
    q_rate: np.ndarray
    q_acceleration: np.ndarray
    hole: np.ndarray
    finite: np.ndarray
    converged: np.ndarray
    on_bottom: np.ndarray
    error: np.ndarray
    full: np.ndarray
    modal: np.ndarray
    radial: np.ndarray
    rop: np.ndarray
    omega: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    jacobian: np.ndarray


class KeptFlags(NamedTuple):
    """
    New arrays for what the integrator keeps a step longer than its caller.

    saved_rate (m,): the contraction rates before the step (to undo it); contact (m, N) and
    lifted (m,) bool: the final evaluation's flags (the next step compares with them).
    """

    saved_rate: np.ndarray
    contact: np.ndarray
    lifted: np.ndarray


class FinalEvaluation(NamedTuple):
    """
    The forces of each member's final state, members last where (D or n, m).

    full (D, m), modal (n, m), radial (m, N), contact (m, N) bool, tangent (m, N, 2, 2), and
    the bit's rop, omega, force, torque (m,), lifted (m,) bool, jacobian (m, 2, 2) and solved
    (m,) bool (its equation solved).
    """

    full: np.ndarray
    modal: np.ndarray
    radial: np.ndarray
    contact: np.ndarray
    tangent: np.ndarray
    rop: np.ndarray
    omega: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    lifted: np.ndarray
    jacobian: np.ndarray
    solved: np.ndarray


class StepCounts(NamedTuple):
    """
    What a step counted.

    iterations; robust: iterations in which a member needed the bracketed bit solve;
    converged: members converged; touching: a node of the final evaluation touches the wall;
    on_bottom: members on bottom; lifted: members whose bit the final evaluation has lifted
    off.
    """

    iterations: int
    robust: int
    converged: int
    touching: bool
    on_bottom: int
    lifted: int


class NewState(NamedTuple):
    """The state a step ends with, members first: :class:`StepOutputs`' first eight fields."""

    q: np.ndarray
    q_rate: np.ndarray
    q_acceleration: np.ndarray
    hole: np.ndarray
    finite: np.ndarray
    converged: np.ndarray
    on_bottom: np.ndarray
    error: np.ndarray


# -- one object for the step's operands ---------------------------------------------------

@structref.register
class StepOperandsType(types.StructRef):
    """numba type of :class:`StepOperands`."""

    def preprocess_fields(self, fields):
        """Keep the fields' types as they are (no literals)."""
        return tuple((name, types.unliteral(kind)) for name, kind in fields)


class StepOperands(structref.StructRefProxy):
    """
    What does not change from step to step, as one object (module docstring).

    Fields: forces (:class:`StringForces`), operators (:class:`StepOperators`), law
    (:class:`BitLaw`), modal (:class:`ModalWork`), members (:class:`MemberWork`), force_work
    (:class:`ForceWork`), compact (:class:`CompactBuffers`), final_tangent (m, N, 2, 2) and
    final_solved (m,) bool (the final evaluation's arrays that callers do not keep as they
    are).
    """


structref.define_proxy(StepOperands, StepOperandsType,
                       ['forces', 'operators', 'law', 'modal', 'members', 'force_work',
                        'compact', 'final_tangent', 'final_solved'])


@kernel
def make_step_operands(forces, operators, law, modal, members, force_work, compact,
                       final_tangent, final_solved):
    """
    Return a :class:`StepOperands` of its fields (each a structure of this module, by type).

    Made in compiled code: the proxy's own constructor is compiled again in every process
    (3.5 s), this one is cached on disk with the kernels.
    """
    return StepOperands(forces, operators, law, modal, members, force_work, compact,
                        final_tangent, final_solved)
