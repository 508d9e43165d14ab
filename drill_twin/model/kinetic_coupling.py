"""
f_ke: the kinetic coupling of torsion and bending (Eq. 8-11).

The coupling term of the kinetic energy per unit length is taken as
T_c = -rho I_p theta_x' theta_y theta_z' (dots: time derivatives): the spin component of the
angular velocity for the rotation sequence used by the strain energy (twist first, then the
small bending tilts). Lagrange's equations give the generalized forces, moved to the
right-hand side:

    on theta_x:  +rho I_p (theta_y' theta_z' + theta_y theta_z'')
    on theta_y:  -rho I_p theta_x' theta_z'
    on theta_z:  +rho I_p (theta_x'' theta_y + theta_x' theta_y')

These are MODEL.md's expressions with the opposite sign: with theta_y = -w', theta_z = v' and a
right-handed spin, the printed sign would stiffen backward whirl instead of forward whirl
(docs/MODEL-CHOICES.md; test_kinetic_coupling.py checks a spinning disk).

The kernel runs Gauss point by Gauss point with the members of the batch as the inner (vector)
axis: each point interpolates its rotations and their rates from its element's nodes (two or
four non-zeros of the dense interpolation rows, in padded rows: :mod:`padded_rows`) and
scatters its forces straight back.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.numerics.compiled import VECTOR_BATCH, inline, kernel
from drill_twin.numerics.padded_rows import padded_rows_of


@dataclass(frozen=True)
class CouplingOperators:
    """
    The kinetic-coupling data of a reduced system, in the kernel's layout.

    theta_x, theta_y, theta_z: (column, value, length) (:mod:`padded_rows`), the rows
    giving each rotation at the P Gauss points from the torsional field, the bending_z block
    (w, theta_y) and the bending_y block (v, theta_z); torsion_row, bending_y_row,
    bending_z_row: first field-wise DOF of each; scale: rho I_p times the Gauss weight
    (kg m^2), (P,).
    """

    theta_x: tuple
    theta_y: tuple
    theta_z: tuple
    torsion_row: int
    bending_y_row: int
    bending_z_row: int
    scale: np.ndarray

    @classmethod
    def of(cls, system) -> 'CouplingOperators':
        b = system.blocks
        return cls(theta_x=padded_rows_of(system.theta_x_gauss),
                   theta_y=padded_rows_of(system.theta_y_gauss),
                   theta_z=padded_rows_of(system.theta_z_gauss),
                   torsion_row=b['torsional'].rows.start, bending_y_row=b['bending_y'].rows.start,
                   bending_z_row=b['bending_z'].rows.start,
                   scale=np.ascontiguousarray(_sign(system) * system.polar_inertia_density
                                              * system.gauss_weight_m, dtype=float))

    def arguments(self) -> tuple:
        """Return the kernel's operator arguments, in its order."""
        rows = (np.uintp(self.torsion_row), np.uintp(self.bending_y_row),
                np.uintp(self.bending_z_row))         # unsigned like the columns they offset
        return (*self.theta_x, *self.theta_y, *self.theta_z, *rows, self.scale)


def _sign(system) -> float:
    """
    Return +1 for the derived T_c, -1 for the sign printed in Eq. 8-11.

    The sign is chosen by ``lateral_readings.kinetic_coupling``.
    """
    return -1.0 if system.model.config.lateral_readings.kinetic_coupling == 'printed' else 1.0


@inline
def _point_forces(scale, rate_x, acc_x, rate_z, acc_z, theta_y, rate_y):
    """
    Return the forces on (theta_x, theta_y, theta_z) of a Gauss point of weight rho I_p w.

    See the module docstring.
    """
    return (scale * (rate_y * rate_z + theta_y * acc_z), -scale * rate_x * rate_z,
            scale * (acc_x * theta_y + rate_x * rate_y))


@kernel
def accumulate_kinetic_coupling(displacement_t, theta_x_rate_t, theta_x_acceleration_t,
                                bending_y_rate_t, bending_y_acceleration_t, bending_z_rate_t,
                                x_column, x_value, x_length, y_column, y_value, y_length,
                                z_column, z_value, z_length, torsion_row, bending_y_row,
                                bending_z_row, scale, work, force_t):
    """
    force_t += f_ke, members last.

    Displacement_t and force_t (n_dofs, m); theta_x rates and accelerations (n_nodes, m);
    bending rates and accelerations (2 n_nodes, m); work: (9, m). Small batches run member by
    member.
    """
    members = displacement_t.shape[1]
    x_width, y_width, z_width = x_column.shape[1], y_column.shape[1], z_column.shape[1]
    if members < VECTOR_BATCH:
        for i in range(members):
            for p in range(scale.shape[0]):
                rate_x = acc_x = rate_z = acc_z = theta_y = rate_y = 0.0
                for j in range(x_width):
                    rate_x += x_value[p, j] * theta_x_rate_t[x_column[p, j], i]
                    acc_x += x_value[p, j] * theta_x_acceleration_t[x_column[p, j], i]
                for j in range(z_width):
                    rate_z += z_value[p, j] * bending_y_rate_t[z_column[p, j], i]
                    acc_z += z_value[p, j] * bending_y_acceleration_t[z_column[p, j], i]
                for j in range(y_width):
                    theta_y += y_value[p, j] * displacement_t[bending_z_row + y_column[p, j], i]
                    rate_y += y_value[p, j] * bending_z_rate_t[y_column[p, j], i]
                fx, fy, fz = _point_forces(scale[p], rate_x, acc_x, rate_z, acc_z, theta_y,
                                           rate_y)
                for j in range(x_width):
                    force_t[torsion_row + x_column[p, j], i] += x_value[p, j] * fx
                for j in range(y_width):
                    force_t[bending_z_row + y_column[p, j], i] += y_value[p, j] * fy
                for j in range(z_width):
                    force_t[bending_y_row + z_column[p, j], i] += z_value[p, j] * fz
        return
    rate_x, acc_x, rate_z, acc_z, theta_y, rate_y = (work[0], work[1], work[2], work[3],
                                                     work[4], work[5])
    force_x, force_y, force_z = work[6], work[7], work[8]
    for p in range(scale.shape[0]):
        for i in range(members):
            rate_x[i] = 0.0
            acc_x[i] = 0.0
            rate_z[i] = 0.0
            acc_z[i] = 0.0
            theta_y[i] = 0.0
            rate_y[i] = 0.0
        for j in range(x_length[p]):
            column, value = x_column[p, j], x_value[p, j]
            for i in range(members):
                rate_x[i] += value * theta_x_rate_t[column, i]
                acc_x[i] += value * theta_x_acceleration_t[column, i]
        for j in range(z_length[p]):
            column, value = z_column[p, j], z_value[p, j]
            for i in range(members):
                rate_z[i] += value * bending_y_rate_t[column, i]
                acc_z[i] += value * bending_y_acceleration_t[column, i]
        for j in range(y_length[p]):
            column, value = y_column[p, j], y_value[p, j]
            for i in range(members):
                theta_y[i] += value * displacement_t[bending_z_row + column, i]
                rate_y[i] += value * bending_z_rate_t[column, i]
        s = scale[p]
        for i in range(members):
            force_x[i], force_y[i], force_z[i] = _point_forces(s, rate_x[i], acc_x[i],
                                                               rate_z[i], acc_z[i], theta_y[i],
                                                               rate_y[i])
        for j in range(x_length[p]):
            column, value = torsion_row + x_column[p, j], x_value[p, j]
            for i in range(members):
                force_t[column, i] += value * force_x[i]
        for j in range(y_length[p]):
            column, value = bending_z_row + y_column[p, j], y_value[p, j]
            for i in range(members):
                force_t[column, i] += value * force_y[i]
        for j in range(z_length[p]):
            column, value = bending_y_row + z_column[p, j], z_value[p, j]
            for i in range(members):
                force_t[column, i] += value * force_z[i]


def transposed(array) -> np.ndarray:
    """Return a (m, k) array as a C-contiguous (k, m) array (the kernels' member-last layout)."""
    return np.ascontiguousarray(np.asarray(array, dtype=float).T)


def kinetic_coupling_force(system, fields, operators: CouplingOperators | None = None):
    """
    f_ke on the field-wise DOFs, shape (m, n_dofs).

    fields: :class:`~drill_twin.model.forces.Kinematics` of the batch; ``operators``
    (built from ``system`` when not given) are :meth:`CouplingOperators.of` the system.
    """
    operators = operators or CouplingOperators.of(system)
    displacement_t = transposed(fields.displacement)
    force_t = np.zeros_like(displacement_t)
    accumulate_kinetic_coupling(
        displacement_t, transposed(fields.theta_x_rate), transposed(fields.theta_x_acceleration),
        transposed(fields.bending_y_rate), transposed(fields.bending_y_acceleration),
        transposed(fields.bending_z_rate), *operators.arguments(),
        np.empty((9, displacement_t.shape[1])), force_t)
    return np.ascontiguousarray(force_t.T)


def kinetic_coupling_energy(system, fields):
    """T_c integrated over the string, shape (m,) (J): part of the kinetic energy."""
    theta_y = fields.displacement[:, system.blocks['bending_z'].rows] @ system.theta_y_gauss_t
    rate_x = fields.theta_x_rate @ system.theta_x_gauss_t
    rate_z = fields.bending_y_rate @ system.theta_z_gauss_t
    scale = _sign(system) * system.polar_inertia_density * system.gauss_weight_m
    return -np.sum(scale * rate_x * theta_y * rate_z, axis=-1)
