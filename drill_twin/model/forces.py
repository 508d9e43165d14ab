"""
The non-linear force vector f_NL of Eq. 31, evaluated for a batch of members.

The finite-strain, kinetic-coupling and contact forces are accumulated by compiled kernels
(``finite_strain``, ``kinetic_coupling``, ``contact``) into one force array laid out members
last, (n_dofs, m); its work arrays belong to a :class:`Workspace` made once per batch size.
What an evaluation returns is new arrays: the integrator keeps evaluations across iterations
and steps. The projection on the reduced basis stays a dense (BLAS) product.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.bottom_hole_pattern import LobedBottom
from drill_twin.numerics.compiled import kernel
from drill_twin.model.contact import ContactForces, accumulate_contact
from drill_twin.model.excitation import ImbalanceForce, accumulate_imbalance
from drill_twin.model.finite_strain import (WORK_ROWS, StrainOperators,
                                            accumulate_finite_strain)
from drill_twin.model.kinetic_coupling import CouplingOperators, accumulate_kinetic_coupling
from drill_twin.model.rotating_damping import (RotatingDampingOperators,
                                               accumulate_rotating_damping)
from drill_twin.model.reduced_system import ReducedSystem
from drill_twin.fem import strain_energy as se


@dataclass(frozen=True)
class Kinematics:
    """
    What the forces need of a batch of m members (field-wise DOFs, SI units).

    displacement: u from the prestress, (m, n_dofs) (without the driven angle, on which no
    force depends). Rates and accelerations include the driven rotation:
    theta_x_rate, theta_x_acceleration: (m, n_nodes); bending_y_rate,
    bending_y_acceleration: (v, theta_z) rates, (m, 2 n_nodes); bending_z_rate: (w, theta_y),
    (m, 2 n_nodes); bit_axial_rate: ROP, (m,). For the excitation (model/excitation.py):
    bending_z_acceleration: (w, theta_y), (m, 2 n_nodes) (None if not computed);
    top_angle_rad: the top-drive angle (rad), which the local spin angle adds to the twist.
    """

    displacement: np.ndarray
    theta_x_rate: np.ndarray
    theta_x_acceleration: np.ndarray
    bending_y_rate: np.ndarray
    bending_y_acceleration: np.ndarray
    bending_z_rate: np.ndarray
    bit_axial_rate: np.ndarray
    bending_z_acceleration: np.ndarray | None = None
    top_angle_rad: float = 0.0

    @classmethod
    def of(cls, system: ReducedSystem, d, v, a, top_speed: float, top_acceleration: float,
           top_angle: float = 0.0):
        """
        Fields of reduced coordinates, the top-drive speed/acceleration and angle.

        Reduced coordinates d, v, a (m, n); the top-drive angle is ``top_angle`` (rad).

        The arrays are transposed views of members-last arrays (the kernels' layout), so the
        forces read them without a copy.
        """
        b = system.blocks
        axial, torsion = b['axial'], b['torsional']
        y, z = b['bending_y'], b['bending_z']
        displacement_t = np.empty((system.n_dofs, d.shape[0]))
        for block in b.values():
            np.matmul(block.shapes, d[:, block.columns].T, out=displacement_t[block.rows])
        theta_x_rate_t = torsion.shapes @ v[:, torsion.columns].T
        theta_x_rate_t += top_speed
        theta_x_acceleration_t = torsion.shapes @ a[:, torsion.columns].T
        theta_x_acceleration_t += top_acceleration
        return cls(
            displacement=displacement_t.T,
            theta_x_rate=theta_x_rate_t.T,
            theta_x_acceleration=theta_x_acceleration_t.T,
            bending_y_rate=(y.shapes @ v[:, y.columns].T).T,
            bending_y_acceleration=(y.shapes @ a[:, y.columns].T).T,
            bending_z_rate=(z.shapes @ v[:, z.columns].T).T,
            bit_axial_rate=v[:, axial.columns] @ axial.shapes[system.bit_node],
            bending_z_acceleration=(z.shapes @ a[:, z.columns].T).T,
            top_angle_rad=float(top_angle))


def members_last(array: np.ndarray, buffer: np.ndarray) -> np.ndarray:
    """
    ``array`` (m, k) as a C-contiguous (k, m) array.

    Its transpose when that is one (no copy), else a copy into ``buffer``.
    """
    transposed = array.T
    if transposed.flags.c_contiguous and transposed.dtype == np.float64:
        return transposed
    np.copyto(buffer, transposed)
    return buffer


@dataclass(frozen=True)
class ForceEvaluation:
    """
    f_NL and what the bit and the wall see.

    full: f_NL on the field-wise DOFs, (m, n_dofs) (N, N m); modal: Phi^T f_NL, (m, n).
    weight_on_bit_n, torque_on_bit_nm: the bit-rock forces f_bit, t_bit (total, not minus the
    prestress), (m,); rop_m_per_s, bit_speed_rad_per_s: the bit velocities they were computed
    at; lifted: bit off the rock, (m,); bit_jacobian: d(f, t)/d(ROP, omega), (m, 2, 2);
    contact: radial wall forces and flags per node; contact_tangent: d(-F)/d(v, w) per node,
    (m, n_nodes, 2, 2), or None without contact.
    """

    full: np.ndarray
    modal: np.ndarray
    weight_on_bit_n: np.ndarray
    torque_on_bit_nm: np.ndarray
    rop_m_per_s: np.ndarray
    bit_speed_rad_per_s: np.ndarray
    lifted: np.ndarray
    bit_jacobian: np.ndarray
    contact: ContactForces
    contact_tangent: np.ndarray | None


class Workspace:
    """
    Work arrays of the force kernels for a batch of m members (allocated once).

    displacement_t: (n_dofs, m); theta_x_rate_t, theta_x_acceleration_t: (n_nodes, m);
    bending_y_rate_t, bending_y_acceleration_t, bending_z_rate_t, bending_z_acceleration_t:
    (2 n_nodes, m) (used only when the kinematics are not laid out members last already;
    the last one only by the imbalance); strain, linear, stress:
    (8, m); coupling: (9, m); tangent: (m, n_nodes, 2, 2).
    """

    def __init__(self, system: ReducedSystem, members: int):
        n_dofs, nodes = system.n_dofs, system.n_nodes
        self.members = members
        self.displacement_t = np.empty((n_dofs, members))
        self.theta_x_rate_t = np.empty((nodes, members))
        self.theta_x_acceleration_t = np.empty((nodes, members))
        self.bending_y_rate_t = np.empty((2 * nodes, members))
        self.bending_y_acceleration_t = np.empty((2 * nodes, members))
        self.bending_z_rate_t = np.empty((2 * nodes, members))
        self.bending_z_acceleration_t = np.empty((2 * nodes, members))   # the imbalance's
        self.strain = np.empty((WORK_ROWS, members))
        self.linear = np.empty((se.N_STRAINS, members))
        self.stress = np.empty((WORK_ROWS, members))
        self.coupling = np.empty((9, members))
        self.tangent = np.empty((members, nodes, 2, 2))
        self.force_t = np.empty((n_dofs, members))
        self.radial = np.empty((members, nodes))
        self.in_contact = np.empty((members, nodes), dtype=bool)
        self.kinematics = (self.displacement_t, self.theta_x_rate_t, self.theta_x_acceleration_t,
                           self.bending_y_rate_t, self.bending_y_acceleration_t,
                           self.bending_z_rate_t)
        """The six members-last kinematic arrays, in the order of
        :meth:`NonlinearForces.accumulate`."""


@kernel
def string_forces(switches, strain_arguments, coupling_arguments, contact_arguments,
                  imbalance_arguments, rotating_arguments, displacement_t, theta_x_rate_t,
                  theta_x_acceleration_t, bending_y_rate_t, bending_y_acceleration_t,
                  bending_z_rate_t, bending_z_acceleration_t, strain, linear, stress, coupling,
                  force_t, radial, in_contact, tangent):
    """
    force_t += f_se + f_ke + the imbalance + rotating damping + f_ip (not the bit's).

    Members last. The one place the forces of the string are summed
    (:meth:`NonlinearForces.accumulate` and the Newmark step kernel call it). switches: (finite
    strain, kinetic coupling, contact); the arguments of each kernel are those of
    NonlinearForces; imbalance_arguments: the excitation's (:meth:`ImbalanceForce.arguments`,
    its first element says whether it is on; only then is bending_z_acceleration_t read, at the
    imbalance's node); rotating_arguments: :meth:`RotatingDampingOperators.arguments` (first
    element: on). Returns the number of (member, node) pairs touching the wall (radial,
    in_contact are zero and False without contact).
    """
    if switches[0]:
        accumulate_finite_strain(displacement_t, *strain_arguments, strain, linear, stress,
                                 force_t)
    if switches[1]:
        accumulate_kinetic_coupling(displacement_t, theta_x_rate_t, theta_x_acceleration_t,
                                    bending_y_rate_t, bending_y_acceleration_t,
                                    bending_z_rate_t, *coupling_arguments, coupling, force_t)
    if imbalance_arguments[0]:
        accumulate_imbalance(imbalance_arguments, displacement_t, theta_x_rate_t,
                             theta_x_acceleration_t, bending_y_acceleration_t,
                             bending_z_acceleration_t, force_t)
    if rotating_arguments[0]:
        accumulate_rotating_damping(rotating_arguments, displacement_t, theta_x_rate_t, force_t)
    if not switches[2]:
        radial[:, :] = 0.0
        in_contact[:, :] = False
        return 0
    return accumulate_contact(displacement_t, theta_x_rate_t, bending_y_rate_t,
                              bending_z_rate_t, *contact_arguments, force_t,
                              radial, in_contact, tangent)


class NonlinearForces:
    """f_ke + f_se + f_ip + f_br of Eq. 31 (g(t) is handled by the integrator)."""

    def __init__(self, system: ReducedSystem):
        config = system.model.config
        self.system = system
        self.physics = config.physics
        self.borehole = config.borehole
        self.law = BitRockLaw.from_config(config.bit_rock)
        self.static_weight_on_bit_n = system.model.prestress.static_weight_on_bit_n
        self.bit_axial_index = system.field(0).start + system.bit_node
        self.bit_torsion_index = system.field(1).start + system.bit_node
        self.strain_operators = StrainOperators.of(system)
        self.coupling_operators = CouplingOperators.of(system)
        self.clearance_m = np.ascontiguousarray(system.clearance_m, dtype=float)
        self.outer_radius_m = np.ascontiguousarray(system.node_outer_radius_m, dtype=float)
        self.imbalance = ImbalanceForce.of(system)     # excitation.imbalance, None when off
        self.imbalance_arguments = ImbalanceForce.arguments_of(self.imbalance, system)
        self.bottom_pattern = LobedBottom.of(system)   # the lobed hole bottom, None when off
        self.rotating_damping = RotatingDampingOperators.of(system)
        self.rotating_arguments = self.rotating_damping.arguments()
        """lateral_readings.stiffness_damping's circulatory force (inert when fixed_frame)."""
        """The imbalance's kernel operands (inert when it is off); its top-drive angle is
        set before every evaluation."""
        self._workspace = None
        self._step_workspace = None
        physics, borehole = self.physics, self.borehole
        self.switches = (bool(physics.finite_strain), bool(physics.kinetic_coupling),
                         bool(physics.contact))
        """Which forces of the string are on: finite strain, kinetic coupling, contact."""
        self.strain_arguments = self.strain_operators.arguments()
        self.coupling_arguments = self.coupling_operators.arguments()
        self.contact_arguments = (system.n_nodes, self.clearance_m, self.outer_radius_m,
                                  float(borehole.contact_stiffness_n_per_m),
                                  float(borehole.friction_coefficient),
                                  float(borehole.friction_regularization_rad_per_s),
                                  bool(borehole.tangential_friction))
        """The kernels' operands: string_forces takes them as they are."""

    def workspace(self, members: int) -> Workspace:
        """Return the work arrays for a batch of ``members`` (made again only when m changes)."""
        if self._workspace is None or self._workspace.members != members:
            self._workspace = Workspace(self.system, members)
        return self._workspace

    def step_workspace(self, members: int) -> Workspace:
        """
        Return the work arrays of the Newmark step for ``members``.

        They are the step's own: :meth:`evaluate` may run between steps.
        """
        if self._step_workspace is None or self._step_workspace.members != members:
            self._step_workspace = Workspace(self.system, members)
        return self._step_workspace

    def accumulate(self, displacement_t, theta_x_rate_t, theta_x_acceleration_t,
                   bending_y_rate_t, bending_y_acceleration_t, bending_z_rate_t,
                   work: Workspace, force_t, radial, in_contact,
                   bending_z_acceleration_t=None) -> int:
        """
        Add f_se + f_ke + imbalance + f_ip (not the bit's) of members-last kinematics to force_t.

        The kinematics are the fields of :class:`Kinematics`, transposed: (n_dofs, m),
        (n_nodes, m) and (2 n_nodes, m); bending_z_acceleration_t is needed only with the
        imbalance on (whose top-drive angle must have been set).

        radial, in_contact (m, n_nodes) receive the wall forces and flags (zero and False
        without contact physics), work.tangent their tangents. Returns the number of
        (member, node) pairs touching the wall. This is the one place the non-linear forces of
        the string are summed: :meth:`evaluate` and the Newmark step both call it.
        """
        if bending_z_acceleration_t is None:
            if self.imbalance is not None:
                raise ValueError('the imbalance needs the (w, theta_y) accelerations')
            bending_z_acceleration_t = work.bending_z_acceleration_t      # not read
        return string_forces(self.switches, self.strain_arguments, self.coupling_arguments,
                             self.contact_arguments, self.imbalance_arguments,
                             self.rotating_arguments, displacement_t,
                             theta_x_rate_t, theta_x_acceleration_t, bending_y_rate_t,
                             bending_y_acceleration_t, bending_z_rate_t,
                             bending_z_acceleration_t, work.strain, work.linear, work.stress,
                             work.coupling, force_t, radial, in_contact, work.tangent)

    def evaluate(self, fields: Kinematics, germ=None) -> ForceEvaluation:
        """
        f_NL for the fields of a batch; ``germ`` (m, 2, 2) randomises the bit-rock law.

        The arrays of the result are new (the integrator keeps results across iterations);
        ``full`` and ``modal`` are transposed views of members-last arrays.
        """
        system = self.system
        m = fields.displacement.shape[0]
        work = self.workspace(m)
        force_t = np.zeros((system.n_dofs, m))
        radial = np.zeros((m, system.n_nodes))
        in_contact = np.zeros((m, system.n_nodes), dtype=bool)
        bending_z_acceleration_t = None
        self.strain_operators.set_top_angle(fields.top_angle_rad)
        if self.imbalance is not None:                # the rotating imbalance force
            self.imbalance.set_top_angle(fields.top_angle_rad)
            if fields.bending_z_acceleration is not None:
                bending_z_acceleration_t = members_last(fields.bending_z_acceleration,
                                                        work.bending_z_acceleration_t)
        touching = self.accumulate(
            members_last(fields.displacement, work.displacement_t),
            members_last(fields.theta_x_rate, work.theta_x_rate_t),
            members_last(fields.theta_x_acceleration, work.theta_x_acceleration_t),
            members_last(fields.bending_y_rate, work.bending_y_rate_t),
            members_last(fields.bending_y_acceleration, work.bending_y_acceleration_t),
            members_last(fields.bending_z_rate, work.bending_z_rate_t),
            work, force_t, radial, in_contact, bending_z_acceleration_t)
        tangent = work.tangent.copy() if touching else None
        physics = self.physics
        rop = fields.bit_axial_rate
        omega = fields.theta_x_rate[:, system.bit_node]
        if physics.bit_rock:
            wob, tob, lifted, jacobian = self.law.forces_and_jacobian(rop, omega, germ)
            force_t[self.bit_axial_index] += wob - self.static_weight_on_bit_n
            force_t[self.bit_torsion_index] += tob
        else:
            wob = np.full(m, self.static_weight_on_bit_n)
            tob = np.zeros(m)
            lifted = np.zeros(m, dtype=bool)
            jacobian = np.zeros((m, 2, 2))
        modal_t = np.empty((system.size, m))
        for block in system.blocks.values():                  # Phi^T f, block by block
            np.matmul(block.shapes_t, force_t[block.rows], out=modal_t[block.columns])
        return ForceEvaluation(full=force_t.T, modal=modal_t.T, weight_on_bit_n=wob,
                               torque_on_bit_nm=tob, rop_m_per_s=rop, bit_speed_rad_per_s=omega,
                               lifted=lifted, bit_jacobian=jacobian,
                               contact=ContactForces(radial, in_contact),
                               contact_tangent=tangent)
