"""f_ke: the kinetic coupling of torsion and bending (Eq. 8-11).

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
"""
from __future__ import annotations

import numpy as np


def kinetic_coupling_force(system, fields):
    """f_ke on the field-wise DOFs, shape (m, n_dofs).

    fields: :class:`~drill_twin.dynamics.forces.Kinematics` of the batch.
    """
    m = fields.displacement.shape[0]
    b = system.blocks
    # One product per operator: the stacked inputs share it.
    x = np.concatenate([fields.theta_x_rate, fields.theta_x_acceleration]) @ system.theta_x_gauss_t
    z = (np.concatenate([fields.bending_y_rate, fields.bending_y_acceleration])
         @ system.theta_z_gauss_t)
    y = (np.concatenate([fields.displacement[:, b['bending_z'].rows], fields.bending_z_rate])
         @ system.theta_y_gauss_t)
    rate_x, acc_x = x[:m], x[m:]
    rate_z, acc_z = z[:m], z[m:]
    theta_y, rate_y = y[:m], y[m:]
    scale = system.polar_inertia_density * system.gauss_weight_m
    force = np.zeros_like(fields.displacement)
    force[:, b['torsional'].rows] = (scale * (rate_y * rate_z + theta_y * acc_z)) @ system.theta_x_gauss
    force[:, b['bending_z'].rows] = (-scale * rate_x * rate_z) @ system.theta_y_gauss
    force[:, b['bending_y'].rows] = (scale * (acc_x * theta_y + rate_x * rate_y)) @ system.theta_z_gauss
    return force


def kinetic_coupling_energy(system, fields):
    """T_c integrated over the string, shape (m,) (J): part of the kinetic energy."""
    theta_y = fields.displacement[:, system.blocks['bending_z'].rows] @ system.theta_y_gauss_t
    rate_x = fields.theta_x_rate @ system.theta_x_gauss_t
    rate_z = fields.bending_y_rate @ system.theta_z_gauss_t
    scale = system.polar_inertia_density * system.gauss_weight_m
    return -np.sum(scale * rate_x * theta_y * rate_z, axis=-1)
